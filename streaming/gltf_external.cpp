// The external files a glTF file's buffers name: the store's fingerprint of
// a glTF mesh covers them, so that editing a .bin beside its .gltf rebuilds
// the store (octree_build_mesh.cpp).
#include <sys/stat.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>

#include <nlohmann/json.hpp>

#include "streaming/distinct_keys.h"
#include "streaming/gltf_io.h"

namespace raylod {
namespace {

// The JSON text of a .gltf file, or the JSON chunk of a .glb; empty if the
// file cannot be read or its container is broken (its reader says why).
std::string gltf_json_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return {};
  char header[20];
  in.read(header, 20);
  const std::streamsize got = in.gcount();
  auto le32 = [&](int at) {
    uint32_t v = 0;
    for (int i = 3; i >= 0; --i) v = v << 8 | uint8_t(header[at + i]);
    return v;
  };
  if (got >= 12 && std::memcmp(header, "glTF", 4) == 0) {
    if (got < 20 || le32(16) != 0x4E4F534Au) return {};  // no JSON chunk first
    std::string text(le32(12), '\0');
    in.read(text.data(), std::streamsize(text.size()));
    if (in.gcount() != std::streamsize(text.size())) return {};
    return text;
  }
  std::string text(header, size_t(got));
  text.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return text;
}

// RFC 3986 percent-decoding, as glTF URIs are written ("my%20mesh.bin").
std::string percent_decode(const std::string& s) {
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hex(s[i + 1]) >= 0 && hex(s[i + 2]) >= 0) {
      out += char(hex(s[i + 1]) * 16 + hex(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

}  // namespace

std::vector<std::filesystem::path> gltf_external_buffers(const std::filesystem::path& file) {
  std::vector<std::filesystem::path> out;
  const std::string text = gltf_json_text(file);
  // Parse only if some "uri" names more than data (a .gltf holding its
  // buffers as data URIs may be large, and this runs on every store check).
  bool external = false;
  for (size_t at = text.find("\"uri\""); at != std::string::npos && !external; at = text.find("\"uri\"", at + 5)) {
    size_t v = at + 5;
    while (v < text.size() && (text[v] == ' ' || text[v] == '\t' || text[v] == '\n' || text[v] == '\r' || text[v] == ':'))
      ++v;
    external = !(v < text.size() && text[v] == '"' && text.compare(v + 1, 5, "data:") == 0);
  }
  if (!external) return out;
  nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!doc.is_object() || !doc.contains("buffers") || !doc["buffers"].is_array()) return out;
  const std::filesystem::path folder = file.parent_path();
  for (const auto& buffer : doc["buffers"]) {
    if (!buffer.is_object() || !buffer.contains("uri") || !buffer["uri"].is_string()) continue;
    const std::string uri = buffer["uri"].get<std::string>();
    if (uri.rfind("data:", 0) == 0) continue;
    const std::filesystem::path path = folder / percent_decode(uri);
    if (std::find(out.begin(), out.end(), path) == out.end()) out.push_back(path);
  }
  return out;
}

FileStatus with_external_buffers(FileStatus file, std::span<const std::filesystem::path> buffers) {
  for (const std::filesystem::path& buffer : buffers) {
    struct stat st {};
    if (::stat(buffer.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;
    const FileStatus b = file_status_of(st);
    file.bytes += b.bytes;
    file.mtime_ns = std::max(file.mtime_ns, b.mtime_ns);
    file.ctime_ns = std::max(file.ctime_ns, b.ctime_ns);
    file.inode = mix64_finalise(file.inode ^ mix64_finalise(b.inode + b.device));
  }
  return file;
}

}  // namespace raylod
