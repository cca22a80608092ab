#include "tcpest/render/image_io.hpp"

#include <fcntl.h>
#include <turbojpeg.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>

namespace tcpest {
namespace render {

const char* to_string(ImageIoError e) noexcept {
  switch (e) {
    case ImageIoError::OutOfMemory: return "out of memory";
    case ImageIoError::BadImage: return "invalid image (or larger than the encoder was made for)";
    case ImageIoError::BadQuality: return "JPEG quality must be 1..100";
    case ImageIoError::EncodeFailed: return "JPEG encoding failed";
    case ImageIoError::OpenFailed: return "cannot create the file";
    case ImageIoError::WriteFailed: return "write failed (disk full?)";
  }
  return "unknown image I/O error";
}

Result<std::unique_ptr<JpegEncoder>, ImageIoError> JpegEncoder::create(int max_width, int max_height) noexcept {
  using R = Result<std::unique_ptr<JpegEncoder>, ImageIoError>;
  if (max_width <= 0 || max_height <= 0 || max_width > 16384 || max_height > 16384) {
    return R::failure(ImageIoError::BadImage);
  }
  std::unique_ptr<JpegEncoder> e(new (std::nothrow) JpegEncoder());
  if (!e) {
    return R::failure(ImageIoError::OutOfMemory);
  }
  e->handle_ = tjInitCompress();
  if (e->handle_ == nullptr) {
    return R::failure(ImageIoError::OutOfMemory);
  }
  const unsigned long bound = tjBufSize(max_width, max_height, TJSAMP_444);  // >= any subsampling
  if (bound == static_cast<unsigned long>(-1)) {
    return R::failure(ImageIoError::BadImage);
  }
  e->buffer_ = tjAlloc(static_cast<int>(bound));
  if (e->buffer_ == nullptr) {
    return R::failure(ImageIoError::OutOfMemory);
  }
  e->capacity_ = bound;
  e->max_width_ = max_width;
  e->max_height_ = max_height;
  return R::success(std::move(e));
}

JpegEncoder::~JpegEncoder() {
  if (buffer_ != nullptr) {
    tjFree(buffer_);
  }
  if (handle_ != nullptr) {
    static_cast<void>(tjDestroy(handle_));  // nothing to do about a failure at teardown
  }
}

const char* to_string(ChromaSubsampling subsampling) noexcept {
  switch (subsampling) {
    case ChromaSubsampling::k420: return "420";
    case ChromaSubsampling::k422: return "422";
    case ChromaSubsampling::k444: return "444";
  }
  return "?";
}

Status<ImageIoError> JpegEncoder::encode(const ImageView& image, int quality, ChromaSubsampling subsampling) noexcept {
  if (!image.valid() || image.width > max_width_ || image.height > max_height_) {
    return Status<ImageIoError>::failure(ImageIoError::BadImage);
  }
  if (quality < 1 || quality > 100) {
    return Status<ImageIoError>::failure(ImageIoError::BadQuality);
  }
  unsigned char* out = buffer_;
  unsigned long size = capacity_;
  // TJFLAG_NOREALLOC: write into our buffer (sized by tjBufSize), never reallocate.
  const int samp = subsampling == ChromaSubsampling::k444   ? TJSAMP_444
                   : subsampling == ChromaSubsampling::k422 ? TJSAMP_422
                                                            : TJSAMP_420;
  const int rc = tjCompress2(handle_, image.data, image.width, static_cast<int>(image.stride_bytes), image.height,
                             TJPF_RGB, &out, &size, samp, quality, TJFLAG_NOREALLOC | TJFLAG_ACCURATEDCT);
  if (rc != 0 || out != buffer_) {
    return Status<ImageIoError>::failure(ImageIoError::EncodeFailed);
  }
  size_ = size;
  return ok_status<ImageIoError>();
}

Status<ImageIoError> JpegEncoder::write_file(const ImageView& image, int quality, const char* path,
                                             ChromaSubsampling subsampling) noexcept {
  const auto encoded = encode(image, quality, subsampling);
  if (!encoded.ok()) {
    return encoded;
  }
  return write_bytes_file(path, buffer_, size_);
}

Status<ImageIoError> write_bytes_file(const char* path, const void* data, std::size_t size) noexcept {
  std::FILE* file = std::fopen(path, "wb");
  if (file == nullptr) {
    return Status<ImageIoError>::failure(ImageIoError::OpenFailed);
  }
  const std::size_t written = std::fwrite(data, 1U, size, file);
  const int closed = std::fclose(file);
  if (written != size || closed != 0) {
    return Status<ImageIoError>::failure(ImageIoError::WriteFailed);
  }
  return ok_status<ImageIoError>();
}

Status<ImageIoError> write_ppm_file(const ImageView& image, const char* path) noexcept {
  if (!image.valid()) {
    return Status<ImageIoError>::failure(ImageIoError::BadImage);
  }
  std::FILE* file = std::fopen(path, "wb");
  if (file == nullptr) {
    return Status<ImageIoError>::failure(ImageIoError::OpenFailed);
  }
  bool ok = std::fprintf(file, "P6\n%d %d\n255\n", image.width, image.height) > 0;
  const auto row_bytes = static_cast<std::size_t>(image.width) * 3U;
  for (int y = 0; y < image.height && ok; ++y) {
    ok = std::fwrite(image.row(y), 1U, row_bytes, file) == row_bytes;
  }
  const int closed = std::fclose(file);
  if (!ok || closed != 0) {
    return Status<ImageIoError>::failure(ImageIoError::WriteFailed);
  }
  return ok_status<ImageIoError>();
}

namespace {

// The CRC-32 of every byte value (PNG's polynomial), computed at compile time:
// one lookup per byte instead of eight shifts (an overlay is 1.2 MB).
constexpr std::array<std::uint32_t, 256> make_crc32_table() noexcept {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t n = 0; n < 256U; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k) {
      c = (c >> 1U) ^ (0xEDB88320U & (0U - (c & 1U)));
    }
    table[n] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrc32Table = make_crc32_table();

std::uint32_t crc32_update(std::uint32_t crc, const std::uint8_t* data, std::size_t size) noexcept {
  crc = ~crc;
  for (std::size_t i = 0; i < size; ++i) {
    crc = kCrc32Table[(crc ^ data[i]) & 0xFFU] ^ (crc >> 8U);
  }
  return ~crc;
}

// Adler-32 over `size` bytes; the modulo once per 5552 bytes (zlib's NMAX,
// the most that cannot overflow 32 bits) instead of twice per byte.
void adler32_update(std::uint32_t& a, std::uint32_t& b, const std::uint8_t* data, std::size_t size) noexcept {
  constexpr std::size_t kMaxRun = 5552U;
  while (size > 0U) {
    const std::size_t run = size < kMaxRun ? size : kMaxRun;
    for (std::size_t i = 0; i < run; ++i) {
      a += data[i];
      b += a;
    }
    a %= 65521U;
    b %= 65521U;
    data += run;
    size -= run;
  }
}

// Streams PNG chunks to a file descriptor through a fixed buffer, with the
// chunk CRC and the zlib Adler-32. No allocation (the recorder's writer
// thread writes overlays with it); a failed write(2) keeps its errno.
class PngStream {
 public:
  explicit PngStream(int fd) noexcept : fd_(fd) {}
  bool put(const void* data, std::size_t size) noexcept {
    crc_ = crc32_update(crc_, static_cast<const std::uint8_t*>(data), size);
    const auto* bytes = static_cast<const std::uint8_t*>(data);
    while (ok_ && size > 0U) {
      const std::size_t n = size < buffer_.size() - used_ ? size : buffer_.size() - used_;
      std::memcpy(buffer_.data() + used_, bytes, n);
      used_ += n;
      bytes += n;
      size -= n;
      if (used_ == buffer_.size()) {
        ok_ = flush();
      }
    }
    return ok_;
  }
  bool put_u32(std::uint32_t v) noexcept {
    const std::uint8_t b[4] = {static_cast<std::uint8_t>(v >> 24U), static_cast<std::uint8_t>(v >> 16U),
                               static_cast<std::uint8_t>(v >> 8U), static_cast<std::uint8_t>(v)};
    return put(b, 4U);
  }
  bool begin_chunk(const char* type, std::uint32_t length) noexcept {
    static_cast<void>(put_u32(length));  // the CRC covers type and data only: reset after the length
    crc_ = 0U;
    return put(type, 4U);
  }
  bool end_chunk() noexcept {
    const std::uint32_t crc = crc_;
    return put_u32(crc);
  }
  // Writes what is buffered; false (errno set) when a write failed.
  bool flush() noexcept {
    std::size_t done = 0U;
    int interrupted = 0;
    while (ok_ && done < used_) {
      const ssize_t n = ::write(fd_, buffer_.data() + done, used_ - done);
      if (n > 0) {
        done += static_cast<std::size_t>(n);
      } else if (n < 0 && errno == EINTR && interrupted < 100) {
        ++interrupted;
      } else {
        if (n == 0) {
          errno = ENOSPC;  // no progress on a regular file: no room
        }
        ok_ = false;
      }
    }
    used_ = 0U;
    return ok_;
  }
  bool ok() const noexcept { return ok_; }

 private:
  int fd_;
  std::array<std::uint8_t, 16384> buffer_{};
  std::size_t used_ = 0U;
  std::uint32_t crc_ = 0U;
  bool ok_ = true;
};

}  // namespace

Status<ImageIoError> write_png_file(const ImageView& image, const char* path) noexcept {
  if (!image.valid() || image.width > 16384 || image.height > 16384) {
    return Status<ImageIoError>::failure(ImageIoError::BadImage);
  }
  const int fd = ::open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return Status<ImageIoError>::failure(ImageIoError::OpenFailed);
  }
  PngStream png(fd);
  const std::uint8_t signature[8] = {0x89U, 'P', 'N', 'G', '\r', '\n', 0x1AU, '\n'};
  static_cast<void>(png.put(signature, 8U));  // errors accumulate in png.ok()
  static_cast<void>(png.begin_chunk("IHDR", 13U));
  static_cast<void>(png.put_u32(static_cast<std::uint32_t>(image.width)));
  static_cast<void>(png.put_u32(static_cast<std::uint32_t>(image.height)));
  const std::uint8_t header[5] = {8U, 2U, 0U, 0U, 0U};  // 8-bit, RGB, deflate, no filter method, no interlace
  static_cast<void>(png.put(header, 5U));
  static_cast<void>(png.end_chunk());
  // One stored deflate block per row (row = filter byte + 3 * width <= 65535).
  const auto row_bytes = static_cast<std::uint32_t>(image.width) * 3U + 1U;
  const auto rows = static_cast<std::uint32_t>(image.height);
  const std::uint32_t data_length = 2U + rows * (5U + row_bytes) + 4U;
  static_cast<void>(png.begin_chunk("IDAT", data_length));
  const std::uint8_t zlib_header[2] = {0x78U, 0x01U};
  static_cast<void>(png.put(zlib_header, 2U));
  std::uint32_t adler_a = 1U;
  std::uint32_t adler_b = 0U;
  for (std::uint32_t y = 0; y < rows; ++y) {
    const std::uint8_t last = (y + 1U == rows) ? 1U : 0U;
    const auto len = static_cast<std::uint16_t>(row_bytes);
    const auto nlen = static_cast<std::uint16_t>(~len);
    const std::uint8_t block[5] = {last, static_cast<std::uint8_t>(len & 0xFFU), static_cast<std::uint8_t>(len >> 8U),
                                   static_cast<std::uint8_t>(nlen & 0xFFU), static_cast<std::uint8_t>(nlen >> 8U)};
    static_cast<void>(png.put(block, 5U));
    const std::uint8_t filter = 0U;
    static_cast<void>(png.put(&filter, 1U));
    adler_b = (adler_b + adler_a) % 65521U;  // the filter byte (0) adds nothing to a
    const std::uint8_t* row = image.row(static_cast<int>(y));
    static_cast<void>(png.put(row, row_bytes - 1U));
    adler32_update(adler_a, adler_b, row, row_bytes - 1U);
  }
  static_cast<void>(png.put_u32((adler_b << 16U) | adler_a));
  static_cast<void>(png.end_chunk());
  static_cast<void>(png.begin_chunk("IEND", 0U));
  static_cast<void>(png.end_chunk());
  const bool written = png.flush();
  const int write_errno = errno;
  const int closed = ::close(fd);
  if (!written) {
    errno = write_errno;  // the write's reason, not the close's
  }
  if (!written || closed != 0) {
    return Status<ImageIoError>::failure(ImageIoError::WriteFailed);
  }
  return ok_status<ImageIoError>();
}

}  // namespace render
}  // namespace tcpest
