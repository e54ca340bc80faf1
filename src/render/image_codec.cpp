#include "render/image_codec.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <thread>

namespace raylod {
namespace {

// Where the module may be, in the order tried (image_codec.h).
std::vector<std::filesystem::path> candidates() {
  if (const char* env = std::getenv("RAYLOD_IMAGE_CODEC"); env && *env) return {std::filesystem::path(env)};
  std::vector<std::filesystem::path> paths;
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec && self.has_parent_path()) {
    const std::filesystem::path dir = self.parent_path();
    paths.push_back(dir / kImageCodecModule);
    paths.push_back(dir.parent_path() / kImageCodecModule);
    paths.push_back(dir.parent_path() / "lib" / "raylod" / kImageCodecModule);
  }
  return paths;
}

StatusOr<const ImageCodec*> load() {
  const auto paths = candidates();
  std::string tried;
  for (const auto& path : paths) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) {
      tried += (tried.empty() ? "" : ", ") + path.string();
      continue;
    }
    // RTLD_LOCAL: OpenImageIO's symbols stay the module's.
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* why = dlerror();
      return Status::error("cannot load the image codec " + path.string() + ": " + (why ? why : "dlopen failed") +
                           " (is OpenImageIO installed? tools/setup.sh installs it)");
    }
    using Entry = const ImageCodec* (*)();
    auto entry = reinterpret_cast<Entry>(dlsym(handle, kImageCodecEntry));
    const ImageCodec* codec = entry ? entry() : nullptr;
    if (!codec || codec->abi != kImageCodecAbi)
      return Status::error("the image codec " + path.string() +
                           " is from another build of raylod (rebuild it with the program)");
    return codec;  // never unloaded: the table points into it
  }
  return Status::error(std::string("cannot find the image codec ") + kImageCodecModule +
                       ", which reads and writes images (tried: " + (tried.empty() ? "nothing" : tried) +
                       "; set RAYLOD_IMAGE_CODEC to its path)");
}

}  // namespace

StatusOr<const ImageCodec*> image_codec() {
  static std::once_flag once;
  // Never destroyed: start_loading_image_codec's thread may still be
  // assigning it while the process exits (it is joined after the statics
  // constructed after it are gone).
  static StatusOr<const ImageCodec*>* codec = new StatusOr<const ImageCodec*>(Status::error("not loaded"));
  std::call_once(once, [] { *codec = load(); });
  return *codec;
}

void start_loading_image_codec() {
  // A static owner joins the thread at exit, so the process never ends
  // while it is inside the dynamic loader.
  struct Loader {
    std::thread thread{[] { (void)image_codec(); }};
    ~Loader() {
      if (thread.joinable()) thread.join();
    }
  };
  static Loader loader;
}

}  // namespace raylod
