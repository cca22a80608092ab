#include "cli/recorder.hpp"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>

#include "cli/cycle_overlay.hpp"
#include "cli/cycles_csv.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/render/image_io.hpp"

namespace tcpest {
namespace cli {

namespace {

// The writer's niceness: below the loop's (0, or SCHED_FIFO).
constexpr int kWriterNice = 10;
// The writer's stack: its buffers are on the heap (allocated at start-up).
constexpr std::size_t kWriterStackBytes = std::size_t{256U} * 1024U;
// How long the writer sleeps when the queue is empty: it then writes what
// came meanwhile in one go (a few wake-ups a second, not one per cycle).
constexpr long kWriterIdleNs = 10'000'000L;
// Bytes of the candump lines of one entry.
constexpr std::size_t kTextBytes = kMaxFramesPerEntry * hal::kCandumpMaxLine;
// The smallest share of the cap a file may have (a few rows).
constexpr std::uint64_t kMinFileBytes = 4096U;
// How long finish() waits for room in the queue for the frames after the last cycle.
constexpr int kFinishWaitPasses = 2500;

// Writes all of `data` to `fd` (retrying short writes and EINTR); 0, or the errno.
int write_fully(int fd, const char* data, std::size_t size) noexcept {
  std::size_t done = 0U;
  int interrupted = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
    } else if (n < 0 && errno == EINTR && interrupted < 100) {
      ++interrupted;
    } else {
      return n < 0 ? errno : ENOSPC;  // write(2) returning 0 for a regular file: no room
    }
  }
  return 0;
}

void sleep_ns(long ns) noexcept {
  const timespec t{0, ns};
  static_cast<void>(::clock_nanosleep(CLOCK_MONOTONIC, 0, &t, nullptr));  // an early wake-up only polls sooner
}

}  // namespace

const char* to_string(RecorderError error) noexcept {
  switch (error) {
    case RecorderError::kNone:
      return "no error";
    case RecorderError::kBadOptions:
      return "bad options";
    case RecorderError::kCannotCreate:
      return "cannot create";
    case RecorderError::kOutOfMemory:
      return "out of memory";
    case RecorderError::kNoThread:
      return "cannot start the writer thread";
  }
  return "unknown";
}

std::uint64_t overlay_png_bytes(int width, int height) noexcept {
  const std::uint64_t row_bytes = static_cast<std::uint64_t>(width) * 3U + 1U;
  const std::uint64_t idat = 2U + static_cast<std::uint64_t>(height) * (5U + row_bytes) + 4U;
  return 8U + (12U + 13U) + (12U + idat) + 12U;  // signature, IHDR, IDAT, IEND
}

// ---- RotatingFile -----------------------------------------------------------

void Recorder::RotatingFile::name(std::uint32_t index, char* out, std::size_t capacity) const noexcept {
  if (index == 0U) {
    static_cast<void>(std::snprintf(out, capacity, "%s/%s.%s", dir_, stem_, ext_));  // sized for the longest
  } else {
    static_cast<void>(std::snprintf(out, capacity, "%s/%s.%u.%s", dir_, stem_, index, ext_));  // idem
  }
}

bool Recorder::RotatingFile::open(const char* dir, const char* stem, const char* ext, std::uint64_t limit,
                                  std::uint32_t keep) noexcept {
  static_cast<void>(std::snprintf(dir_, sizeof dir_, "%s", dir));  // checked by the caller's length test
  static_cast<void>(std::snprintf(stem_, sizeof stem_, "%s", stem));
  static_cast<void>(std::snprintf(ext_, sizeof ext_, "%s", ext));
  limit_ = limit;
  keep_ = keep > 0U ? keep : 1U;
  name(0U, path_, sizeof path_);
  fd_ = ::open(path_, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bytes_ = 0U;
  return fd_ >= 0;
}

int Recorder::RotatingFile::rotate() noexcept {
  int error = close();
  // The oldest is replaced by the one before it, and so on down to the current file.
  for (std::uint32_t i = keep_ - 1U; i >= 1U; --i) {
    char from[448];
    char to[448];
    name(i - 1U, from, sizeof from);
    name(i, to, sizeof to);
    if (::rename(from, to) != 0 && errno != ENOENT && error == 0) {
      error = errno;
    }
  }
  fd_ = ::open(path_, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bytes_ = 0U;
  if (fd_ < 0 && error == 0) {
    error = errno;
  }
  return error;
}

int Recorder::RotatingFile::write(const char* data, std::size_t size, const char* header, std::size_t header_size,
                                  std::uint64_t& rotations) noexcept {
  int error = 0;
  if (limit_ > 0U && bytes_ > header_size && bytes_ + size > limit_) {
    error = rotate();
    ++rotations;
  }
  if (fd_ < 0) {
    return error != 0 ? error : EBADF;
  }
  if (bytes_ == 0U && header != nullptr && header_size > 0U) {
    const int header_error = write_fully(fd_, header, header_size);
    if (header_error != 0) {
      return header_error;
    }
    bytes_ += header_size;
  }
  const int data_error = write_fully(fd_, data, size);
  if (data_error == 0) {
    bytes_ += size;
  }
  return data_error != 0 ? data_error : error;
}

int Recorder::RotatingFile::close() noexcept {
  if (fd_ < 0) {
    return 0;
  }
  const int rc = ::close(fd_);
  fd_ = -1;
  return rc == 0 ? 0 : errno;
}

// ---- Recorder: start-up -----------------------------------------------------

Result<std::unique_ptr<Recorder>, RecorderError> Recorder::create(const RecorderOptions& options,
                                                                   const ModelSetup& models) noexcept {
  using R = Result<std::unique_ptr<Recorder>, RecorderError>;
  if (options.dir == nullptr || options.width <= 0 || options.height <= 0 || options.queue_capacity == 0U ||
      options.queue_capacity > kMaxRecorderQueue || options.keep_files == 0U ||
      options.keep_files > kMaxRecorderKeepFiles || std::strlen(options.dir) > 360U) {
    return R::failure(RecorderError::kBadOptions);
  }
  std::unique_ptr<Recorder> recorder(new (std::nothrow) Recorder(models));
  if (!recorder) {
    return R::failure(RecorderError::kOutOfMemory);
  }
  recorder->options_ = options;
  static_cast<void>(std::snprintf(recorder->dir_, sizeof recorder->dir_, "%s", options.dir));  // length checked
  static_cast<void>(std::snprintf(recorder->overlay_dir_, sizeof recorder->overlay_dir_, "%s/overlays", options.dir));
  // The cap's shares (docs/loop.md, "The recorder").
  const bool overlays = options.overlay_every > 0U;
  if (options.max_bytes > 0U) {
    const std::uint64_t stream_share = overlays ? options.max_bytes / 4U : options.max_bytes / 2U;
    recorder->file_limit_bytes_ = stream_share / options.keep_files;
    recorder->max_overlays_ = overlays ? (options.max_bytes / 2U) / overlay_png_bytes(options.width, options.height) : 0U;
    if (recorder->file_limit_bytes_ < kMinFileBytes || (overlays && recorder->max_overlays_ == 0U)) {
      return R::failure(RecorderError::kBadOptions);
    }
  }
  RecorderError error = recorder->allocate();
  if (error == RecorderError::kNone) {
    error = recorder->open_files();
  }
  if (error != RecorderError::kNone) {
    return R::failure(error);
  }
  // The writer: created now, before the loop's real-time settings (it keeps
  // the normal policy and a lower priority), with a small stack.
  pthread_attr_t attr;
  if (::pthread_attr_init(&attr) != 0) {
    return R::failure(RecorderError::kNoThread);
  }
  static_cast<void>(::pthread_attr_setstacksize(&attr, kWriterStackBytes));  // above PTHREAD_STACK_MIN: cannot fail
  // The writer inherits a mask blocking every signal: SIGINT/SIGTERM must
  // reach the loop's thread, whose sleep they cut short.
  sigset_t all;
  sigset_t previous;
  static_cast<void>(sigfillset(&all));                                // a valid set: cannot fail
  static_cast<void>(::pthread_sigmask(SIG_SETMASK, &all, &previous));  // idem
  const int rc = ::pthread_create(&recorder->thread_, &attr, &Recorder::writer_main, recorder.get());
  static_cast<void>(::pthread_sigmask(SIG_SETMASK, &previous, nullptr));  // idem
  static_cast<void>(::pthread_attr_destroy(&attr));  // an initialised attribute: cannot fail
  if (rc != 0) {
    errno = rc;  // for the caller's message
    return R::failure(RecorderError::kNoThread);
  }
  recorder->thread_started_ = true;
  return R::success(std::move(recorder));
}

RecorderError Recorder::allocate() noexcept {
  const std::size_t frame_bytes =
      static_cast<std::size_t>(options_.width) * static_cast<std::size_t>(options_.height) * 3U;
  if (!queue_.create(options_.queue_capacity)) {
    return RecorderError::kOutOfMemory;
  }
  csv_header_.reset(new (std::nothrow) char[kCyclesCsvMaxLine]);
  text_.reset(new (std::nothrow) char[kTextBytes]);
  if (!csv_header_ || !text_) {
    return RecorderError::kOutOfMemory;
  }
  csv_header_size_ = format_cycles_csv_header(options_.with_truth, csv_header_.get(), kCyclesCsvMaxLine);
  if (options_.overlay_every == 0U) {
    return RecorderError::kNone;
  }
  slot_count_ = options_.overlay_slots > 0U ? options_.overlay_slots : 1U;
  slots_.reset(new (std::nothrow) OverlaySlot[slot_count_]);
  canvas_.reset(new (std::nothrow) std::uint8_t[frame_bytes]);
  if (!slots_ || !canvas_) {
    return RecorderError::kOutOfMemory;
  }
  for (std::uint32_t i = 0; i < slot_count_; ++i) {
    slots_[i].pixels.reset(new (std::nothrow) std::uint8_t[frame_bytes]);
    if (!slots_[i].pixels) {
      return RecorderError::kOutOfMemory;
    }
  }
  if (max_overlays_ > 0U) {
    kept_.reset(new (std::nothrow) std::uint32_t[max_overlays_]);
    if (!kept_) {
      return RecorderError::kOutOfMemory;
    }
  }
  return RecorderError::kNone;
}

RecorderError Recorder::open_files() noexcept {
  if (!make_directory(dir_) || (options_.overlay_every > 0U && !make_directory(overlay_dir_))) {
    const int error = errno == EEXIST ? ENOTDIR : errno;  // there, but not a directory
    note_error(error, dir_);
    errno = error;  // for the caller's message
    return RecorderError::kCannotCreate;
  }
  if (!csv_.open(dir_, "cycles", "csv", file_limit_bytes_, options_.keep_files)) {
    note_error(errno, csv_.path());
    return RecorderError::kCannotCreate;
  }
  if (!can_log_.open(dir_, "can", "log", file_limit_bytes_, options_.keep_files)) {
    note_error(errno, can_log_.path());
    return RecorderError::kCannotCreate;
  }
  return RecorderError::kNone;
}

Recorder::~Recorder() { static_cast<void>(finish()); }  // the result was reported by whoever called finish() first

// ---- Recorder: the producer (the loop's thread) ----------------------------

void Recorder::on_frame(const can::Frame& frame, std::int64_t wall_us) noexcept {
  if (staged_count_ < staged_.size()) {
    staged_[staged_count_] = TappedFrame{frame, wall_us};
    ++staged_count_;
  } else {
    ++staged_lost_;
  }
}

int Recorder::claim_overlay_slot() noexcept {
  for (std::uint32_t i = 0; i < slot_count_; ++i) {
    if (!slots_[i].busy.load(std::memory_order_acquire)) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

void Recorder::on_cycle(const loop::CycleRecord& record, const ImageView& frame) noexcept {
  const bool overlay_cycle = options_.overlay_every > 0U && record.have_frame && frame.valid() &&
                             frame.width == options_.width && frame.height == options_.height &&
                             record.frame_sequence % options_.overlay_every == 0U;
  Entry* entry = finished_ ? nullptr : queue_.begin_push();
  counts_.can_frames_lost += staged_lost_;
  staged_lost_ = 0U;
  if (entry == nullptr) {
    ++counts_.dropped;
    counts_.can_frames_lost += staged_count_;
    counts_.overlays_skipped += overlay_cycle ? 1U : 0U;
    staged_count_ = 0U;
  } else {
    entry->has_row = true;
    entry->cycle = record;
    entry->has_truth = truth_ != nullptr && record.have_frame;
    entry->truth = entry->has_truth ? truth_->last_truth() : hal::FrameTruth{};
    entry->frame_count = staged_count_;
    std::copy_n(staged_.data(), staged_count_, entry->frames.data());
    staged_count_ = 0U;
    entry->overlay_slot = overlay_cycle ? claim_overlay_slot() : -1;
    if (entry->overlay_slot >= 0) {
      OverlaySlot& slot = slots_[static_cast<std::size_t>(entry->overlay_slot)];
      const std::size_t row_bytes = static_cast<std::size_t>(frame.width) * 3U;
      for (int y = 0; y < frame.height; ++y) {
        std::memcpy(slot.pixels.get() + static_cast<std::size_t>(y) * row_bytes, frame.row(y), row_bytes);
      }
      slot.has_extraction = extraction_ != nullptr;
      if (extraction_ != nullptr) {
        slot.extraction = *extraction_;
      }
      slot.busy.store(true, std::memory_order_release);
    } else if (overlay_cycle) {
      ++counts_.overlays_skipped;
    }
    queue_.commit_push();
    ++counts_.entries;
  }
  if (next_ != nullptr) {
    next_->on_cycle(record, frame);
  }
}

bool Recorder::finish() noexcept {
  if (finished_) {
    return !failed_;
  }
  if (thread_started_) {
    // The frames after the last cycle (a final heartbeat, EMCY), if any.
    for (int pass = 0; staged_count_ > 0U && pass < kFinishWaitPasses; ++pass) {
      Entry* entry = queue_.begin_push();
      if (entry == nullptr) {
        sleep_ns(kWriterIdleNs);
        continue;
      }
      entry->has_row = false;
      entry->overlay_slot = -1;
      entry->frame_count = staged_count_;
      std::copy_n(staged_.data(), staged_count_, entry->frames.data());
      staged_count_ = 0U;
      queue_.commit_push();
    }
    counts_.can_frames_lost += staged_count_ + staged_lost_;
    staged_count_ = 0U;
    staged_lost_ = 0U;
    stop_.store(true, std::memory_order_release);
    static_cast<void>(::pthread_join(thread_, nullptr));  // a joinable thread of ours: cannot fail
    thread_started_ = false;
  }
  finished_ = true;
  const int csv_closed = csv_.close();
  if (csv_closed != 0) {
    note_error(csv_closed, csv_.path());
  }
  const int log_closed = can_log_.close();
  if (log_closed != 0) {
    note_error(log_closed, can_log_.path());
  }
  failed_ = write_errors() > 0U;
  return !failed_;
}

// ---- Recorder: the writer ---------------------------------------------------

void* Recorder::writer_main(void* self) noexcept {
  // Below the loop: SCHED_BATCH (its wake-ups do not preempt a running
  // thread, the loop's in particular) and a nice value for this thread alone
  // (Linux threads have their own). Both are preferences: without them the
  // writer still only reads copies.
  const sched_param batch{};
  static_cast<void>(::pthread_setschedparam(::pthread_self(), SCHED_BATCH, &batch));
  static_cast<void>(::setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), kWriterNice));
  static_cast<Recorder*>(self)->writer_loop();
  return nullptr;
}

void Recorder::writer_loop() noexcept {
  for (;;) {
    Entry* entry = queue_.front();
    if (entry == nullptr) {
      // Stop only once the producer has stopped and everything it queued is written.
      if (stop_.load(std::memory_order_acquire) && queue_.empty()) {
        return;
      }
      sleep_ns(kWriterIdleNs);
      continue;
    }
    write_entry(*entry);
    queue_.pop();
  }
}

void Recorder::note_error(int error_number, const char* path) noexcept {
  if (write_errors_.fetch_add(1U, std::memory_order_relaxed) == 0U) {
    first_errno_ = error_number;
    static_cast<void>(std::snprintf(first_error_path_, sizeof first_error_path_, "%s", path));  // for the message
  }
}

void Recorder::write_entry(Entry& entry) noexcept {
  if (entry.has_row) {
    if (t0_ns_ < 0) {
      t0_ns_ = entry.cycle.trigger_ns;
    }
    char row[kCyclesCsvMaxLine];
    const std::size_t n = format_cycles_csv_row(entry.cycle, entry.has_truth ? &entry.truth : nullptr,
                                                options_.with_truth, t0_ns_, row, sizeof row);
    const int error = csv_.write(row, n, csv_header_.get(), csv_header_size_, counts_.rotations);
    if (error != 0) {
      note_error(error, csv_.path());
    } else {
      ++counts_.rows;
    }
  }
  std::size_t used = 0U;
  for (std::uint32_t i = 0; i < entry.frame_count; ++i) {
    used += hal::format_candump_line(entry.frames[i].frame, entry.frames[i].wall_us, options_.can_interface,
                                     text_.get() + used, kTextBytes - used);
  }
  if (used > 0U) {
    const int error = can_log_.write(text_.get(), used, nullptr, 0U, counts_.rotations);
    if (error != 0) {
      note_error(error, can_log_.path());
    } else {
      counts_.can_lines += entry.frame_count;
    }
  }
  if (entry.overlay_slot >= 0) {
    write_overlay(entry);
    slots_[static_cast<std::size_t>(entry.overlay_slot)].busy.store(false, std::memory_order_release);
  }
}

void Recorder::write_overlay(const Entry& entry) noexcept {
  const OverlaySlot& slot = slots_[static_cast<std::size_t>(entry.overlay_slot)];
  const std::size_t stride = static_cast<std::size_t>(options_.width) * 3U;
  const ImageView frame{slot.pixels.get(), options_.width, options_.height, stride};
  const MutableImageView out{canvas_.get(), options_.width, options_.height, stride};
  draw_cycle_overlay(out, frame, slot.has_extraction ? &slot.extraction : nullptr, models_, entry.cycle,
                     entry.has_truth ? &entry.truth : nullptr);
  char path[448];
  // The cap: the oldest overlay makes room for this one.
  if (max_overlays_ > 0U && kept_count_ == max_overlays_) {
    static_cast<void>(std::snprintf(path, sizeof path, "%s/frame_%06u.png", overlay_dir_,
                                    kept_[kept_first_]));  // sized for the longest
    if (::unlink(path) != 0 && errno != ENOENT) {
      note_error(errno, path);
    }
    ++counts_.overlays_removed;
    kept_first_ = kept_first_ + 1U == max_overlays_ ? 0U : kept_first_ + 1U;
    --kept_count_;
  }
  static_cast<void>(std::snprintf(path, sizeof path, "%s/frame_%06u.png", overlay_dir_,
                                  entry.cycle.frame_sequence));  // idem
  if (!render::write_png_file(out.view(), path).ok()) {
    note_error(errno != 0 ? errno : EIO, path);
    return;
  }
  ++counts_.overlays;
  if (max_overlays_ > 0U) {
    kept_[(kept_first_ + kept_count_) % max_overlays_] = entry.cycle.frame_sequence;
    ++kept_count_;
  }
}

void Recorder::print(std::FILE* out, const char* command) const noexcept {
  const RecorderCounts& c = counts_;
  std::fprintf(out,
               "record %s: %llu rows, %llu can lines, %llu overlays (removed %llu, skipped %llu), rotations %llu; "
               "dropped %llu entries (queue full, %llu can frames lost), write errors %llu\n",
               dir_, static_cast<unsigned long long>(c.rows), static_cast<unsigned long long>(c.can_lines),
               static_cast<unsigned long long>(c.overlays), static_cast<unsigned long long>(c.overlays_removed),
               static_cast<unsigned long long>(c.overlays_skipped), static_cast<unsigned long long>(c.rotations),
               static_cast<unsigned long long>(c.dropped), static_cast<unsigned long long>(c.can_frames_lost),
               static_cast<unsigned long long>(write_errors()));
  if (write_errors() > 0U) {
    std::fprintf(stderr, "tcpest %s: record %s: %llu write error(s), the first: %s: %s; the recording is incomplete\n",
                 command, dir_, static_cast<unsigned long long>(write_errors()), first_error_path_,
                 std::strerror(first_errno_));
  }
}

}  // namespace cli
}  // namespace tcpest
