// JPEG decoding into a caller-owned RGB buffer (libjpeg-turbo).
//
// Every failure is a value: a corrupt, truncated or wrongly sized JPEG returns
// an error and leaves the decoder ready for the next image. libjpeg reports
// fatal errors through a callback that must not return; ours longjmps back to
// one small guarded function (see jpeg_decoder.cpp) - the only setjmp in tcpest.
// libjpeg warnings (corrupt entropy data, premature end of file) are errors too:
// a frame that libjpeg would "repair" with grey is not one to measure on.
//
// Memory: libjpeg's allocations for a decode are served from a fixed arena
// owned by the decoder, sized at init() from the largest image it must decode,
// so a baseline (sequential) decode makes no heap allocation. Progressive JPEGs
// need libjpeg's whole-image coefficient buffer, which still comes from libjpeg's
// own allocator (malloc): that is the bounded deviation documented in
// hal/camera/README.md. The libjpeg context itself is created once in init().
#pragma once

#include <cstddef>
#include <cstdint>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/hal/camera/camera_error.hpp"

namespace tcpest {
namespace hal {

struct JpegInfo {
  int width = 0;
  int height = 0;
  int components = 0;
  bool progressive = false;
};

// Usage statistics of the decoder's arena, for tests and the README's numbers.
struct JpegArenaStats {
  std::size_t capacity_bytes = 0U;
  std::size_t permanent_bytes = 0U;      // allocations that live as long as the decoder
  std::size_t image_high_water_bytes = 0U;  // most per-image bytes any decode needed
  std::size_t fallback_allocations = 0U;  // decodes that had to use libjpeg's own allocator (progressive)
};

class JpegDecoder {
 public:
  JpegDecoder() noexcept = default;
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;
  JpegDecoder(JpegDecoder&&) = delete;
  JpegDecoder& operator=(JpegDecoder&&) = delete;

  // Allocates the libjpeg context and the arena for images up to
  // max_width x max_height. Called once, before the loop. `arena_bytes`: 0
  // for the default size (256 KiB + 64 RGB rows of max_width, several times
  // what any sampling needs: hal/camera/README.md), else that size (rounded
  // up to 64 B; more than 256 MiB is kBadArgument); a decode that needs more
  // returns kOutOfMemory.
  Status<CameraError> init(int max_width, int max_height, std::size_t arena_bytes = 0U) noexcept;
  bool initialised() const noexcept { return context_ != nullptr; }

  // Reads only the header.
  Result<JpegInfo, CameraError> inspect(const std::uint8_t* data, std::size_t size) noexcept;

  // Decodes `data` into `out`, which must have exactly the image's size
  // (otherwise kWrongSize, checked before any pixel is written). Greyscale
  // JPEGs are expanded to RGB. On error the content of `out` is unspecified.
  Status<CameraError> decode(const std::uint8_t* data, std::size_t size, const MutableImageView& out) noexcept;

  JpegArenaStats arena_stats() const noexcept;
  // libjpeg's text for the last error (for logs), "" if none.
  const char* last_message() const noexcept;

  struct Context;  // libjpeg state and the arena (jpeg_decoder.cpp)

 private:
  Context* context_ = nullptr;
};

}  // namespace hal
}  // namespace tcpest
