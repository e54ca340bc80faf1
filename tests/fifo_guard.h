// A guard for tests that open named pipes: a regression that blocks on the
// FIFO fails the test instead of hanging the suite.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <future>

#include <gtest/gtest.h>

namespace raylod::test {

// Runs f, which may open `fifo` for reading. If it is still blocked after
// 10 s the test fails, and the FIFO is opened for writing (and closed) until
// f returns.
template <class F>
auto without_blocking(const std::filesystem::path& fifo, F f) {
  using namespace std::chrono_literals;
  auto result = std::async(std::launch::async, f);
  if (result.wait_for(10s) == std::future_status::timeout) {
    ADD_FAILURE() << "blocked on the named pipe " << fifo;
    while (result.wait_for(100ms) == std::future_status::timeout) {
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
      if (fd >= 0) ::close(fd);
    }
  }
  return result.get();
}

}  // namespace raylod::test
