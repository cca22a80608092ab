// libFuzzer target: the JPEG decoder of hal/camera (libjpeg-turbo behind the
// decoder's arena and its one error guard): header inspection, then a decode
// into a buffer of the image's size, or of a wrong size when the image is
// larger than the decoder was sized for. Every failure must be an error
// value, and the decoder must stay usable after it.
#include <cstddef>
#include <cstdint>

#include "tcpest/hal/camera/jpeg_decoder.hpp"

namespace {

using namespace tcpest;

constexpr int kMaxWidth = 320;
constexpr int kMaxHeight = 240;
std::uint8_t g_pixels[static_cast<std::size_t>(kMaxWidth) * kMaxHeight * 3U];

hal::JpegDecoder& decoder() {
  static hal::JpegDecoder instance;
  if (!instance.initialised() && !instance.init(kMaxWidth, kMaxHeight).ok()) {
    __builtin_trap();  // the harness itself is broken
  }
  return instance;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  hal::JpegDecoder& jpeg = decoder();
  const auto info = jpeg.inspect(data, size);
  MutableImageView out{g_pixels, 8, 8, 8U * 3U};  // wrong size for most images: kWrongSize
  if (info.ok() && info.value().width > 0 && info.value().height > 0 && info.value().width <= kMaxWidth &&
      info.value().height <= kMaxHeight) {
    out.width = info.value().width;
    out.height = info.value().height;
    out.stride_bytes = static_cast<std::size_t>(out.width) * 3U;
  }
  static_cast<void>(jpeg.decode(data, size, out));  // refusal is a valid outcome
  static_cast<void>(jpeg.last_message());
  return 0;
}
