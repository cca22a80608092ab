#include "tcpest/hal/camera/file_sources.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <new>

namespace tcpest {
namespace hal {

namespace {

constexpr std::size_t kMaxPath = 4096U;
constexpr std::size_t kMaxHeaderLine = 512U;
// A Y4M frame's tag: "FRAME" and the '\n' (or ' ' before parameters) after it.
constexpr std::size_t kY4mFrameTagBytes = 6U;

CameraError from_errno(int error) noexcept {
  switch (error) {
    case ENOENT:
    case ENOTDIR:
      return CameraError::kNotFound;
    case ENODEV:
    case ENXIO:
      return CameraError::kDeviceLost;
    case ENOMEM:
      return CameraError::kOutOfMemory;
    default:
      return CameraError::kIo;
  }
}

bool ends_with_jpeg(const char* name) noexcept {
  const std::size_t n = std::strlen(name);
  const char* suffixes[] = {".jpg", ".jpeg", ".JPG", ".JPEG"};
  for (const char* suffix : suffixes) {
    const std::size_t s = std::strlen(suffix);
    if (n > s && std::strcmp(name + n - s, suffix) == 0) {
      return true;
    }
  }
  return false;
}

// Reads exactly `size` bytes unless the file ends first; EINTR is retried.
Result<std::size_t, CameraError> read_fully(int fd, std::uint8_t* out, std::size_t size) noexcept {
  std::size_t done = 0U;
  while (done < size) {
    const ssize_t n = ::read(fd, out + done, size - done);
    if (n < 0) {
      if (errno == EINTR) {
        continue;
      }
      return Result<std::size_t, CameraError>::failure(from_errno(errno));
    }
    if (n == 0) {
      break;
    }
    done += static_cast<std::size_t>(n);
  }
  return Result<std::size_t, CameraError>::success(done);
}

void close_quietly(int fd) noexcept {
  if (fd >= 0) {
    static_cast<void>(::close(fd));  // read-only descriptor: nothing to flush, nothing to report
  }
}

bool parse_int(const char* text, std::size_t length, int& out) noexcept {
  if (length == 0U || length > 9U) {
    return false;
  }
  int value = 0;
  for (std::size_t i = 0; i < length; ++i) {
    if (text[i] < '0' || text[i] > '9') {
      return false;
    }
    value = value * 10 + (text[i] - '0');
  }
  out = value;
  return true;
}

// The JPEG paths of a replay, NUL-separated in one block, in play order.
struct FileList {
  std::unique_ptr<char[]> names;         // all paths, NUL-separated
  std::unique_ptr<std::size_t[]> offsets;  // start of each path in names
  std::size_t count = 0U;
};

// The *.jpg / *.jpeg files of a directory sorted by name, the first
// max_files of them: every name is listed and sorted before the cut, so the
// frames kept do not depend on the file system's order.
Status<CameraError> list_directory(const char* path, std::size_t max_files, FileList& list) noexcept {
  // First pass: the total size of the names, so that one block holds them all.
  std::size_t bytes = 0U;
  std::size_t count = 0U;
  char prefix[kMaxPath] = {};
  static_cast<void>(std::snprintf(prefix, sizeof prefix, "%s/", path));  // paths longer than 4 KiB fail open() later
  DIR* dir = ::opendir(path);
  if (dir == nullptr) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  for (const dirent* e = ::readdir(dir); e != nullptr; e = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe): start-up, one thread
    if (ends_with_jpeg(e->d_name)) {
      bytes += std::strlen(prefix) + std::strlen(e->d_name) + 1U;
      ++count;
    }
  }
  ::closedir(dir);
  if (count == 0U) {
    return Status<CameraError>::failure(CameraError::kNotFound);
  }
  list.names.reset(new (std::nothrow) char[bytes]);
  list.offsets.reset(new (std::nothrow) std::size_t[count]);
  if (!list.names || !list.offsets) {
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  dir = ::opendir(path);
  if (dir == nullptr) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  std::size_t at = 0U;
  std::size_t n = 0U;
  for (const dirent* e = ::readdir(dir); e != nullptr && n < count; e = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe): start-up, one thread
    if (ends_with_jpeg(e->d_name)) {
      const int written = std::snprintf(list.names.get() + at, bytes - at, "%s%s", prefix, e->d_name);
      if (written < 0 || static_cast<std::size_t>(written) >= bytes - at) {
        break;  // the directory changed between the passes: keep what fits
      }
      list.offsets[n++] = at;
      at += static_cast<std::size_t>(written) + 1U;
    }
  }
  ::closedir(dir);
  list.count = n;
  const char* names = list.names.get();
  std::sort(list.offsets.get(), list.offsets.get() + list.count,
            [names](std::size_t a, std::size_t b) { return std::strcmp(names + a, names + b) < 0; });
  list.count = std::min(list.count, max_files);
  return ok_status<CameraError>();
}

// Reads a whole list file of `size` bytes into `text`, NUL-terminated;
// `length` is the number of bytes read.
Status<CameraError> read_list_text(const char* path, std::size_t size, std::unique_ptr<char[]>& text,
                                   std::size_t& length) noexcept {
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  text.reset(new (std::nothrow) char[size + 1U]);
  if (!text) {
    close_quietly(fd);
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  const auto got = read_fully(fd, reinterpret_cast<std::uint8_t*>(text.get()), size);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): bytes of a text file
  close_quietly(fd);
  if (!got.ok()) {
    return Status<CameraError>::failure(got.error());
  }
  text[got.value()] = '\0';
  length = got.value();
  return ok_status<CameraError>();
}

// A list file of `size` bytes: one path per line (at most max_files), relative
// paths relative to the list's directory; blank lines and '#' comments skipped.
Status<CameraError> list_file(const char* path, std::size_t size, std::size_t max_files, FileList& list) noexcept {
  // A list file: read it whole, one path per line.
  std::unique_ptr<char[]> text;
  std::size_t length = 0U;
  const auto read = read_list_text(path, size, text, length);
  if (!read.ok()) {
    return read;
  }
  char prefix[kMaxPath] = {};
  const char* slash = std::strrchr(path, '/');
  if (slash != nullptr) {
    const auto dir_len = static_cast<std::size_t>(slash - path) + 1U;
    if (dir_len < sizeof prefix) {
      std::memcpy(prefix, path, dir_len);
      prefix[dir_len] = '\0';
    }
  }
  const std::size_t prefix_len = std::strlen(prefix);
  // Every line costs at most prefix + line + NUL.
  std::size_t lines = 1U;
  for (std::size_t i = 0; i < length; ++i) {
    if (text[i] == '\n') {
      ++lines;
    }
  }
  const std::size_t bytes = length + lines * (prefix_len + 1U) + 1U;
  list.names.reset(new (std::nothrow) char[bytes]);
  list.offsets.reset(new (std::nothrow) std::size_t[lines]);
  if (!list.names || !list.offsets) {
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  std::size_t at = 0U;
  char* line = text.get();
  for (std::size_t l = 0; l < lines && list.count < max_files; ++l) {
    char* end = std::strchr(line, '\n');
    if (end != nullptr) {
      *end = '\0';
    }
    std::size_t len = std::strlen(line);
    while (len > 0U && (line[len - 1U] == '\r' || line[len - 1U] == ' ')) {
      line[--len] = '\0';
    }
    if (len > 0U && line[0] != '#') {
      const char* use_prefix = line[0] == '/' ? "" : prefix;
      const int written = std::snprintf(list.names.get() + at, bytes - at, "%s%s", use_prefix, line);
      if (written > 0 && static_cast<std::size_t>(written) < bytes - at) {
        list.offsets[list.count++] = at;
        at += static_cast<std::size_t>(written) + 1U;
      }
    }
    if (end == nullptr) {
      break;
    }
    line = end + 1;
  }
  if (list.count == 0U) {
    return Status<CameraError>::failure(CameraError::kNotFound);
  }
  return ok_status<CameraError>();
}

}  // namespace

std::int64_t monotonic_now_ns() noexcept {
  timespec ts{};
  static_cast<void>(clock_gettime(CLOCK_MONOTONIC, &ts));  // cannot fail with a valid pointer
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + static_cast<std::int64_t>(ts.tv_nsec);
}

// ---------------------------------------------------------------- JPEG files

JpegFileSource::~JpegFileSource() = default;

Result<std::unique_ptr<JpegFileSource>, CameraError> JpegFileSource::open(const char* path,
                                                                        const ReplayOptions& options) noexcept {
  using R = Result<std::unique_ptr<JpegFileSource>, CameraError>;
  if (path == nullptr || options.max_files == 0U) {
    return R::failure(CameraError::kBadArgument);
  }
  std::unique_ptr<JpegFileSource> source(new (std::nothrow) JpegFileSource());
  if (!source) {
    return R::failure(CameraError::kOutOfMemory);
  }
  struct stat st {};
  if (::stat(path, &st) != 0) {
    return R::failure(from_errno(errno));
  }
  FileList list;
  const auto listed = S_ISDIR(st.st_mode) ? list_directory(path, options.max_files, list)
                                          : list_file(path, static_cast<std::size_t>(st.st_size), options.max_files, list);
  if (!listed.ok()) {
    return R::failure(listed.error());
  }
  source->names_ = std::move(list.names);
  source->offsets_ = std::move(list.offsets);
  source->count_ = list.count;
  source->rate_hz_ = options.rate_hz > 0.0 ? options.rate_hz : 25.0;
  source->loop_ = options.loop;
  source->width_ = options.width;
  source->height_ = options.height;
  // The image size: configured, else the first readable file's.
  source->file_capacity_ = std::size_t{16U} * 1024U * 1024U;
  if (options.width > 0 && options.height > 0) {
    source->file_capacity_ = static_cast<std::size_t>(options.width) * static_cast<std::size_t>(options.height) * 3U +
                             std::size_t{1024U} * 1024U;
  }
  source->file_buffer_.reset(new (std::nothrow) std::uint8_t[source->file_capacity_]);
  if (!source->file_buffer_) {
    return R::failure(CameraError::kOutOfMemory);
  }
  JpegDecoder probe;
  if (!probe.init(16384, 16384).ok()) {
    return R::failure(CameraError::kOutOfMemory);
  }
  if (source->width_ <= 0 || source->height_ <= 0) {
    std::size_t size = 0U;
    const auto read = source->read_file(source->file_name(0U), size);
    if (!read.ok()) {
      return R::failure(read.error());
    }
    const auto info = probe.inspect(source->file_buffer_.get(), size);
    if (!info.ok()) {
      return R::failure(info.error());
    }
    source->width_ = info.value().width;
    source->height_ = info.value().height;
    // Now the file buffer can shrink to what this image size needs.
    source->file_capacity_ = static_cast<std::size_t>(source->width_) * static_cast<std::size_t>(source->height_) * 3U +
                             std::size_t{1024U} * 1024U;
    source->file_buffer_.reset(new (std::nothrow) std::uint8_t[source->file_capacity_]);
    if (!source->file_buffer_) {
      return R::failure(CameraError::kOutOfMemory);
    }
  }
  const auto init = source->decoder_.init(source->width_, source->height_);
  if (!init.ok()) {
    return R::failure(init.error());
  }
  return R::success(std::move(source));
}

const char* JpegFileSource::file_name(std::size_t i) const noexcept {
  return i < count_ ? names_.get() + offsets_[i] : "";
}

Status<CameraError> JpegFileSource::read_file(const char* path, std::size_t& size) noexcept {
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  // One byte more than the buffer's capacity tells a too-large file from a full one.
  const auto got = read_fully(fd, file_buffer_.get(), file_capacity_);
  close_quietly(fd);
  if (!got.ok()) {
    return Status<CameraError>::failure(got.error());
  }
  if (got.value() == file_capacity_) {
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  size = got.value();
  return ok_status<CameraError>();
}

Status<CameraError> JpegFileSource::acquire(const MutableImageView& out, FrameInfo& info) noexcept {
  if (next_ >= count_) {
    if (!loop_) {
      return Status<CameraError>::failure(CameraError::kEndOfStream);
    }
    next_ = 0U;
  }
  info.timestamp_ns = monotonic_now_ns();
  info.sequence = sequence_++;
  last_file_ = file_name(next_);
  ++next_;
  std::size_t size = 0U;
  const auto read = read_file(last_file_, size);
  if (!read.ok()) {
    return read;
  }
  return decoder_.decode(file_buffer_.get(), size, out);
}

Status<CameraError> JpegFileSource::reopen() noexcept {
  next_ = 0U;
  return ok_status<CameraError>();
}

// ---------------------------------------------------------------------- Y4M

namespace {

// Writes why a Y4M file is refused (a printf format and its values) into
// `detail`, when given; returns `error`.
template <typename... Values>
CameraError explain(char* detail, std::size_t capacity, CameraError error, const char* format,
                    Values... values) noexcept {
  static_assert(sizeof...(Values) > 0U, "a plain message goes through \"%s\"");
  if (detail != nullptr && capacity > 0U) {
    static_cast<void>(std::snprintf(detail, capacity, format, values...));  // a message: truncation is harmless
  }
  return error;
}

// The colour spaces taken: 8 bits per sample, with chroma. The 4:2:0 siting
// variants read alike (nearest sample).
bool parse_colour_space(const char* value, std::size_t length, ChromaLayout& layout) noexcept {
  struct Known {
    const char* tag;
    ChromaLayout layout;
  };
  constexpr Known kKnown[] = {{"420", ChromaLayout::k420},      {"420jpeg", ChromaLayout::k420},
                              {"420mpeg2", ChromaLayout::k420}, {"420paldv", ChromaLayout::k420},
                              {"422", ChromaLayout::k422},      {"444", ChromaLayout::k444}};
  for (const Known& known : kKnown) {
    if (std::strlen(known.tag) == length && std::strncmp(value, known.tag, length) == 0) {
      layout = known.layout;
      return true;
    }
  }
  return false;
}

// One header tag (its letter, then `value` of `length` bytes) into `header`.
CameraError parse_header_tag(char tag, const char* value, std::size_t length, Y4mHeader& header, char* detail,
                             std::size_t capacity) noexcept {
  const int shown = static_cast<int>(std::min<std::size_t>(length, 32U));
  switch (tag) {
    case 'W':
    case 'H':
      if (!parse_int(value, length, tag == 'W' ? header.width : header.height)) {
        return explain(detail, capacity, CameraError::kCorrupt, "bad header tag '%c%.*s'", tag, shown, value);
      }
      break;
    case 'F': {
      const char* colon = static_cast<const char*>(std::memchr(value, ':', length));
      if (colon == nullptr || !parse_int(value, static_cast<std::size_t>(colon - value), header.rate_num) ||
          !parse_int(colon + 1, length - static_cast<std::size_t>(colon - value) - 1U, header.rate_den)) {
        return explain(detail, capacity, CameraError::kCorrupt, "bad header tag 'F%.*s'", shown, value);
      }
      break;
    }
    case 'I':
      header.interlaced = length > 0U && value[0] != 'p' && value[0] != '?';
      break;
    case 'C':
      if (!parse_colour_space(value, length, header.layout)) {
        return explain(detail, capacity, CameraError::kUnsupported,
                       "colour space 'C%.*s' not supported (8-bit 4:2:0, 4:2:2 or 4:4:4 only: C420, C420jpeg, "
                       "C420mpeg2, C420paldv, C422, C444)",
                       shown, value);
      }
      break;
    case 'X':
      if (length == 15U && std::strncmp(value, "COLORRANGE=FULL", 15U) == 0) {
        header.range = YuvRange::kFull;
      }
      break;
    default:
      break;  // A (aspect) and unknown tags do not change the pixels
  }
  return CameraError::kNone;
}

}  // namespace

Result<Y4mHeader, CameraError> parse_y4m_header(const char* line, std::size_t length, char* detail,
                                                std::size_t detail_capacity) noexcept {
  using R = Result<Y4mHeader, CameraError>;
  constexpr char kMagic[] = "YUV4MPEG2";
  constexpr std::size_t kMagicLen = sizeof kMagic - 1U;
  if (line == nullptr || length < kMagicLen || std::strncmp(line, kMagic, kMagicLen) != 0) {
    return R::failure(explain(detail, detail_capacity, CameraError::kCorrupt, "%s", "not a YUV4MPEG2 header"));
  }
  Y4mHeader header;  // no C tag: 4:2:0, the format's default
  std::size_t i = kMagicLen;
  while (i < length) {
    while (i < length && line[i] == ' ') {
      ++i;
    }
    std::size_t end = i;
    while (end < length && line[end] != ' ') {
      ++end;
    }
    if (end == i) {
      break;
    }
    const CameraError e = parse_header_tag(line[i], line + i + 1, end - i - 1U, header, detail, detail_capacity);
    if (e != CameraError::kNone) {
      return R::failure(e);
    }
    i = end;
  }
  if (header.width <= 0 || header.height <= 0 || header.width > 16384 || header.height > 16384) {
    return R::failure(explain(detail, detail_capacity, CameraError::kCorrupt,
                              "frame size %dx%d outside 1..16384 (W and H tags)", header.width, header.height));
  }
  if (header.rate_num < 0 || header.rate_den <= 0) {
    return R::failure(explain(detail, detail_capacity, CameraError::kCorrupt, "bad frame rate %d:%d (F tag)",
                              header.rate_num, header.rate_den));
  }
  return R::success(header);
}

Y4mSource::~Y4mSource() { close_quietly(fd_); }

double Y4mSource::rate_hz() const noexcept {
  return header_.rate_den > 0 ? static_cast<double>(header_.rate_num) / static_cast<double>(header_.rate_den) : 0.0;
}

Result<std::unique_ptr<Y4mSource>, CameraError> Y4mSource::open(const char* path, const ReplayOptions& options,
                                                                char* detail, std::size_t detail_capacity) noexcept {
  using R = Result<std::unique_ptr<Y4mSource>, CameraError>;
  if (path == nullptr) {
    return R::failure(CameraError::kBadArgument);
  }
  std::unique_ptr<Y4mSource> source(new (std::nothrow) Y4mSource());
  if (!source) {
    return R::failure(CameraError::kOutOfMemory);
  }
  source->fd_ = ::open(path, O_RDONLY | O_CLOEXEC);
  if (source->fd_ < 0) {
    return R::failure(from_errno(errno));
  }
  char line[kMaxHeaderLine] = {};
  std::size_t length = 0U;
  bool complete = false;
  while (length + 1U < sizeof line) {
    std::uint8_t c = 0U;
    const auto got = read_fully(source->fd_, &c, 1U);
    if (!got.ok()) {
      return R::failure(got.error());
    }
    if (got.value() == 0U) {
      break;
    }
    if (c == '\n') {
      complete = true;
      break;
    }
    line[length++] = static_cast<char>(c);
  }
  if (!complete) {
    return R::failure(explain(detail, detail_capacity, length == 0U ? CameraError::kTruncated : CameraError::kCorrupt,
                              "%s", length == 0U ? "empty file" : "no complete YUV4MPEG2 header line"));
  }
  const auto header = parse_y4m_header(line, length, detail, detail_capacity);
  if (!header.ok()) {
    return R::failure(header.error());
  }
  source->header_ = header.value();
  if ((options.width > 0 && options.width != source->header_.width) ||
      (options.height > 0 && options.height != source->header_.height)) {
    return R::failure(CameraError::kWrongSize);
  }
  source->data_offset_ = static_cast<long long>(length) + 1;
  source->frame_bytes_ = planar_frame_bytes(source->header_.width, source->header_.height, source->header_.layout);
  struct stat st {};
  if (::fstat(source->fd_, &st) == 0 && S_ISREG(st.st_mode)) {
    const long long file_bytes = static_cast<long long>(st.st_size);
    if (file_bytes <= source->data_offset_) {
      return R::failure(explain(detail, detail_capacity, CameraError::kEndOfStream, "%s",
                                "no frame after the header (an empty stream)"));
    }
    // A file too short for one frame is refused before its buffer is taken:
    // a few bytes must not make the source allocate up to 805 MB.
    const long long first_frame_end = source->data_offset_ + static_cast<long long>(kY4mFrameTagBytes) +
                                      static_cast<long long>(source->frame_bytes_);
    if (file_bytes < first_frame_end) {
      return R::failure(explain(detail, detail_capacity, CameraError::kTruncated,
                                "the file's %lld bytes hold no complete %dx%d frame (%zu bytes after its FRAME tag)",
                                file_bytes, source->header_.width, source->header_.height, source->frame_bytes_));
    }
  }
  source->frame_.reset(new (std::nothrow) std::uint8_t[source->frame_bytes_]);
  if (!source->frame_) {
    return R::failure(CameraError::kOutOfMemory);
  }
  std::memset(source->frame_.get(), 0, source->frame_bytes_);  // pre-fault
  source->loop_ = options.loop;
  return R::success(std::move(source));
}

Status<CameraError> Y4mSource::skip_frame_parameters() noexcept {
  std::size_t skipped = 0U;
  std::uint8_t c = 0U;
  do {
    const auto got = read_fully(fd_, &c, 1U);
    if (!got.ok()) {
      return Status<CameraError>::failure(got.error());
    }
    if (got.value() == 0U) {
      return Status<CameraError>::failure(CameraError::kTruncated);
    }
    ++skipped;
  } while (c != '\n' && skipped < kMaxHeaderLine);
  return c == '\n' ? ok_status<CameraError>() : Status<CameraError>::failure(CameraError::kCorrupt);
}

// Looks for the next "FRAME" tag (followed by ' ' or '\n') from byte `from`
// on, in at most kY4mResyncFrames frame sizes, and leaves the stream at its
// 'F'. The frame being read is lost either way (kCorrupt); when no tag is
// found the source stops. The frame buffer is the scratch space.
Status<CameraError> Y4mSource::resync(long long from) noexcept {
  constexpr char kTag[] = "FRAME";
  constexpr std::size_t kTagLength = sizeof kTag - 1U;
  const std::size_t limit = kY4mResyncFrames * (frame_bytes_ + kMaxHeaderLine);
  if (::lseek(fd_, static_cast<off_t>(from), SEEK_SET) < 0) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  std::size_t scanned = 0U;
  std::size_t matched = 0U;
  // Each pass reads at least one byte or returns: bounded by `limit`.
  while (scanned < limit) {
    const auto got = read_fully(fd_, frame_.get(), std::min(frame_bytes_, limit - scanned));
    if (!got.ok()) {
      return Status<CameraError>::failure(got.error());
    }
    if (got.value() == 0U) {
      return Status<CameraError>::failure(CameraError::kCorrupt);  // the data ends: the next read says so
    }
    for (std::size_t i = 0U; i < got.value(); ++i) {
      const std::uint8_t c = frame_[i];
      if (matched == kTagLength) {
        if (c == ' ' || c == '\n') {
          const long long tag_at = from + static_cast<long long>(scanned + i) - static_cast<long long>(kTagLength);
          if (::lseek(fd_, static_cast<off_t>(tag_at), SEEK_SET) < 0) {
            return Status<CameraError>::failure(from_errno(errno));
          }
          return Status<CameraError>::failure(CameraError::kCorrupt);
        }
        matched = 0U;
      }
      if (c == static_cast<std::uint8_t>(kTag[matched])) {
        ++matched;
      } else {
        matched = c == static_cast<std::uint8_t>(kTag[0]) ? 1U : 0U;
      }
    }
    scanned += got.value();
  }
  stopped_ = true;
  static_cast<void>(std::snprintf(stop_reason_, sizeof stop_reason_,
                                  "damaged stream: no FRAME tag in the %zu bytes from byte %lld on", limit,
                                  from));  // a message: truncation is harmless
  return Status<CameraError>::failure(CameraError::kCorrupt);
}

Status<CameraError> Y4mSource::read_frame() noexcept {
  // "FRAME" then optional parameters, then '\n'.
  std::uint8_t tag[kY4mFrameTagBytes] = {};
  auto got = read_fully(fd_, tag, sizeof tag);
  if (!got.ok()) {
    return Status<CameraError>::failure(got.error());
  }
  if (got.value() == 0U) {
    return Status<CameraError>::failure(CameraError::kEndOfStream);
  }
  if (got.value() < sizeof tag) {
    return Status<CameraError>::failure(CameraError::kTruncated);
  }
  if (std::memcmp(tag, "FRAME", 5U) != 0 || (tag[5] != '\n' && tag[5] != ' ')) {
    // Not a frame tag: look for the next one from the byte after this one's start.
    const off_t at = ::lseek(fd_, 0, SEEK_CUR);
    if (at < 0) {
      return Status<CameraError>::failure(from_errno(errno));
    }
    return resync(static_cast<long long>(at) - static_cast<long long>(sizeof tag) + 1);
  }
  if (tag[5] == ' ') {
    const auto skipped = skip_frame_parameters();
    if (!skipped.ok()) {
      if (skipped.error() != CameraError::kCorrupt) {
        return skipped;
      }
      const off_t at = ::lseek(fd_, 0, SEEK_CUR);  // a parameter line longer than any header: damaged
      return at < 0 ? Status<CameraError>::failure(from_errno(errno)) : resync(static_cast<long long>(at));
    }
  }
  got = read_fully(fd_, frame_.get(), frame_bytes_);
  if (!got.ok()) {
    return Status<CameraError>::failure(got.error());
  }
  if (got.value() < frame_bytes_) {
    return Status<CameraError>::failure(CameraError::kTruncated);
  }
  return ok_status<CameraError>();
}

Status<CameraError> Y4mSource::acquire(const MutableImageView& out, FrameInfo& info) noexcept {
  if (!out.valid()) {
    return Status<CameraError>::failure(CameraError::kBadArgument);
  }
  if (out.width != header_.width || out.height != header_.height) {
    return Status<CameraError>::failure(CameraError::kWrongSize);
  }
  if (stopped_) {
    return Status<CameraError>::failure(CameraError::kEndOfStream);  // damaged: replaying it again would not help
  }
  info.timestamp_ns = monotonic_now_ns();
  auto status = read_frame();
  if (!status.ok() && status.error() == CameraError::kEndOfStream && loop_) {
    const auto rewound = reopen();
    if (!rewound.ok()) {
      return rewound;
    }
    status = read_frame();
  }
  if (!status.ok()) {
    return status;
  }
  info.sequence = sequence_++;
  planar_yuv_to_rgb(frame_.get(), header_.width, header_.height, header_.layout, header_.range, out);
  return ok_status<CameraError>();
}

Status<CameraError> Y4mSource::reopen() noexcept {
  if (::lseek(fd_, static_cast<off_t>(data_offset_), SEEK_SET) < 0) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  stopped_ = false;
  stop_reason_[0] = '\0';
  return ok_status<CameraError>();
}

Y4mWriter::~Y4mWriter() { static_cast<void>(close()); }  // a destructor cannot report; call close() to know

Status<CameraError> Y4mWriter::open(const char* path, int width, int height, int rate_num, int rate_den) noexcept {
  if (fd_ >= 0 || path == nullptr || width <= 0 || height <= 0 || rate_num <= 0 || rate_den <= 0) {
    return Status<CameraError>::failure(CameraError::kBadArgument);
  }
  width_ = width;
  height_ = height;
  frame_bytes_ = planar_frame_bytes(width, height, ChromaLayout::k420);
  frame_.reset(new (std::nothrow) std::uint8_t[frame_bytes_]);
  if (!frame_) {
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  fd_ = ::open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    return Status<CameraError>::failure(from_errno(errno));
  }
  char header[128] = {};
  const int n = std::snprintf(header, sizeof header, "YUV4MPEG2 W%d H%d F%d:%d Ip A1:1 C420jpeg XYSCSS=420JPEG XCOLORRANGE=FULL\n",
                              width, height, rate_num, rate_den);
  if (n <= 0 || ::write(fd_, header, static_cast<std::size_t>(n)) != n) {
    return Status<CameraError>::failure(CameraError::kIo);
  }
  return ok_status<CameraError>();
}

Status<CameraError> Y4mWriter::write(const ImageView& rgb) noexcept {
  if (fd_ < 0 || !rgb.valid() || rgb.width != width_ || rgb.height != height_) {
    return Status<CameraError>::failure(CameraError::kBadArgument);
  }
  rgb_to_planar_yuv420(rgb, YuvRange::kFull, frame_.get());
  if (::write(fd_, "FRAME\n", 6U) != 6) {
    return Status<CameraError>::failure(CameraError::kIo);
  }
  std::size_t done = 0U;
  while (done < frame_bytes_) {
    const ssize_t n = ::write(fd_, frame_.get() + done, frame_bytes_ - done);
    if (n <= 0) {
      if (n < 0 && errno == EINTR) {
        continue;
      }
      return Status<CameraError>::failure(CameraError::kIo);
    }
    done += static_cast<std::size_t>(n);
  }
  return ok_status<CameraError>();
}

Status<CameraError> Y4mWriter::close() noexcept {
  if (fd_ < 0) {
    return ok_status<CameraError>();
  }
  const int rc = ::close(fd_);
  fd_ = -1;
  return rc == 0 ? ok_status<CameraError>() : Status<CameraError>::failure(CameraError::kIo);
}

}  // namespace hal
}  // namespace tcpest
