// Replay sources: JPEG files and YUV4MPEG2 video. Both read with plain
// open()/read() (no stdio buffers) into buffers sized at open(); both restart
// from the first frame when `loop` is set (long replays of a short recording).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/hal/camera/jpeg_decoder.hpp"
#include "tcpest/hal/camera/pixel_formats.hpp"

namespace tcpest {
namespace hal {

struct ReplayOptions {
  int width = 0;          // the loop's image size; 0 = take it from the first file / the header
  int height = 0;
  double rate_hz = 25.0;  // JPEG files carry no rate; Y4M's header rate wins when present
  bool loop = false;      // start again after the last frame instead of kEndOfStream
  std::size_t max_files = 100000U;  // frames kept: the first names of a directory, the first lines of a list
};

// A directory of *.jpg / *.jpeg (sorted by name) or a text file listing one
// JPEG path per line (relative paths are relative to the list's directory).
class JpegFileSource final : public FrameSource {
 public:
  static Result<std::unique_ptr<JpegFileSource>, CameraError> open(const char* path,
                                                                   const ReplayOptions& options) noexcept;
  ~JpegFileSource() override;
  JpegFileSource(const JpegFileSource&) = delete;
  JpegFileSource& operator=(const JpegFileSource&) = delete;
  JpegFileSource(JpegFileSource&&) = delete;
  JpegFileSource& operator=(JpegFileSource&&) = delete;

  const char* kind() const noexcept override { return "jpeg"; }
  int width() const noexcept override { return width_; }
  int height() const noexcept override { return height_; }
  double rate_hz() const noexcept override { return rate_hz_; }
  bool live() const noexcept override { return false; }
  Status<CameraError> acquire(const MutableImageView& out, FrameInfo& info) noexcept override;
  Status<CameraError> reopen() noexcept override;

  std::size_t file_count() const noexcept { return count_; }
  const char* file_name(std::size_t i) const noexcept;
  // The file of the last acquire (for error messages).
  const char* last_file() const noexcept { return last_file_; }
  const JpegDecoder& decoder() const noexcept { return decoder_; }

 private:
  JpegFileSource() noexcept = default;
  Status<CameraError> read_file(const char* path, std::size_t& size) noexcept;

  JpegDecoder decoder_;
  std::unique_ptr<char[]> names_;         // all paths, NUL-separated
  std::unique_ptr<std::size_t[]> offsets_;  // start of each path in names_
  std::unique_ptr<std::uint8_t[]> file_buffer_;
  std::size_t file_capacity_ = 0U;
  std::size_t count_ = 0U;
  std::size_t next_ = 0U;
  std::uint32_t sequence_ = 0U;
  const char* last_file_ = "";
  int width_ = 0;
  int height_ = 0;
  double rate_hz_ = 25.0;
  bool loop_ = false;
};

struct Y4mHeader {
  int width = 0;
  int height = 0;
  int rate_num = 25;
  int rate_den = 1;
  ChromaLayout layout = ChromaLayout::k420;
  YuvRange range = YuvRange::kLimited;
  bool interlaced = false;
};

// Parses the stream header line (without its '\n'): "YUV4MPEG2 W720 H576 F25:1 Ip A1:1 C420jpeg ...".
// Colour spaces taken: 8-bit 4:2:0 (C420, C420jpeg, C420mpeg2, C420paldv),
// C422 and C444; any other C tag (high bit depths such as C420p10, mono,
// alpha, 4:1:1) is kUnsupported. On failure `detail` (when given) says what
// was wrong, naming the tag.
Result<Y4mHeader, CameraError> parse_y4m_header(const char* line, std::size_t length, char* detail = nullptr,
                                                std::size_t detail_capacity = 0U) noexcept;

// A damaged stream (a frame tag that is not "FRAME"): the frame is dropped
// (kCorrupt) and the next "FRAME" tag is looked for in at most this many
// frame sizes after it; without one the source stops (stop_reason()).
constexpr std::size_t kY4mResyncFrames = 2U;

class Y4mSource final : public FrameSource {
 public:
  // `detail` (optional) says why the file is refused: the header's fault, or
  // a file that holds no frame after its header (kEndOfStream).
  static Result<std::unique_ptr<Y4mSource>, CameraError> open(const char* path, const ReplayOptions& options,
                                                              char* detail = nullptr,
                                                              std::size_t detail_capacity = 0U) noexcept;
  ~Y4mSource() override;
  Y4mSource(const Y4mSource&) = delete;
  Y4mSource& operator=(const Y4mSource&) = delete;
  Y4mSource(Y4mSource&&) = delete;
  Y4mSource& operator=(Y4mSource&&) = delete;

  const char* kind() const noexcept override { return "y4m"; }
  int width() const noexcept override { return header_.width; }
  int height() const noexcept override { return header_.height; }
  double rate_hz() const noexcept override;
  bool live() const noexcept override { return false; }
  Status<CameraError> acquire(const MutableImageView& out, FrameInfo& info) noexcept override;
  Status<CameraError> reopen() noexcept override;
  const char* stop_reason() const noexcept override { return stopped_ ? stop_reason_ : nullptr; }
  const Y4mHeader& header() const noexcept { return header_; }

 private:
  Y4mSource() noexcept = default;
  Status<CameraError> read_frame() noexcept;
  Status<CameraError> skip_frame_parameters() noexcept;
  Status<CameraError> resync(long long from) noexcept;

  int fd_ = -1;
  Y4mHeader header_{};
  long long data_offset_ = 0;  // first "FRAME" byte
  std::unique_ptr<std::uint8_t[]> frame_;
  std::size_t frame_bytes_ = 0U;
  std::uint32_t sequence_ = 0U;
  bool loop_ = false;
  bool stopped_ = false;      // damaged beyond resynchronisation: kEndOfStream until reopen()
  char stop_reason_[160] = {};
};

// Writes RGB frames as a YUV4MPEG2 C420jpeg file (full-range, as ffmpeg's
// "-pix_fmt yuvj420p"): test fixtures, the bench dataset, recordings.
class Y4mWriter {
 public:
  Y4mWriter() noexcept = default;
  ~Y4mWriter();
  Y4mWriter(const Y4mWriter&) = delete;
  Y4mWriter& operator=(const Y4mWriter&) = delete;
  Y4mWriter(Y4mWriter&&) = delete;
  Y4mWriter& operator=(Y4mWriter&&) = delete;

  Status<CameraError> open(const char* path, int width, int height, int rate_num, int rate_den) noexcept;
  Status<CameraError> write(const ImageView& rgb) noexcept;
  Status<CameraError> close() noexcept;

 private:
  int fd_ = -1;
  int width_ = 0;
  int height_ = 0;
  std::unique_ptr<std::uint8_t[]> frame_;
  std::size_t frame_bytes_ = 0U;
};

}  // namespace hal
}  // namespace tcpest
