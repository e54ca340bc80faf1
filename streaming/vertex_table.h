// Vertex tables indexed in place: record i of a table starts at
// base + i * stride, and holds three scalars (x, y, z) of any PLY scalar type
// at fixed offsets, in file byte order. Binary PLY files are indexed this way
// straight from the memory map; the text readers spill float records to a
// scratch file and index that. Shared by the PLY and OBJ readers.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <string>

#include "core/math.h"

namespace raylod {

enum class ScalarType : uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

inline size_t scalar_size(ScalarType t) {
  switch (t) {
    case ScalarType::Int8: case ScalarType::UInt8: return 1;
    case ScalarType::Int16: case ScalarType::UInt16: return 2;
    case ScalarType::Int32: case ScalarType::UInt32: case ScalarType::Float32: return 4;
    case ScalarType::Float64: return 8;
  }
  return 0;
}
inline bool is_integer(ScalarType t) { return t != ScalarType::Float32 && t != ScalarType::Float64; }

template <class T>
inline T load_raw(const uint8_t* p, bool swap) {
  uint8_t b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// Any scalar as double (exact for every PLY type).
inline double load_scalar(const uint8_t* p, ScalarType t, bool swap) {
  switch (t) {
    case ScalarType::Int8: return double(int8_t(*p));
    case ScalarType::UInt8: return double(*p);
    case ScalarType::Int16: return double(load_raw<int16_t>(p, swap));
    case ScalarType::UInt16: return double(load_raw<uint16_t>(p, swap));
    case ScalarType::Int32: return double(load_raw<int32_t>(p, swap));
    case ScalarType::UInt32: return double(load_raw<uint32_t>(p, swap));
    case ScalarType::Float32: return double(load_raw<float>(p, swap));
    case ScalarType::Float64: return load_raw<double>(p, swap);
  }
  return 0;
}

// Integer scalars as int64 (list counts and vertex indices).
inline int64_t load_integer(const uint8_t* p, ScalarType t, bool swap) {
  switch (t) {
    case ScalarType::Int8: return int8_t(*p);
    case ScalarType::UInt8: return *p;
    case ScalarType::Int16: return load_raw<int16_t>(p, swap);
    case ScalarType::UInt16: return load_raw<uint16_t>(p, swap);
    case ScalarType::Int32: return load_raw<int32_t>(p, swap);
    case ScalarType::UInt32: return load_raw<uint32_t>(p, swap);
    default: return 0;  // callers only pass integer types
  }
}

struct Vec3Table {
  const uint8_t* base = nullptr;
  size_t stride = 0;
  uint64_t count = 0;
  ScalarType type[3] = {ScalarType::Float32, ScalarType::Float32, ScalarType::Float32};
  uint32_t offset[3] = {0, 4, 8};
  bool swap = false;
  // Three native float32 scalars at offset[0], +4, +8: one memcpy per record.
  bool packed_float = true;

  void finalize() {
    packed_float = !swap && type[0] == ScalarType::Float32 && type[1] == ScalarType::Float32 &&
                   type[2] == ScalarType::Float32 && offset[1] == offset[0] + 4 && offset[2] == offset[0] + 8;
  }
  [[gnu::always_inline]] Vec3 load(uint64_t i) const {
    const uint8_t* r = base + i * stride;
    Vec3 v;
    if (packed_float) {
      std::memcpy(&v.x, r + offset[0], sizeof(float) * 3);
    } else {
      v.x = float(load_scalar(r + offset[0], type[0], swap));
      v.y = float(load_scalar(r + offset[1], type[1], swap));
      v.z = float(load_scalar(r + offset[2], type[2], swap));
    }
    return v;
  }
};

// Unit normal from a stored normal; false if it is zero-length or not finite.
inline bool unit_normal(Vec3& n) {
  // Fast accept for normals that are already unit length (almost all of them).
  const float l2f = n.x * n.x + n.y * n.y + n.z * n.z;
  if (l2f > 0.999999f && l2f < 1.000001f) return true;
  // In double so that huge or tiny (denormal) components neither overflow nor vanish.
  double len2 = double(n.x) * n.x + double(n.y) * n.y + double(n.z) * n.z;
  if (!(len2 > 0.0) || !std::isfinite(len2)) return false;
  // Most files already store unit normals; skip the division for those.
  if (std::fabs(len2 - 1.0) > 1e-6) n = Vec3(Vec3d(n) / std::sqrt(len2));
  return true;
}

inline std::string vec_text(const Vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%g, %g, %g)", double(v.x), double(v.y), double(v.z));
  return buf;
}

}  // namespace raylod
