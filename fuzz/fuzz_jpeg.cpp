// libFuzzer target: the JPEG decoder of hal/camera (libjpeg-turbo behind the
// decoder's arena and its one error guard): header inspection, then a decode
// into a buffer of the image's size, or of a wrong size when the image is
// larger than the decoder was sized for. Every failure must be an error
// value, and the decoder must stay usable after it: a reference frame
// (made by the renderer's encoder) must decode after every input.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "tcpest/hal/camera/jpeg_decoder.hpp"
#include "tcpest/render/image_io.hpp"

namespace {

using namespace tcpest;

constexpr int kMaxWidth = 320;
constexpr int kMaxHeight = 240;
constexpr int kReferenceWidth = 24;
constexpr int kReferenceHeight = 16;

// The decoder (made once, as the loop makes it), its output buffer, and the
// reference frame.
struct Harness {
  hal::JpegDecoder decoder;
  std::uint8_t pixels[static_cast<std::size_t>(kMaxWidth) * kMaxHeight * 3U] = {};
  std::uint8_t reference[4096] = {};
  std::size_t reference_size = 0U;
};

void make_reference(Harness& h) {
  static std::uint8_t rgb[static_cast<std::size_t>(kReferenceWidth) * kReferenceHeight * 3U];
  for (std::size_t i = 0U; i < sizeof rgb; ++i) {
    rgb[i] = static_cast<std::uint8_t>(i * 7U);
  }
  auto encoder = render::JpegEncoder::create(kReferenceWidth, kReferenceHeight);
  const ImageView image{rgb, kReferenceWidth, kReferenceHeight, static_cast<std::size_t>(kReferenceWidth) * 3U};
  if (!encoder.ok() || !encoder.value()->encode(image, 80).ok() || encoder.value()->size() > sizeof h.reference) {
    __builtin_trap();  // the harness itself is broken
  }
  h.reference_size = encoder.value()->size();
  std::memcpy(h.reference, encoder.value()->data(), h.reference_size);
}

Harness& harness() {
  static Harness instance;
  if (!instance.decoder.initialised()) {
    if (!instance.decoder.init(kMaxWidth, kMaxHeight).ok()) {
      __builtin_trap();  // the harness itself is broken
    }
    make_reference(instance);
  }
  return instance;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Harness& h = harness();
  const auto info = h.decoder.inspect(data, size);
  MutableImageView out{h.pixels, 8, 8, std::size_t{8U} * 3U};  // wrong size for most images: kWrongSize
  if (info.ok() && info.value().width > 0 && info.value().height > 0 && info.value().width <= kMaxWidth &&
      info.value().height <= kMaxHeight) {
    out.width = info.value().width;
    out.height = info.value().height;
    out.stride_bytes = static_cast<std::size_t>(out.width) * 3U;
  }
  static_cast<void>(h.decoder.decode(data, size, out));  // refusal is a valid outcome
  static_cast<void>(h.decoder.last_message());
  const MutableImageView reference{h.pixels, kReferenceWidth, kReferenceHeight,
                                   static_cast<std::size_t>(kReferenceWidth) * 3U};
  if (!h.decoder.decode(h.reference, h.reference_size, reference).ok()) {
    __builtin_trap();  // the last input left the decoder unusable
  }
  return 0;
}
