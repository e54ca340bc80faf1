// Checked accessor views: an accessor's elements must lie inside its buffer
// view and the view inside its buffer (glTF 2.0, section 3.6.2 "Accessors"
// and 5.1 "accessor"), with the component types glTF allows for each use and
// those KHR_mesh_quantization adds (byte and short positions and normals).
#include <cmath>
#include <cstring>

#include "streaming/gltf_model.h"

namespace raylod::gltf {
namespace {

size_t component_size(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT: case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT: case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: return 8;
  }
  return 0;
}

const char* use_name(AccessorUse use) {
  switch (use) {
    case AccessorUse::Position: return "POSITION";
    case AccessorUse::Normal: return "NORMAL";
    case AccessorUse::Indices: return "indices";
  }
  return "?";
}

bool allowed(AccessorUse use, int type, int component_type) {
  switch (use) {
    case AccessorUse::Indices:
      return type == TINYGLTF_TYPE_SCALAR && (component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                                              component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
                                              component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
    case AccessorUse::Position:
      return type == TINYGLTF_TYPE_VEC3 && (component_type == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                                            component_type == TINYGLTF_COMPONENT_TYPE_BYTE ||
                                            component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                                            component_type == TINYGLTF_COMPONENT_TYPE_SHORT ||
                                            component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    case AccessorUse::Normal:
      return type == TINYGLTF_TYPE_VEC3 && (component_type == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                                            component_type == TINYGLTF_COMPONENT_TYPE_BYTE ||
                                            component_type == TINYGLTF_COMPONENT_TYPE_SHORT);
  }
  return false;
}

template <class T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // glTF is little-endian, like every machine raylod runs on
  return v;
}

}  // namespace

double AccessorView::component(size_t i, int c) const {
  const uint8_t* p = data + i * stride + size_t(c) * component_size(component_type);
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return double(load<float>(p));
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const double v = double(load<int8_t>(p));
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
      const double v = double(load<uint8_t>(p));
      return normalized ? v / 255.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const double v = double(load<int16_t>(p));
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      const double v = double(load<uint16_t>(p));
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return double(load<uint32_t>(p));
  }
  return 0;
}

uint32_t AccessorView::index(size_t i) const {
  const uint8_t* p = data + i * stride;
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return *p;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return load<uint16_t>(p);
    default: return load<uint32_t>(p);
  }
}

namespace {

// The names the glTF JSON uses ("SCALAR", "FLOAT (5126)"), for messages:
// tinygltf keeps the type as its own code (SCALAR is 65).
std::string type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "an unknown type";
  }
}
std::string component_type_name(int type) {
  const char* name = "an unknown component type";
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: name = "BYTE"; break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: name = "UNSIGNED_BYTE"; break;
    case TINYGLTF_COMPONENT_TYPE_SHORT: name = "SHORT"; break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: name = "UNSIGNED_SHORT"; break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: name = "UNSIGNED_INT"; break;
    case TINYGLTF_COMPONENT_TYPE_FLOAT: name = "FLOAT"; break;
    default: break;
  }
  return std::string(name) + " (" + std::to_string(type) + ")";
}

}  // namespace

StatusOr<AccessorView> view_accessor(const tinygltf::Model& model, int index, AccessorUse use, const std::string& where) {
  const std::string what = std::string(" (") + use_name(use) + ")";
  auto fail = [&](const std::string& message) { return Status::error(where + ": " + message); };
  if (index < 0 || size_t(index) >= model.accessors.size())
    return fail("accessor " + std::to_string(index) + what + " does not exist (the file has " +
                std::to_string(model.accessors.size()) + " accessors)");
  const tinygltf::Accessor& a = model.accessors[size_t(index)];
  const std::string acc = "accessor " + std::to_string(index) + what;
  if (a.sparse.isSparse) return fail(acc + " is sparse; sparse accessors are not supported");
  if (!allowed(use, a.type, a.componentType))
    return fail(acc + " has type " + type_name(a.type) + " with component type " + component_type_name(a.componentType) +
                ", which glTF (with KHR_mesh_quantization) does not allow for " + use_name(use));
  if (use == AccessorUse::Indices && a.normalized) return fail(acc + " is normalized; indices must not be");
  if (a.count == 0) return fail(acc + " has no elements");
  if (a.bufferView < 0) return fail(acc + " has no bufferView (accessors without data are not supported)");
  if (size_t(a.bufferView) >= model.bufferViews.size())
    return fail(acc + ": bufferView " + std::to_string(a.bufferView) + " does not exist (the file has " +
                std::to_string(model.bufferViews.size()) + ")");
  const tinygltf::BufferView& v = model.bufferViews[size_t(a.bufferView)];
  const std::string view = "bufferView " + std::to_string(a.bufferView);
  if (v.buffer < 0 || size_t(v.buffer) >= model.buffers.size())
    return fail(view + ": buffer " + std::to_string(v.buffer) + " does not exist (the file has " +
                std::to_string(model.buffers.size()) + ")");
  const tinygltf::Buffer& b = model.buffers[size_t(v.buffer)];
  // Offsets and counts come from the file and may be anything: no wrapping.
  if (v.byteOffset > b.data.size() || v.byteLength > b.data.size() - v.byteOffset)
    return fail(view + " (bytes " + std::to_string(v.byteOffset) + " + " + std::to_string(v.byteLength) +
                ") is past the end of buffer " + std::to_string(v.buffer) + " (" + std::to_string(b.data.size()) +
                " bytes)");
  AccessorView out;
  out.component_type = a.componentType;
  out.components = use == AccessorUse::Indices ? 1 : 3;
  out.normalized = a.normalized;
  out.count = a.count;
  const size_t element = component_size(a.componentType) * size_t(out.components);
  out.stride = v.byteStride ? v.byteStride : element;
  if (out.stride < element)
    return fail(view + " has byteStride " + std::to_string(v.byteStride) + ", less than the " + std::to_string(element) +
                "-byte elements of " + acc);
  uint64_t end = 0;
  const bool wraps = __builtin_mul_overflow(uint64_t(a.count - 1), uint64_t(out.stride), &end) ||
                     __builtin_add_overflow(end, uint64_t(a.byteOffset) + element, &end) || a.byteOffset > end;
  if (wraps || end > v.byteLength)
    return fail(acc + " (count " + std::to_string(a.count) + ", byteOffset " + std::to_string(a.byteOffset) +
                ") ends at byte " + (wraps ? std::string("> 2^64") : std::to_string(end)) + ", past the end of " + view +
                " (" + std::to_string(v.byteLength) + " bytes)");
  out.data = b.data.data() + v.byteOffset + a.byteOffset;
  return out;
}

}  // namespace raylod::gltf
