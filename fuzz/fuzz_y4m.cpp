// libFuzzer target: the Y4M header parser (the first line), then the stream
// reader (Y4mSource) over the whole input held in a memfd: open, read frames
// until the end or an error, rewind once and read again. Any header is
// opened: the source must not allocate a frame the file cannot hold (run
// with -malloc_limit_mb below the largest frame, 16384 x 16384 x 3 bytes).
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "tcpest/hal/camera/file_sources.hpp"

namespace {

using namespace tcpest;

constexpr int kMaxPixels = 128 * 128;
constexpr int kMaxFrames = 8;

int memory_file() {
  static const int fd = static_cast<int>(::memfd_create("fuzz_y4m", MFD_CLOEXEC));
  return fd;
}

bool fill(int fd, const std::uint8_t* data, std::size_t size) {
  if (::ftruncate(fd, 0) != 0) {
    return false;
  }
  std::size_t done = 0U;
  while (done < size) {
    const ssize_t wrote = ::pwrite(fd, data + done, size - done, static_cast<off_t>(done));
    if (wrote <= 0) {
      return false;
    }
    done += static_cast<std::size_t>(wrote);
  }
  return true;
}

void read_frames(hal::Y4mSource& source) {
  static std::uint8_t pixels[static_cast<std::size_t>(kMaxPixels) * 3U];
  MutableImageView out{pixels, source.width(), source.height(), static_cast<std::size_t>(source.width()) * 3U};
  hal::FrameInfo info{};
  for (int pass = 0; pass < 2; ++pass) {
    for (int i = 0; i < kMaxFrames; ++i) {
      if (!source.acquire(out, info).ok()) {
        break;
      }
    }
    static_cast<void>(source.stop_reason());
    if (!source.reopen().ok()) {
      break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const char* text = reinterpret_cast<const char*>(data);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): bytes as text
  const void* newline = std::memchr(data, '\n', size);
  const std::size_t line = newline != nullptr ? static_cast<std::size_t>(static_cast<const std::uint8_t*>(newline) - data) : size;
  char detail[160] = {};
  const auto header = hal::parse_y4m_header(text, line, detail, sizeof detail);

  const int fd = memory_file();
  if (fd < 0 || !fill(fd, data, size)) {
    __builtin_trap();  // the harness itself is broken
  }
  char path[64] = {};
  std::snprintf(path, sizeof path, "/proc/self/fd/%d", fd);
  static_cast<void>(header);  // open() parses the header again; both must hold up
  hal::ReplayOptions options;
  options.loop = (size % 2U) == 1U;
  auto source = hal::Y4mSource::open(path, options, detail, sizeof detail);
  if (source.ok() && source.value()->width() * source.value()->height() <= kMaxPixels) {
    read_frames(*source.value());
  }
  return 0;
}
