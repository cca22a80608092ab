// The cyclic executive: one thread, one cycle per trigger, the steps of
// kSchedule in order, every step and every cycle timed against its budget.
//
//   trigger   frame: a live camera's next frame / the replay rate (or none with --no-pacing)
//             period: absolute deadlines on CLOCK_MONOTONIC
//             sync: the CAN SYNC message
//   cycle     acquire, classify, interpret, borders, corners, solve, publish, housekeeping
//
// With the period and SYNC triggers the cycle publishes first, at the tick,
// the estimate of the previous cycle (can-protocol.md: "from the latest
// finished cycle"): the send time then only has the timer's jitter. With the
// frame trigger it publishes as soon as the estimate exists (lowest latency).
//
// Everything is sized in create(); run_cycle() allocates nothing (tested with
// tests::AllocationScope over thousands of cycles).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/hal/clock/clock.hpp"
#include "tcpest/loop/config.hpp"
#include "tcpest/loop/histogram.hpp"
#include "tcpest/loop/ports.hpp"
#include "tcpest/loop/schedule.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/solver/pose_estimator.hpp"

namespace tcpest {
namespace loop {

enum class LoopError : std::uint8_t {
  kNone = 0,
  kBadConfig,     // an inconsistent setting (image size, period)
  kOutOfMemory,   // a start-up buffer could not be allocated
};
const char* to_string(LoopError error) noexcept;

// Everything one cycle did: the row of cycles.csv.
struct CycleRecord {
  std::uint64_t cycle = 0U;
  std::uint32_t frame_sequence = 0U;
  bool have_frame = false;
  hal::CameraError frame_error = hal::CameraError::kNone;
  std::int64_t frame_timestamp_ns = 0;
  std::int64_t trigger_ns = 0;      // the tick's deadline (period/paced), or the cycle start
  std::int64_t start_ns = 0;
  std::int64_t end_ns = 0;
  std::array<std::int64_t, kNumSteps> step_ns{};
  std::int64_t total_ns = 0;
  std::int64_t latency_ns = -1;     // frame timestamp -> CAN send; -1 when nothing was sent
  std::int64_t send_offset_ns = -1; // send time - trigger time (jitter of the sends); -1 when nothing was sent
  std::uint32_t slipped = 0U;       // periods skipped before this cycle
  bool overrun = false;
  NodeMode mode = NodeMode::kBootUp;
  PriorSource prior = PriorSource::kGeneric;
  int failed_stage = -1;            // index_of(Step) of the stage that failed, -1 if none
  std::uint8_t stage_error = 0U;
  solver::SolveStatus solve_status = solver::SolveStatus::InvalidInput;
  solver::EstimateQuality quality = solver::EstimateQuality::None;
  int corners_rejected = 0;         // dropped as disagreeing with the model at the estimate
  bool encoder_disagrees = false;   // demoted one level: beyond the encoders' accuracy (loop.encoder_check_*)
  bool solved = false;              // quality != None
  bool refined = false;             // the model-guided rounds gave the estimate
  bool fit_disagrees = false;       // ... and degraded it from valid: its TCP beside their image fit's (loop.max_valid_tcp_disagreement_mm)
  Publication publication{};        // what this cycle's estimate is (sent now or at the next tick)
  bool camera_lost = false;
  bool bus_lost = false;
};

struct LoopStats {
  std::array<DurationHistogram, kNumSteps> step{};
  DurationHistogram total;
  DurationHistogram latency;
  DurationHistogram send_offset;  // |send - trigger| (period and SYNC triggers: the send jitter)
  std::array<std::uint64_t, kNumSteps> step_overruns{};
  std::uint64_t cycles = 0U;
  std::uint64_t cycle_overruns = 0U;
  std::uint64_t slips = 0U;
  std::uint64_t frames = 0U;          // frames acquired and decoded
  std::uint64_t frame_errors = 0U;    // frames dropped (corrupt, truncated, wrong size)
  std::uint64_t not_ready = 0U;       // cycles without a frame from a live camera
  std::array<std::uint64_t, 4> status{};  // per EstimateStatus
  std::array<std::uint64_t, 3> prior{};   // per PriorSource
  std::uint64_t published = 0U;
  std::uint64_t publish_errors = 0U;
  std::uint64_t track_drops = 0U;
  std::uint64_t camera_lost_events = 0U;
  std::uint64_t camera_recoveries = 0U;
  std::uint64_t bus_lost_events = 0U;
  std::uint64_t bus_recoveries = 0U;
  std::uint64_t resets = 0U;
};

class CycleObserver {
 public:
  CycleObserver() noexcept = default;
  virtual ~CycleObserver() = default;
  CycleObserver(const CycleObserver&) = delete;
  CycleObserver& operator=(const CycleObserver&) = delete;
  CycleObserver(CycleObserver&&) = delete;
  CycleObserver& operator=(CycleObserver&&) = delete;
  // After each cycle, outside its timing. `frame` is this cycle's image.
  virtual void on_cycle(const CycleRecord& record, const ImageView& frame) noexcept = 0;
};

struct LoopParts {
  hal::FrameSource* source = nullptr;
  hal::Clock* clock = nullptr;
  FeaturePipeline* pipeline = nullptr;
  NodePort* node = nullptr;
  const solver::CameraModel* camera = nullptr;
  const solver::InstrumentModel* instrument = nullptr;
};

enum class CycleOutcome : std::uint8_t {
  kContinue,     // a cycle ran
  kFinished,     // the replay ended or the configured number of frames was reached
  kInterrupted,  // a signal cut the trigger wait short (the caller checks its stop flag)
};

class Executive {
 public:
  static Result<std::unique_ptr<Executive>, LoopError> create(const LoopConfig& config, const LoopParts& parts) noexcept;
  ~Executive();
  Executive(const Executive&) = delete;
  Executive& operator=(const Executive&) = delete;
  Executive(Executive&&) = delete;
  Executive& operator=(Executive&&) = delete;

  void set_observer(CycleObserver* observer) noexcept { observer_ = observer; }
  // Starts the trigger's time base (called by run(), or before the first run_cycle()).
  void start() noexcept;
  CycleOutcome run_cycle() noexcept;
  // Cycles until finished or *stop becomes true (checked every cycle and
  // after every interrupted wait). Returns kFinished or kInterrupted.
  CycleOutcome run(const std::atomic<bool>* stop) noexcept;
  // The source starts a new sequence (the next pass over a replayed dataset):
  // the next frame starts from the generic prior, as the first one did. The
  // track and the temporal priors are forgotten, as the offline commands'
  // EstimatePipeline::reset_sequence() does, and what was learned of the
  // scene's appearance, as their reset_appearance() does; not a lost track
  // (nothing counted, no EMCY). Between cycles; allocates nothing.
  void reset_sequence() noexcept;

  const LoopStats& stats() const noexcept { return *stats_; }
  const CycleRecord& last() const noexcept { return record_; }
  ImageView frame() const noexcept { return frame_view_.view(); }
  const LoopConfig& config() const noexcept { return config_; }
  // The cycle budget against which overruns are counted (ns).
  std::int64_t cycle_budget_ns() const noexcept { return cycle_budget_ns_; }
  bool publishes_first() const noexcept { return publish_first_; }

 private:
  Executive(const LoopConfig& config, const LoopParts& parts) noexcept;
  CycleOutcome wait_trigger() noexcept;
  void step_publish(std::int64_t trigger_ns) noexcept;
  bool step_acquire() noexcept;
  // The frame's estimate (its steps timed into the record); returns the
  // clock's reading at its end.
  std::int64_t run_pipeline() noexcept;
  void step_housekeeping() noexcept;
  // Heartbeat and EMCY out now (the node's housekeeping).
  void flush_node(std::int64_t now_ns) noexcept;
  // The node's sends or receives found the bus down or gone: bus lost.
  void on_bus_lost() noexcept;
  // Frames the node dropped since the last call (fault 12's detail).
  std::uint32_t take_new_drops() noexcept;
  void choose_prior(std::int64_t now_ns) noexcept;
  void make_publication() noexcept;
  void on_track_dropped() noexcept;
  // Milliseconds since the last frame acquired, saturated (camera-timeout EMCY detail).
  std::uint32_t ms_without_frame(std::int64_t now_ns) const noexcept;
  bool camera_cycle() const noexcept;

  LoopConfig config_;
  LoopParts parts_;
  hal::PeriodicTimer timer_;
  bool use_timer_ = false;
  std::int64_t woke_ns_ = 0;  // the timer's wake-up of this cycle (the cycle's start)
  bool publish_first_ = false;
  std::int64_t cycle_budget_ns_ = 0;
  std::unique_ptr<std::uint8_t[]> frame_buffer_;
  MutableImageView frame_view_{};
  std::unique_ptr<LoopStats> stats_;
  CycleObserver* observer_ = nullptr;
  CycleRecord record_{};
  hal::FrameInfo info_{};
  std::uint64_t cycle_ = 0U;
  bool finished_ = false;
  bool sync_missed_ = false;  // the SYNC trigger's wait timed out

  // The track: which prior each frame gets, what a held frame repeats.
  vision::Track track_;
  vision::FramePrior prior_{};
  Publication last_publication_{};
  bool have_pending_ = false;    // publish-first: an estimate waits for the next tick
  std::uint16_t frame_counter_ = 0U;

  // Health.
  bool camera_lost_ = false;
  int not_ready_run_ = 0;
  int dropped_run_ = 0;  // consecutive dropped (corrupt, truncated, wrongly sized) frames
  bool bus_lost_ = false;
  std::uint64_t drops_seen_ = 0U;  // the node's frames_dropped() at the last take_new_drops()
  std::int64_t next_retry_ns_ = 0;
  std::int64_t last_frame_ns_ = 0;  // clock time of the last frame acquired (or of start()): camera-timeout EMCY detail
  bool overrun_reported_ = false;
  bool frame_error_reported_ = false;
  bool tracking_lost_reported_ = false;
};

}  // namespace loop
}  // namespace tcpest
