// Damaging files on purpose, for the tests of checksums and repair.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>

namespace raylod::test {

// XORs the byte at `offset` of `path` with `mask` in place.
inline void flip_byte(const std::filesystem::path& path, uint64_t offset, char mask = 0x5a) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(std::streamoff(offset));
  char c = 0;
  f.read(&c, 1);
  c = char(c ^ mask);
  f.seekp(std::streamoff(offset));
  f.write(&c, 1);
}

}  // namespace raylod::test
