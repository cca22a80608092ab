// The recorder of `tcpest run --record DIR`: cycles.csv (one row per cycle),
// the candump log of every frame the node sent or received (can.log) and
// every Nth cycle's overlay (overlays/frame_NNNNNN.png), within a disk cap.
//
// The cycle never waits for the disk. The loop's thread (the producer) only
// copies a fixed-size entry (the cycle's record, the frame's truth, the CAN
// frames of the cycle) into a fixed-capacity single-producer/single-consumer
// queue and, on an overlay cycle, the frame and the extraction into a free
// preallocated slot. A writer thread of lower priority, started before the
// loop's real-time settings apply, formats and writes. A full queue drops the
// entry and counts it; a busy overlay slot skips the overlay and counts it; a
// failed write is counted with its errno and fails the run (exit 1).
//
// Disk cap: the recording's bytes are split between its streams (with
// overlays: cycles.csv 1/4, can.log 1/4, overlays 1/2; without: 1/2 each).
// A stream's file rotates when it would pass its share divided by the files
// kept (cycles.csv -> cycles.1.csv -> ... -> cycles.K-1.csv, the oldest
// removed); the overlays kept are as many as their share holds, the oldest
// removed first. Everything is allocated by create().
#pragma once

#include <pthread.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>

#include "cli/setup.hpp"
#include "tcpest/can_iface/frame.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/common/spsc_queue.hpp"
#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/loop/can_node_port.hpp"
#include "tcpest/loop/executive.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace cli {

enum class RecorderError : std::uint8_t {
  kNone = 0,
  kBadOptions,    // a size or count out of range, or a cap too small for its streams
  kCannotCreate,  // the directory or a file could not be created (errno in first_errno())
  kOutOfMemory,   // a buffer could not be allocated
  kNoThread,      // the writer thread could not be started
};
const char* to_string(RecorderError error) noexcept;

struct RecorderOptions {
  const char* dir = nullptr;
  int width = 0;  // the frames' size (overlay slots)
  int height = 0;
  std::uint32_t overlay_every = 25U;   // frames; 0: no overlays
  std::uint64_t max_bytes = 0U;        // the whole recording; 0: no cap
  std::uint32_t keep_files = 4U;       // per stream: the current file and keep_files - 1 rotated ones
  std::uint32_t queue_capacity = 256U; // entries (cycles) waiting for the writer
  std::uint32_t overlay_slots = 2U;    // frames waiting to be drawn and written
  bool with_truth = false;             // cycles.csv has the truth columns
  const char* can_interface = "sim0";  // named on every candump line
};

// Limits of the options.
constexpr std::uint32_t kMaxRecorderQueue = 65536U;
constexpr std::uint32_t kMaxRecorderKeepFiles = 100U;
// CAN frames one entry carries (a cycle's sends and receives); more are counted as lost.
constexpr std::size_t kMaxFramesPerEntry = 128U;

// What the recorder did. The producer's counts are exact at any time on the
// loop's thread; the writer's once finish() has returned.
struct RecorderCounts {
  std::uint64_t entries = 0U;           // queued (producer)
  std::uint64_t dropped = 0U;           // not queued: the queue was full (producer)
  std::uint64_t overlays_skipped = 0U;  // no free overlay slot, or the entry was dropped (producer)
  std::uint64_t can_frames_lost = 0U;   // beyond kMaxFramesPerEntry, or in a dropped entry (producer)
  std::uint64_t rows = 0U;              // cycles.csv rows written (writer)
  std::uint64_t can_lines = 0U;         // candump lines written (writer)
  std::uint64_t overlays = 0U;          // overlays written (writer)
  std::uint64_t overlays_removed = 0U;  // deleted to keep within the cap (writer)
  std::uint64_t rotations = 0U;         // files rotated (writer)
  std::uint64_t write_errors = 0U;      // failed writes, opens, renames, closes (writer)
};

class Recorder final : public loop::CycleObserver, public loop::FrameTap {
 public:
  // Creates DIR (one level) and DIR/overlays, opens the files, allocates the
  // queue and the slots and starts the writer thread. `models` draws the
  // overlays (it must outlive the recorder).
  static Result<std::unique_ptr<Recorder>, RecorderError> create(const RecorderOptions& options,
                                                                  const ModelSetup& models) noexcept;
  ~Recorder() override;
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  Recorder(Recorder&&) = delete;
  Recorder& operator=(Recorder&&) = delete;

  // Where the truth and the extraction of a cycle come from (optional).
  void set_truth_source(const hal::TruthSource* truth) noexcept { truth_ = truth; }
  void set_extraction(const vision::Extraction* extraction) noexcept { extraction_ = extraction; }
  // Called after the recorder's own work in on_cycle (the status line).
  void set_next(loop::CycleObserver* next) noexcept { next_ = next; }

  // The producer side (the loop's thread): no allocation, no blocking.
  void on_cycle(const loop::CycleRecord& record, const ImageView& frame) noexcept override;
  void on_frame(const can::Frame& frame, std::int64_t wall_us) noexcept override;

  // Queues what is left, lets the writer drain the queue, stops it and
  // closes the files. True when every write succeeded. Safe to call twice.
  bool finish() noexcept;

  const RecorderCounts& counts() const noexcept { return counts_; }
  // The producer's drops (queue full), for the status line.
  std::uint64_t dropped() const noexcept { return counts_.dropped; }
  // Failed writes so far (any thread).
  std::uint64_t write_errors() const noexcept { return write_errors_.load(std::memory_order_relaxed); }
  // The first failure's errno and file (valid after finish()).
  int first_errno() const noexcept { return first_errno_; }
  const char* first_error_path() const noexcept { return first_error_path_; }
  // The share of the cap of one file of cycles.csv / can.log, and the
  // overlays kept (0: no cap).
  std::uint64_t file_limit_bytes() const noexcept { return file_limit_bytes_; }
  std::uint64_t max_overlays() const noexcept { return max_overlays_; }

  // The summary line ("record DIR: ...") to `out`; with the first error on
  // stderr when a write failed.
  void print(std::FILE* out, const char* command) const noexcept;

  struct TappedFrame {
    can::Frame frame{};
    std::int64_t wall_us = 0;
  };
  struct Entry {
    bool has_row = false;  // false: only CAN frames (those after the last cycle)
    loop::CycleRecord cycle{};
    bool has_truth = false;
    hal::FrameTruth truth{};
    int overlay_slot = -1;  // index of the slot holding the frame, -1: none
    std::uint32_t frame_count = 0U;
    std::array<TappedFrame, kMaxFramesPerEntry> frames{};
  };
  struct OverlaySlot {
    std::atomic<bool> busy{false};  // set by the producer, cleared by the writer
    std::unique_ptr<std::uint8_t[]> pixels;
    bool has_extraction = false;
    vision::Extraction extraction{};
  };
  // One rotated stream (cycles.csv or can.log): the writer's.
  class RotatingFile {
   public:
    // dir/stem.ext, rotated to dir/stem.N.ext; `limit` 0: never rotated.
    bool open(const char* dir, const char* stem, const char* ext, std::uint64_t limit, std::uint32_t keep) noexcept;
    // Writes all of `data`, rotating first when it would pass the limit;
    // `header` (optional) starts every file. 0, or the errno of the failure.
    int write(const char* data, std::size_t size, const char* header, std::size_t header_size,
              std::uint64_t& rotations) noexcept;
    int close() noexcept;
    const char* path() const noexcept { return path_; }

   private:
    int rotate() noexcept;
    void name(std::uint32_t index, char* out, std::size_t capacity) const noexcept;
    char dir_[400] = {};
    char stem_[16] = {};
    char ext_[8] = {};
    char path_[448] = {};
    int fd_ = -1;
    std::uint64_t bytes_ = 0U;
    std::uint64_t limit_ = 0U;
    std::uint32_t keep_ = 1U;
  };

 private:
  explicit Recorder(const ModelSetup& models) noexcept : models_(models) {}
  RecorderError allocate() noexcept;
  RecorderError open_files() noexcept;
  static void* writer_main(void* self) noexcept;
  void writer_loop() noexcept;
  void write_entry(Entry& entry) noexcept;
  void write_overlay(const Entry& entry) noexcept;
  void note_error(int error_number, const char* path) noexcept;
  int claim_overlay_slot() noexcept;

  const ModelSetup& models_;
  RecorderOptions options_{};
  char dir_[400] = {};
  char overlay_dir_[416] = {};
  const hal::TruthSource* truth_ = nullptr;
  const vision::Extraction* extraction_ = nullptr;
  loop::CycleObserver* next_ = nullptr;

  SpscQueue<Entry> queue_;
  std::unique_ptr<OverlaySlot[]> slots_;
  std::uint32_t slot_count_ = 0U;
  std::array<TappedFrame, kMaxFramesPerEntry> staged_{};  // the frames since the last entry (producer)
  std::uint32_t staged_count_ = 0U;
  std::uint64_t staged_lost_ = 0U;
  RecorderCounts counts_{};

  // The writer's.
  pthread_t thread_{};
  bool thread_started_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> write_errors_{0U};
  int first_errno_ = 0;
  char first_error_path_[448] = {};
  RotatingFile csv_;
  RotatingFile can_log_;
  std::unique_ptr<char[]> csv_header_;
  std::size_t csv_header_size_ = 0U;
  std::unique_ptr<char[]> text_;  // the candump lines of one entry
  std::unique_ptr<std::uint8_t[]> canvas_;  // the overlay being drawn
  std::unique_ptr<std::uint32_t[]> kept_;   // frame numbers of the overlays on disk (a ring), when capped
  std::uint64_t kept_count_ = 0U;
  std::uint64_t kept_first_ = 0U;
  std::uint64_t file_limit_bytes_ = 0U;
  std::uint64_t max_overlays_ = 0U;
  std::int64_t t0_ns_ = -1;
  bool finished_ = false;
  bool failed_ = false;
};

// Bytes of one overlay PNG of this size (render::write_png_file's stored blocks).
std::uint64_t overlay_png_bytes(int width, int height) noexcept;

}  // namespace cli
}  // namespace tcpest
