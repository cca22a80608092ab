// Writing rendered frames: JPEG through libjpeg-turbo (the encoder keeps its
// output buffer, sized once for the largest frame, so encoding allocates
// nothing per frame) and raw binary PPM (P6). File errors are values.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace render {

enum class ImageIoError : std::uint8_t {
  OutOfMemory,   // encoder or buffer allocation failed
  BadImage,      // invalid view, or larger than the encoder was made for
  BadQuality,    // JPEG quality outside 1..100
  EncodeFailed,  // libjpeg-turbo reported an error
  OpenFailed,    // the file could not be created
  WriteFailed,   // short write or close error (disk full, ...)
};
const char* to_string(ImageIoError e) noexcept;

// The JPEG's chroma subsampling: 4:2:0 (the default, most cameras'), 4:2:2, 4:4:4.
enum class ChromaSubsampling : std::uint8_t { k420, k422, k444 };
const char* to_string(ChromaSubsampling subsampling) noexcept;  // "420", "422", "444"

class JpegEncoder {
 public:
  // For frames up to max_width x max_height.
  static Result<std::unique_ptr<JpegEncoder>, ImageIoError> create(int max_width, int max_height) noexcept;
  ~JpegEncoder();
  JpegEncoder(const JpegEncoder&) = delete;
  JpegEncoder& operator=(const JpegEncoder&) = delete;
  JpegEncoder(JpegEncoder&&) = delete;
  JpegEncoder& operator=(JpegEncoder&&) = delete;

  // Encodes (4:2:0 chroma, quality 1..100). The bytes stay valid until the next call.
  Status<ImageIoError> encode(const ImageView& image, int quality,
                              ChromaSubsampling subsampling = ChromaSubsampling::k420) noexcept;
  const std::uint8_t* data() const noexcept { return buffer_; }
  std::size_t size() const noexcept { return size_; }
  // Encodes and writes to `path`.
  Status<ImageIoError> write_file(const ImageView& image, int quality, const char* path,
                                  ChromaSubsampling subsampling = ChromaSubsampling::k420) noexcept;

 private:
  JpegEncoder() noexcept = default;
  void* handle_ = nullptr;
  std::uint8_t* buffer_ = nullptr;
  std::size_t capacity_ = 0U;
  std::size_t size_ = 0U;
  int max_width_ = 0;
  int max_height_ = 0;
};

// Binary PPM (P6, maxval 255).
Status<ImageIoError> write_ppm_file(const ImageView& image, const char* path) noexcept;

// PNG (8-bit RGB, uncompressed deflate blocks: large files, no zlib needed;
// meant for previews and documentation figures). No allocation: written with
// write(2) through a fixed buffer; on WriteFailed errno says why.
Status<ImageIoError> write_png_file(const ImageView& image, const char* path) noexcept;

// Writes `size` bytes to `path` (created or truncated).
Status<ImageIoError> write_bytes_file(const char* path, const void* data, std::size_t size) noexcept;

}  // namespace render
}  // namespace tcpest
