// Distinct keys in first-use order: the vertex deduplication of the page
// encoder (grid point and normal code) and of the open-edge search (grid
// point alone). Hot code: open addressing over a power-of-two table.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <vector>

namespace raylod {

// MurmurHash3's 64-bit finaliser.
inline uint64_t mix64_finalise(uint64_t h) {
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  return h ^ (h >> 33);
}

// For i in [0, count), key_of(i) returns a key of K (3 or 4) words. `keys`
// gets K words per distinct key in first-use order, index[i] the number of
// key i's distinct key. `slots` is scratch (reused between calls).
template <size_t K, class KeyOf>
void index_distinct_keys(size_t count, KeyOf key_of, std::vector<uint32_t>& slots, std::vector<uint32_t>& keys,
                         std::vector<uint32_t>& index) {
  static_assert(K == 3 || K == 4);
  const size_t nslots = std::bit_ceil(std::max<size_t>(16, 2 * count));
  slots.assign(nslots, 0);
  keys.clear();
  index.resize(count);
  const auto hash_of = [](const std::array<uint32_t, K>& key) {
    const uint64_t last = K == 4 ? uint64_t(key[2]) << 32 | key[K - 1] : uint64_t(key[2]) << 32;
    return mix64_finalise((uint64_t(key[0]) << 32 | key[1]) ^ mix64_finalise(last));
  };
  // Keys are hashed kAhead ahead of their turn and their first slot
  // prefetched: a large table misses the cache on nearly every probe, and
  // this lets the misses overlap. Keys are still inserted in order.
  constexpr size_t kAhead = 16;
  std::array<uint64_t, kAhead> ahead;
  for (size_t i = 0; i < std::min(count, kAhead); ++i) {
    ahead[i] = hash_of(key_of(i));
    __builtin_prefetch(&slots[ahead[i] & (nslots - 1)]);
  }
  for (size_t i = 0; i < count; ++i) {
    const std::array<uint32_t, K> key = key_of(i);
    uint64_t h = ahead[i % kAhead];
    if (i + kAhead < count) {
      const uint64_t next = hash_of(key_of(i + kAhead));
      ahead[i % kAhead] = next;
      __builtin_prefetch(&slots[next & (nslots - 1)]);
    }
    for (;; ++h) {
      uint32_t& slot = slots[h & (nslots - 1)];
      if (slot == 0) {
        keys.insert(keys.end(), key.begin(), key.end());
        slot = uint32_t(keys.size() / K);
        index[i] = slot - 1;
        break;
      }
      if (std::equal(key.begin(), key.end(), &keys[K * size_t(slot - 1)])) {
        index[i] = slot - 1;
        break;
      }
    }
  }
}

}  // namespace raylod
