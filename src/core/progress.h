// Progress display (count, elapsed time and time left): a bar redrawn in place on a terminal, plain lines
// (at most one per 10% or per 5 s) when stderr is not a terminal.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace raylod {

class Progress {
 public:
  // total == 0 means unknown; the bar then shows only the count.
  Progress(std::string label, uint64_t total, std::string unit = "");
  ~Progress();
  // Thread-safe; cheap when called often (redraws at most ~10 times a second).
  void advance(uint64_t n);
  void set(uint64_t done);
  void finish();
  // Silences all progress output (tests, --quiet).
  static void set_enabled(bool enabled);

 private:
  void draw(bool final_line);
  std::string label_, unit_;
  uint64_t total_;
  std::atomic<uint64_t> done_{0};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point start_, last_draw_;
  int last_decile_ = -1;
  uint64_t printed_done_ = UINT64_MAX;  // the count of the last line written (not on a terminal)
  bool tty_, finished_ = false;
};

}  // namespace raylod
