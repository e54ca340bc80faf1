// Image files through OpenImageIO, loaded only when an image is read or
// written.
//
// Why a module. Debian's OpenImageIO brings about 270 shared libraries (GDCM,
// OpenCV, libheif, Poppler, ...); binding them took 0.4 to 0.55 s at every
// start of `raylod` on this machine (`raylod --version`; a test binary
// without them starts in 0.02 s), most of it in the dynamic loader. Every
// command paid it, and every rank of an `mpirun` job, though only the rank
// that writes a frame needs an image writer, and `build`, `probe`,
// `simplify`, `info` and `gen` need none. So the OpenImageIO calls live in
// one module, libraylod_oiio.so (src/image_codec/oiio_codec.cpp), that
// image_codec() loads with dlopen the first time an image is read, written,
// compared or drawn.
//
// The module is found (first that exists): $RAYLOD_IMAGE_CODEC (a path to
// it), beside the running program, in the program's parent folder (the
// tests and tools under build/), and in ../lib/raylod/ from the program. A
// missing or broken module is an error naming the paths tried.
//
// The interface. Module and program are built together by one compiler and
// standard library, so the table below passes C++ types; kImageCodecAbi
// guards against a module left from another build. The module holds no
// raylod code: it encodes, decodes, compares and draws, and the program
// writes the files (atomically, with every write checked).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/status.h"

namespace raylod {

inline constexpr uint32_t kImageCodecAbi = 2;
inline constexpr const char* kImageCodecModule = "libraylod_oiio.so";
inline constexpr const char* kImageCodecEntry = "raylod_image_codec";

enum class PixelType : uint8_t { UInt8, UInt32, Float };

struct PixelLayout {
  int width = 0, height = 0, channels = 0;
  PixelType type = PixelType::Float;
};

struct EncodeRequest {
  // What the writer is chosen by: a file name (its extension) or a format
  // name ("png").
  std::string writer;
  // Where a writer that cannot encode into memory writes the file itself.
  std::string file;
  PixelLayout layout;
  const void* pixels = nullptr;
  std::vector<std::string> channel_names;  // empty: the writer's
  bool srgb = false;                       // tag the pixels as sRGB
  int png_filter = -1;                     // libpng's filter flags; -1: libpng's choice
};

struct Encoded {
  std::string error;                 // empty on success
  bool in_memory = false;            // the bytes below; else the writer wrote `file`
  std::vector<unsigned char> bytes;
};

struct Decoded {
  std::string error;       // empty on success
  PixelLayout layout;      // of `pixels`: floats, whatever the file stores
  bool integer = false;    // the file stores 8- or 16-bit integers (sRGB-encoded)
  std::vector<float> pixels;
};

struct Comparison {
  double psnr = 0, max_error = 0, mean_error = 0;
  uint64_t over_threshold = 0;  // pixels more than 1% off
};

// One drawing step of a plot, in pixels from the top left.
struct DrawOp {
  enum class Kind : uint8_t { Line, Box, FilledBox, Text } kind = Kind::Line;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // Text: x0, y0 its baseline's start
  float color[3] = {0, 0, 0};
  int size = 0;      // Text: pixel size
  std::string text;  // Text
};

struct ImageCodec {
  uint32_t abi = kImageCodecAbi;
  // Whether a writer exists for `writer` (as EncodeRequest::writer).
  bool (*has_writer)(const std::string& writer) = nullptr;
  Encoded (*encode)(const EncodeRequest& request) = nullptr;
  Decoded (*decode)(const std::string& path) = nullptr;
  // a and b: same layout, floats.
  Comparison (*compare)(const float* a, const float* b, const PixelLayout& layout) = nullptr;
  // Draws `ops` in order onto rgb (3 floats a pixel, width x height). Text
  // that cannot be drawn (no font) is left out, and the text after it;
  // everything else is drawn.
  void (*draw)(float* rgb, int width, int height, const std::vector<DrawOp>& ops, const char* font) = nullptr;
};

// The module's table, loaded on first use (thread-safe); the same error on
// every call if it cannot be loaded.
StatusOr<const ImageCodec*> image_codec();
// Starts loading the module on a thread of its own and returns at once, so
// that the 0.4 s of binding OpenImageIO's libraries overlaps other work (a
// run's store stage); image_codec() then waits for what is left of it. The
// thread is joined at exit. Calling it again, or after image_codec(), does
// nothing more.
void start_loading_image_codec();

}  // namespace raylod
