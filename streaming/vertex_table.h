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
#include <limits>
#include <string>
#include <vector>

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
// The largest value an integer type holds (a PLY list's count type bounds its length).
inline int64_t largest_integer(ScalarType t) {
  switch (t) {
    case ScalarType::Int8: return std::numeric_limits<int8_t>::max();
    case ScalarType::UInt8: return std::numeric_limits<uint8_t>::max();
    case ScalarType::Int16: return std::numeric_limits<int16_t>::max();
    case ScalarType::UInt16: return std::numeric_limits<uint16_t>::max();
    case ScalarType::Int32: return std::numeric_limits<int32_t>::max();
    default: return std::numeric_limits<uint32_t>::max();
  }
}

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

// Floats round to nearest, so a double is representable as a finite float
// below 2^128 - 2^103 (FLT_MAX plus half an ulp), about 3.4e38.
constexpr double kFloatRangeLimit = 0x1.ffffffp+127;
inline bool beyond_float_range(double d) { return std::isfinite(d) && !(std::fabs(d) < kFloatRangeLimit); }
inline bool beyond_float_range(const Vec3d& v) {
  return beyond_float_range(v.x) || beyond_float_range(v.y) || beyond_float_range(v.z);
}
// A scalar as float; a double beyond the float range becomes +-inf (which the
// finiteness checks reject) rather than an undefined conversion.
inline float to_float(double d) {
  if (beyond_float_range(d)) return d > 0 ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
  return float(d);
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
  // Subtracted (in double) before rounding to float: the reader's local
  // origin (MeshHeader::origin). Only tables of double or integer scalars
  // have one; packed float tables keep (0, 0, 0).
  Vec3d origin{0};

  void finalize() {
    packed_float = !swap && type[0] == ScalarType::Float32 && type[1] == ScalarType::Float32 &&
                   type[2] == ScalarType::Float32 && offset[1] == offset[0] + 4 && offset[2] == offset[0] + 8 &&
                   origin == Vec3d(0);
  }
  [[gnu::always_inline]] Vec3 load(uint64_t i) const {
    const uint8_t* r = base + i * stride;
    Vec3 v;
    if (packed_float) {
      std::memcpy(&v.x, r + offset[0], sizeof(float) * 3);
    } else {
      v.x = to_float(load_scalar(r + offset[0], type[0], swap) - origin.x);
      v.y = to_float(load_scalar(r + offset[1], type[1], swap) - origin.y);
      v.z = to_float(load_scalar(r + offset[2], type[2], swap) - origin.z);
    }
    return v;
  }
  // Whether the scalars hold more than a float does (double or integer).
  bool wider_than_float() const {
    return type[0] != ScalarType::Float32 || type[1] != ScalarType::Float32 || type[2] != ScalarType::Float32;
  }
  // The stored values exactly (for error messages about a record load() rejected).
  Vec3d load_exact(uint64_t i) const {
    const uint8_t* r = base + i * stride;
    return Vec3d(load_scalar(r + offset[0], type[0], swap), load_scalar(r + offset[1], type[1], swap),
                 load_scalar(r + offset[2], type[2], swap));
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

inline bool is_zero(const Vec3& n) { return n.x == 0 && n.y == 0 && n.z == 0; }

// Zero-length normals: OpenCASCADE's tessellations (and other CAD exports)
// store (0, 0, 0) normals, mostly on degenerate triangles, and refusing the
// whole mesh for them would refuse real CAD data. Each corner of triangle
// p[0..2] whose normal n[k] is zero gets, in this triangle only, the
// triangle's unit face normal, turned to agree with the triangle's other
// normals; if the triangle is degenerate, the normalised sum of its other
// normals, else +Z. NaN/Inf normals stay errors (the callers reject them).
// Returns how many corners were replaced.
inline int repair_zero_normals(const Vec3* p, Vec3* n) {
  int zero = 0;
  Vec3d others(0);
  for (int k = 0; k < 3; ++k) {
    if (is_zero(n[k])) ++zero;
    else others += Vec3d(n[k]);
  }
  if (zero == 0) return 0;
  Vec3d f = face_normal(Vec3d(p[0]), Vec3d(p[1]), Vec3d(p[2]));
  if (f == Vec3d(0)) {
    const double len = glm::length(others);
    f = len > 0 ? others / len : Vec3d(0, 0, 1);
  } else if (glm::dot(f, others) < 0) {
    f = -f;
  }
  for (int k = 0; k < 3; ++k)
    if (is_zero(n[k])) n[k] = Vec3(f);
  return zero;
}

// Appends polygon pos[0..n) as a fan around corner 0, triangles (0, k, k+1),
// to `positions` (and nrm[0..n) to `normals`, unless nrm is null); with
// `repair`, the new triangles' zero normals are replaced (repair_zero_normals).
// Returns how many corners were replaced. Shared by the PLY and OBJ readers.
inline uint64_t append_polygon_fan(const Vec3* pos, const Vec3* nrm, size_t n, bool repair,
                                   std::vector<Vec3>& positions, std::vector<Vec3>& normals) {
  const size_t first = positions.size();
  for (size_t k = 1; k + 1 < n; ++k) {
    positions.push_back(pos[0]);
    positions.push_back(pos[k]);
    positions.push_back(pos[k + 1]);
    if (nrm) {
      normals.push_back(nrm[0]);
      normals.push_back(nrm[k]);
      normals.push_back(nrm[k + 1]);
    }
  }
  uint64_t repaired = 0;
  if (nrm && repair)
    for (size_t c = first; c < positions.size(); c += 3) repaired += uint64_t(repair_zero_normals(&positions[c], &normals[c]));
  return repaired;
}

inline std::string vec_text(const Vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%g, %g, %g)", double(v.x), double(v.y), double(v.z));
  return buf;
}
inline std::string vec_text(const Vec3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%g, %g, %g)", v.x, v.y, v.z);
  return buf;
}

}  // namespace raylod
