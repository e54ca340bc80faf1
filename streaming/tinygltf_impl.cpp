// tinygltf's implementation, compiled here (route 2 of Debian's
// README.Debian for libtinygltf-dev) rather than linked from
// libtinygltf.so: libdraco.so exports a bundled, older tinygltf under the
// same symbol names with other struct layouts, so whichever library the
// loader finds first would serve calls made against the other's header
// (measured: FsCallbacks freed as std::function, a crash). Compiled into the
// binary, raylod's own references resolve here at link time. Without stb:
// raylod decodes no images (streaming/gltf_model.h sets the macros for
// every file that includes tiny_gltf.h).
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
