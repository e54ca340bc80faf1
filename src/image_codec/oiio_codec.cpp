// libraylod_oiio.so: the OpenImageIO side of render/image_codec.h. Every
// call to OpenImageIO in raylod is here; the program loads this module only
// when it reads, writes, compares or draws an image.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "render/image_codec.h"

namespace raylod {
namespace {

OIIO::TypeDesc type_of(PixelType t) {
  switch (t) {
    case PixelType::UInt8: return OIIO::TypeDesc::UINT8;
    case PixelType::UInt32: return OIIO::TypeDesc::UINT32;
    case PixelType::Float: return OIIO::TypeDesc::FLOAT;
  }
  return OIIO::TypeDesc::FLOAT;
}

bool has_writer(const std::string& writer) { return OIIO::ImageOutput::create(writer) != nullptr; }

Encoded encode_once(const EncodeRequest& r, bool into_memory) {
  Encoded result;
  auto out = OIIO::ImageOutput::create(r.writer);
  if (!out) {
    result.error = "cannot write images of this type (" + OIIO::geterror() + ")";
    return result;
  }
  OIIO::ImageSpec spec(r.layout.width, r.layout.height, r.layout.channels, type_of(r.layout.type));
  if (!r.channel_names.empty()) spec.channelnames = r.channel_names;
  if (r.srgb) spec.attribute("oiio:ColorSpace", "sRGB");
  if (r.png_filter >= 0) spec.attribute("png:filter", r.png_filter);
  // No timestamp in the file (an empty DateTime stops the EXR writer from
  // adding one): the same render gives the same bytes.
  spec.attribute("DateTime", "");
  // Writers that can encode into memory do (libjpeg's, for one, ends the
  // process on a failed file write); the program then writes the bytes,
  // checking every write.
  OIIO::Filesystem::IOVecOutput memory(result.bytes);
  result.in_memory = into_memory && out->supports("ioproxy") && out->set_ioproxy(&memory);
  if (!out->open(r.file, spec)) {
    result.error = "cannot open for writing: " + out->geterror();
    return result;
  }
  const bool wrote = out->write_image(type_of(r.layout.type), r.pixels);
  const bool closed = out->close();
  if (!wrote || !closed) result.error = "write failed (disk full?): " + out->geterror();
  return result;
}

Encoded encode(const EncodeRequest& r) {
  Encoded result = encode_once(r, true);
  // A writer that takes the memory proxy, puts nothing in it and reports
  // success (OpenJPEG's, for .jp2 and .j2k: a 0-byte file, exit 0) fails.
  if (result.error.empty() && result.in_memory && result.bytes.empty())
    result.error = "the image writer wrote nothing (this build's writer does not encode such images)";
  return result;
}

Decoded decode(const std::string& path) {
  Decoded result;
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    result.error = OIIO::geterror();
    return result;
  }
  const OIIO::ImageSpec& spec = in->spec();
  result.layout = {spec.width, spec.height, spec.nchannels, PixelType::Float};
  result.integer = spec.format.basetype == OIIO::TypeDesc::UINT8 || spec.format.basetype == OIIO::TypeDesc::UINT16;
  result.pixels.resize(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, result.pixels.data())) {
    result.error = in->geterror();
    if (result.error.empty()) result.error = "truncated";
  }
  in->close();
  return result;
}

OIIO::ImageBuf float_buffer(const float* pixels, const PixelLayout& l) {
  OIIO::ImageBuf buf(OIIO::ImageSpec(l.width, l.height, l.channels, OIIO::TypeDesc::FLOAT));
  buf.set_pixels(OIIO::ROI::All(), OIIO::TypeDesc::FLOAT, pixels);
  return buf;
}

Comparison compare(const float* a, const float* b, const PixelLayout& layout) {
  const OIIO::ImageBuf ba = float_buffer(a, layout), bb = float_buffer(b, layout);
  const auto cr = OIIO::ImageBufAlgo::compare(ba, bb, 0.01f, 1.0f);
  return {cr.PSNR, cr.maxerror, cr.meanerror, uint64_t(cr.nwarn + cr.nfail)};
}

void draw(float* rgb, int width, int height, const std::vector<DrawOp>& ops, const char* font) {
  const PixelLayout layout{width, height, 3, PixelType::Float};
  OIIO::ImageBuf img = float_buffer(rgb, layout);
  bool text_ok = true;
  for (const DrawOp& op : ops) {
    const OIIO::cspan<float> color(op.color, 3);
    switch (op.kind) {
      case DrawOp::Kind::Line: OIIO::ImageBufAlgo::render_line(img, op.x0, op.y0, op.x1, op.y1, color); break;
      case DrawOp::Kind::Box: OIIO::ImageBufAlgo::render_box(img, op.x0, op.y0, op.x1, op.y1, color); break;
      case DrawOp::Kind::FilledBox: OIIO::ImageBufAlgo::render_box(img, op.x0, op.y0, op.x1, op.y1, color, true); break;
      case DrawOp::Kind::Text:
        // After a text fails (no font), the rest are left out too.
        if (text_ok) text_ok = OIIO::ImageBufAlgo::render_text(img, op.x0, op.y0, op.text, op.size, font, color);
        break;
    }
  }
  img.get_pixels(OIIO::ROI::All(), OIIO::TypeDesc::FLOAT, rgb);
}

const ImageCodec kCodec{.abi = kImageCodecAbi, .has_writer = has_writer, .encode = encode, .decode = decode,
                        .compare = compare, .draw = draw};

}  // namespace
}  // namespace raylod

extern "C" __attribute__((visibility("default"))) const raylod::ImageCodec* raylod_image_codec() {
  // OpenImageIO and OpenEXR single-threaded: no thread pools of their own
  // beside raylod's TBB workers (raylod's images are encoded one at a time,
  // and libpng's encoder has no threads to use). Pool threads started by a
  // module loaded with dlopen also made LeakSanitizer's exit-time check
  // crash now and then ("Tracer caught signal 11") in the sanitizer suite.
  static const bool configured = [] {
    OIIO::attribute("threads", 1);
    OIIO::attribute("exr_threads", -1);  // OpenEXR without a thread pool
    return true;
  }();
  (void)configured;
  return &raylod::kCodec;
}
