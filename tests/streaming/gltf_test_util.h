// Builds small glTF files in tests: one binary buffer, accessors over it and
// the JSON through nlohmann, written as .gltf with a base64 data URI, as
// .gltf with an external .bin, or as .glb.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/math.h"

namespace raylod::test {

inline std::string base64(const std::string& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = uint32_t(uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 1])) << 8;
    if (i + 2 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 2]));
    out += digits[(v >> 18) & 63];
    out += digits[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? digits[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? digits[v & 63] : '=';
  }
  return out;
}

constexpr int kByte = 5120, kUByte = 5121, kShort = 5122, kUShort = 5123, kUInt = 5125, kFloat = 5126;

struct GltfBuilder {
  std::string bin;
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}}, {"accessors", nlohmann::json::array()},
                        {"bufferViews", nlohmann::json::array()}, {"meshes", nlohmann::json::array()}};

  int view(const void* data, size_t size) {
    while (bin.size() % 4) bin.push_back('\0');
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", size}});
    bin.append(static_cast<const char*>(data), size);
    return int(doc["bufferViews"].size()) - 1;
  }
  template <class T>
  int accessor(const std::vector<T>& values, int component_type, const char* type, size_t count, bool normalized = false) {
    const int v = view(values.data(), values.size() * sizeof(T));
    nlohmann::json a = {{"bufferView", v}, {"componentType", component_type}, {"count", count}, {"type", type}};
    if (normalized) a["normalized"] = true;
    doc["accessors"].push_back(a);
    return int(doc["accessors"].size()) - 1;
  }
  int positions(const std::vector<Vec3>& p) {
    std::vector<float> f;
    for (const Vec3& v : p) f.insert(f.end(), {v.x, v.y, v.z});
    return accessor(f, kFloat, "VEC3", p.size());
  }
  int indices(const std::vector<uint32_t>& i) { return accessor(i, kUInt, "SCALAR", i.size()); }
  // A mesh with one primitive per entry; returns the mesh index.
  int mesh(const std::vector<nlohmann::json>& primitives, const std::string& name = "") {
    nlohmann::json m = {{"primitives", primitives}};
    if (!name.empty()) m["name"] = name;
    doc["meshes"].push_back(m);
    return int(doc["meshes"].size()) - 1;
  }
  static nlohmann::json primitive(int position, int indices = -1, int mode = 4, int normal = -1) {
    nlohmann::json p = {{"attributes", {{"POSITION", position}}}, {"mode", mode}};
    if (indices >= 0) p["indices"] = indices;
    if (normal >= 0) p["attributes"]["NORMAL"] = normal;
    return p;
  }
  nlohmann::json with_buffer(const std::string& uri) const {
    nlohmann::json d = doc;
    nlohmann::json b = {{"byteLength", bin.size()}};
    if (!uri.empty()) b["uri"] = uri;
    d["buffers"] = nlohmann::json::array({b});
    return d;
  }
  // .gltf text with the buffer as a data URI.
  std::string gltf() const { return with_buffer("data:application/octet-stream;base64," + base64(bin)).dump(); }
  // .glb bytes (JSON chunk padded with spaces, BIN with zeros).
  std::string glb() const { return make_glb(with_buffer("").dump(), bin); }

  static std::string make_glb(std::string json, std::string binary) {
    while (json.size() % 4) json.push_back(' ');
    while (binary.size() % 4) binary.push_back('\0');
    std::string out = "glTF";
    auto put = [&](uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
    put(2);
    put(uint32_t(12 + 8 + json.size() + (binary.empty() ? 0 : 8 + binary.size())));
    put(uint32_t(json.size()));
    out += "JSON";
    out += json;
    if (!binary.empty()) {
      put(uint32_t(binary.size()));
      out.append("BIN\0", 4);
      out += binary;
    }
    return out;
  }
};

}  // namespace raylod::test
