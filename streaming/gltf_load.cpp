// Loading a glTF 2.0 file: the GLB container checks (Khronos glTF 2.0
// specification, section 4.4 "Binary glTF Layout": a 12-byte header, then
// chunks of [length, type, data] with a JSON chunk first and an optional BIN
// chunk), then tinygltf for the JSON and the buffers, with file access
// confined to the glTF's own folder.
#include <sys/stat.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <mutex>

#include <nlohmann/json.hpp>

#include "core/system.h"
#include "streaming/gltf_io.h"
#include "streaming/gltf_model.h"

namespace raylod::gltf {
namespace {

constexpr uint32_t kGlbMagic = 0x46546C67;     // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;    // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;     // "BIN\0"

uint32_t le32(const uint8_t* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }

Status check_glb_container(const std::vector<uint8_t>& bytes, const std::string& name) {
  const std::string where = name + ": ";
  const uint64_t size = bytes.size();
  if (size < 12) return Status::error(where + "truncated GLB: " + std::to_string(size) + " bytes, less than the 12-byte header");
  const uint32_t version = le32(&bytes[4]), length = le32(&bytes[8]);
  if (version != 2) return Status::error(where + "GLB version " + std::to_string(version) + " (only glTF 2.0 is supported)");
  if (length > size)
    return Status::error(where + "truncated GLB: the header says " + std::to_string(length) + " bytes, the file has " +
                         std::to_string(size));
  if (length < size)
    return Status::error(where + "the GLB header says " + std::to_string(length) + " bytes, but the file has " +
                         std::to_string(size) + " (trailing data)");
  uint64_t at = 12;
  for (int chunk = 0; at < length; ++chunk) {
    const char* what = chunk == 0 ? "JSON chunk" : chunk == 1 ? "BIN chunk" : "chunk";
    if (length - at < 8)
      return Status::error(where + "truncated GLB: " + std::to_string(length - at) + " bytes at offset " +
                           std::to_string(at) + ", too few for the " + what + "'s 8-byte header");
    const uint32_t chunk_length = le32(&bytes[at]), type = le32(&bytes[at + 4]);
    if (chunk_length > length - at - 8)
      return Status::error(where + "truncated GLB: the " + what + " at offset " + std::to_string(at) + " claims " +
                           std::to_string(chunk_length) + " bytes, only " + std::to_string(length - at - 8) + " follow");
    if (chunk == 0 && type != kChunkJson) return Status::error(where + "GLB: the first chunk is not JSON");
    if (chunk == 1 && type != kChunkBin && type != kChunkJson) {
      // Unknown chunk types are ignored (the specification says so).
    } else if (chunk == 1 && type == kChunkJson) {
      return Status::error(where + "GLB: a second JSON chunk");
    }
    at += 8 + uint64_t(chunk_length);
  }
  if (at == 12) return Status::error(where + "truncated GLB: no JSON chunk");
  return Status::ok();
}

// File access for external buffers: only regular files inside the glTF's own
// folder (tinygltf also tries the working directory). External images are
// never read (TINYGLTF_NO_EXTERNAL_IMAGE).
struct FsContext {
  std::string folder;   // absolute, without a trailing slash
  std::string missing;  // the last file looked for and not found
  std::string outside;  // the last file looked for outside the folder
};

// Only files in the glTF file's folder or below it: the path as written
// ("DIR/../x.bin" is outside), not where symbolic links inside it lead.
bool file_exists(const std::string& path, void* user) {
  auto* fs = static_cast<FsContext*>(user);
  const std::string normal = std::filesystem::path(path).lexically_normal().string();
  const bool inside = path.rfind(fs->folder + "/", 0) == 0 && normal.rfind(fs->folder + "/", 0) == 0;
  struct stat st {};
  if (inside && ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) return true;
  if (inside) fs->missing = path;
  else fs->outside = path;
  return false;
}

std::string expand_path(const std::string& path, void*) { return path; }

bool read_whole_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  if (Status st = check_regular_file(path); !st) {
    if (err) *err = st.message();
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (err) *err = "cannot open";
    return false;
  }
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return true;
}

bool write_whole_file(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err = "raylod's glTF reader writes no files";
  return false;
}

bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;  // textures are not used: keep the image undecoded
}

bool extension_supported(const std::string& ext) {
  return ext == "KHR_draco_mesh_compression" || ext == "KHR_mesh_quantization" || ext == "KHR_lights_punctual" ||
         ext.rfind("KHR_materials_", 0) == 0 || ext.rfind("KHR_texture_", 0) == 0;
}

// tinygltf 2.7 rejects a primitive whose indices accessor has no bufferView
// unless it was built with its own Draco decoder (Debian's is not), yet that
// is how KHR_draco_mesh_compression primitives look. Such indices are taken
// out of the JSON before tinygltf sees it and kept here; the Draco data
// holds the real indices anyway.
Status hide_draco_indices(std::string& text, const std::string& name, LoadedModel& loaded) {
  if (text.find("KHR_draco_mesh_compression") == std::string::npos) return Status::ok();
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    return Status::error(name + ": not valid JSON: " + e.what());
  }
  if (!doc.is_object() || !doc.contains("meshes") || !doc["meshes"].is_array()) return Status::ok();
  bool changed = false;
  auto& meshes = doc["meshes"];
  for (size_t m = 0; m < meshes.size(); ++m) {
    if (!meshes[m].is_object() || !meshes[m].contains("primitives") || !meshes[m]["primitives"].is_array()) continue;
    auto& prims = meshes[m]["primitives"];
    for (size_t i = 0; i < prims.size(); ++i) {
      auto& p = prims[i];
      if (!p.is_object() || !p.contains("extensions") || !p["extensions"].is_object() ||
          !p["extensions"].contains("KHR_draco_mesh_compression") || !p.contains("indices"))
        continue;
      if (p["indices"].is_number_integer()) loaded.draco_indices[{int(m), int(i)}] = p["indices"].get<int64_t>();
      p.erase("indices");
      changed = true;
    }
  }
  if (changed) text = doc.dump();
  return Status::ok();
}

// The GLB with its JSON chunk replaced by `text` (the other chunks as they were).
std::vector<uint8_t> replace_json_chunk(const std::vector<uint8_t>& glb, const std::string& text) {
  const uint32_t old_length = le32(&glb[12]);
  std::string chunk = text;
  chunk.append((4 - chunk.size() % 4) % 4, ' ');
  std::vector<uint8_t> out(glb.begin(), glb.begin() + 12);
  auto put32 = [&](uint32_t v) { for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i))); };
  put32(uint32_t(chunk.size()));
  put32(kChunkJson);
  out.insert(out.end(), chunk.begin(), chunk.end());
  out.insert(out.end(), glb.begin() + 20 + old_length, glb.end());
  const uint32_t total = uint32_t(out.size());
  for (int i = 0; i < 4; ++i) out[size_t(8 + i)] = uint8_t(total >> (8 * i));
  return out;
}

StatusOr<std::shared_ptr<const LoadedModel>> load_uncached(const std::filesystem::path& file, uint64_t file_bytes) {
  const std::string name = file.string();
  std::ifstream in(file, std::ios::binary);
  if (!in) return Status::error(name + ": cannot open file");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.eof() && in.fail()) return Status::error(name + ": read failed");
  auto loaded = std::make_shared<LoadedModel>();
  loaded->name = name;
  loaded->file_bytes = bytes.size();
  (void)file_bytes;
  loaded->binary = bytes.size() >= 4 && le32(bytes.data()) == kGlbMagic;
  if (loaded->binary) RAYLOD_RETURN_IF_ERROR(check_glb_container(bytes, name));
  if (bytes.empty()) return Status::error(name + ": empty file (not glTF)");
  {
    std::string text = loaded->binary ? std::string(reinterpret_cast<const char*>(&bytes[20]), le32(&bytes[12]))
                                      : std::string(bytes.begin(), bytes.end());
    const size_t before = text.size();
    RAYLOD_RETURN_IF_ERROR(hide_draco_indices(text, name, *loaded));
    if (!loaded->draco_indices.empty() || text.size() != before)
      bytes = loaded->binary ? replace_json_chunk(bytes, text) : std::vector<uint8_t>(text.begin(), text.end());
  }

  FsContext context;
  std::error_code ec;
  std::filesystem::path folder = std::filesystem::absolute(file, ec).parent_path();
  context.folder = folder.lexically_normal().string();
  while (context.folder.size() > 1 && context.folder.back() == '/') context.folder.pop_back();
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(skip_image, nullptr);
  loader.SetFsCallbacks(tinygltf::FsCallbacks{file_exists, expand_path, read_whole_file, write_whole_file, &context});
  std::string err, warn;
  bool ok = false;
  try {
    ok = loaded->binary
             ? loader.LoadBinaryFromMemory(&loaded->model, &err, &warn, bytes.data(), unsigned(bytes.size()), context.folder)
             : loader.LoadASCIIFromString(&loaded->model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                          unsigned(bytes.size()), context.folder);
  } catch (const std::exception& e) {
    err = e.what();
  }
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    for (char& c : err) if (c == '\n') c = ';';
    if (err.empty()) err = "not a valid glTF 2.0 file";
    std::string hint;
    if (!context.missing.empty())
      hint = " (external files are looked for only beside the glTF file: " + context.missing + " does not exist)";
    else if (!context.outside.empty())
      hint = " (external files are looked for only in the glTF file's folder: " + context.outside + " is outside it)";
    return Status::error(name + ": cannot load glTF: " + err + hint);
  }
  const tinygltf::Model& m = loaded->model;
  if (!m.asset.version.empty() && m.asset.version.rfind("2.", 0) != 0)
    return Status::error(name + ": asset.version is '" + m.asset.version + "' (only glTF 2.0 is supported)");
  for (const std::string& ext : m.extensionsRequired)
    if (!extension_supported(ext))
      return Status::error(name + ": extensionsRequired: '" + ext +
                           "' is not supported (raylod reads KHR_draco_mesh_compression and KHR_mesh_quantization)");
  return std::shared_ptr<const LoadedModel>(std::move(loaded));
}

}  // namespace

StatusOr<std::shared_ptr<const LoadedModel>> load_model(const std::filesystem::path& file) {
  RAYLOD_RETURN_IF_ERROR(check_regular_file(file));
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return Status::error(file.string() + ": " + std::strerror(errno));
  std::error_code ec;
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(std::filesystem::absolute(file, ec), ec);
  // One entry: the per-mesh readers of a scene's glTF (build passes, render)
  // open the same file one after the other. /proc/self/fd paths (the fuzz
  // targets) are never cached: their numbers are reused for other files.
  static std::mutex mutex;
  static std::string cached_path;
  // The file's status with its external buffers' (an edited .bin is read
  // again); the buffers are those of the cached model's JSON, which cannot
  // change while the file's own status does not.
  static FileStatus cached_status;
  static std::vector<std::filesystem::path> cached_buffers;
  static std::weak_ptr<const LoadedModel> cached;
  static std::shared_ptr<const LoadedModel> kept;  // small files stay loaded between readers
  const bool cacheable = file.string().rfind("/proc/", 0) != 0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    std::shared_ptr<const LoadedModel> hit = cached.lock();
    if (cacheable && hit && cached_path == canonical.string() && hit->name == file.string() &&
        with_external_buffers(file_status_of(st), cached_buffers) == cached_status)
      return hit;
  }
  // Their status before the load: a buffer written meanwhile is read again next time.
  std::vector<std::filesystem::path> buffers;
  if (cacheable) buffers = gltf_external_buffers(file);
  const FileStatus status = with_external_buffers(file_status_of(st), buffers);
  RAYLOD_ASSIGN_OR_RETURN(std::shared_ptr<const LoadedModel> loaded, load_uncached(file, uint64_t(st.st_size)));
  if (cacheable) {
    std::lock_guard<std::mutex> lock(mutex);
    cached = loaded;
    // Larger files are shared only while a reader holds them, so that a
    // render does not keep a huge glTF's buffers beside its own mesh.
    kept = loaded->file_bytes <= (uint64_t(256) << 20) ? loaded : nullptr;
    cached_path = canonical.string();
    cached_status = status;
    cached_buffers = std::move(buffers);
  }
  return loaded;
}

}  // namespace raylod::gltf
