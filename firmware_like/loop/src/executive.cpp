#include "tcpest/loop/executive.hpp"

#include <cmath>
#include <cstring>
#include <new>

namespace tcpest {
namespace loop {

namespace {

std::int64_t ms_to_ns(std::int64_t ms) noexcept { return ms * hal::kNsPerMs; }

bool is_device_failure(hal::CameraError e) noexcept {
  return e == hal::CameraError::kDeviceLost || e == hal::CameraError::kNotFound || e == hal::CameraError::kIo;
}

}  // namespace

const char* to_string(LoopError error) noexcept {
  switch (error) {
    case LoopError::kNone:
      return "ok";
    case LoopError::kBadConfig:
      return "inconsistent loop configuration";
    case LoopError::kOutOfMemory:
      return "out of memory at start-up";
  }
  return "?";
}

const char* to_string(NodeMode mode) noexcept {
  switch (mode) {
    case NodeMode::kBootUp:
      return "boot-up";
    case NodeMode::kPreOperational:
      return "pre-operational";
    case NodeMode::kOperational:
      return "operational";
    case NodeMode::kStopped:
      return "stopped";
  }
  return "?";
}

const char* to_string(PortError error) noexcept {
  switch (error) {
    case PortError::kNone:
      return "ok";
    case PortError::kBusDown:
      return "bus down";
    case PortError::kBusFull:
      return "transmit queue full";
    case PortError::kTimeout:
      return "timeout";
    case PortError::kInterrupted:
      return "interrupted";
    case PortError::kNotAllowed:
      return "not allowed in this NMT state";
  }
  return "?";
}

Executive::Executive(const LoopConfig& config, const LoopParts& parts) noexcept
    : config_(config), parts_(parts), timer_(*parts.clock, 0), track_(*parts.instrument, config.loop.track_drop_after) {}

Executive::~Executive() = default;

Result<std::unique_ptr<Executive>, LoopError> Executive::create(const LoopConfig& config,
                                                              const LoopParts& parts) noexcept {
  using R = Result<std::unique_ptr<Executive>, LoopError>;
  if (parts.source == nullptr || parts.clock == nullptr || parts.pipeline == nullptr || parts.node == nullptr ||
      parts.camera == nullptr || parts.instrument == nullptr) {
    return R::failure(LoopError::kBadConfig);
  }
  const int width = parts.source->width();
  const int height = parts.source->height();
  if (width <= 0 || height <= 0 || width != parts.camera->width() || height != parts.camera->height()) {
    return R::failure(LoopError::kBadConfig);
  }
  std::unique_ptr<Executive> loop(new (std::nothrow) Executive(config, parts));
  if (!loop) {
    return R::failure(LoopError::kOutOfMemory);
  }
  const std::size_t stride = static_cast<std::size_t>(width) * 3U;
  const std::size_t bytes = stride * static_cast<std::size_t>(height);
  loop->frame_buffer_.reset(new (std::nothrow) std::uint8_t[bytes]);
  loop->stats_.reset(new (std::nothrow) LoopStats());
  if (!loop->frame_buffer_ || !loop->stats_) {
    return R::failure(LoopError::kOutOfMemory);
  }
  std::memset(loop->frame_buffer_.get(), 0, bytes);  // pre-fault the pages before the first cycle
  loop->frame_view_ = MutableImageView{loop->frame_buffer_.get(), width, height, stride};

  // The trigger's time base.
  std::int64_t period_ns = 0;
  const LoopSettings& l = config.loop;
  switch (l.trigger) {
    case Trigger::kFrame:
      if (!parts.source->live() && l.pacing && parts.source->rate_hz() > 0.0) {
        period_ns = static_cast<std::int64_t>(std::llround(1e9 / parts.source->rate_hz()));
      }
      break;
    case Trigger::kPeriod:
      period_ns = l.period_us * hal::kNsPerUs;
      break;
    case Trigger::kSync:
      break;
  }
  if (l.trigger == Trigger::kPeriod && period_ns <= 0) {
    return R::failure(LoopError::kBadConfig);
  }
  loop->use_timer_ = period_ns > 0;
  loop->timer_.set_period_ns(period_ns);
  loop->publish_first_ = l.trigger != Trigger::kFrame;
  loop->cycle_budget_ns_ = cycle_budget_us() * hal::kNsPerUs;
  if (period_ns > 0 && period_ns < loop->cycle_budget_ns_) {
    loop->cycle_budget_ns_ = period_ns;
  }
  return R::success(std::move(loop));
}

void Executive::start() noexcept {
  const std::int64_t now = parts_.clock->now_ns();
  if (use_timer_) {
    timer_.start(now);
  }
  next_retry_ns_ = now;
  last_frame_ns_ = now;
}

std::uint32_t Executive::ms_without_frame(std::int64_t now_ns) const noexcept {
  const std::int64_t ms = (now_ns - last_frame_ns_) / hal::kNsPerMs;
  constexpr std::int64_t kMax = 0xFFFFFFFFLL;
  return static_cast<std::uint32_t>(ms < 0 ? 0 : (ms > kMax ? kMax : ms));
}

CycleOutcome Executive::wait_trigger() noexcept {
  if (finished_ || (config_.loop.frames != 0U && cycle_ >= config_.loop.frames)) {
    return CycleOutcome::kFinished;
  }
  hal::Clock& clock = *parts_.clock;
  record_.slipped = 0U;
  if (use_timer_) {
    const auto tick = timer_.wait_next();
    if (!tick.ok()) {
      return CycleOutcome::kInterrupted;  // the deadline is kept: the next call waits for it again
    }
    record_.trigger_ns = tick.value().deadline_ns;
    record_.slipped = tick.value().slipped;
    woke_ns_ = tick.value().woke_ns;
    return CycleOutcome::kContinue;
  }
  if (config_.loop.trigger == Trigger::kSync) {
    const std::int64_t deadline = clock.now_ns() + ms_to_ns(config_.can.sync_timeout_ms);
    const auto synced = parts_.node->wait_sync(deadline);
    if (!synced.ok() && synced.error() == PortError::kInterrupted) {
      return CycleOutcome::kInterrupted;
    }
    sync_missed_ = !synced.ok();
    // A timeout still runs the cycle (heartbeat, recovery); it publishes nothing.
    record_.trigger_ns = clock.now_ns();
    return CycleOutcome::kContinue;
  }
  if (camera_lost_) {
    // No frames to wait for: keep the heartbeat and the retries going at the configured period.
    const auto slept = clock.sleep_until_ns(clock.now_ns() + config_.loop.period_us * hal::kNsPerUs);
    if (!slept.ok()) {
      return CycleOutcome::kInterrupted;
    }
  }
  record_.trigger_ns = clock.now_ns();
  return CycleOutcome::kContinue;
}

CycleOutcome Executive::run_cycle() noexcept {
  const CycleOutcome outcome = wait_trigger();
  if (outcome != CycleOutcome::kContinue) {
    return outcome;
  }
  // A fresh record, keeping what wait_trigger() filled in.
  const std::int64_t trigger_ns = record_.trigger_ns;
  const std::uint32_t slipped = record_.slipped;
  record_ = CycleRecord{};
  record_.trigger_ns = trigger_ns;
  record_.slipped = slipped;
  record_.cycle = cycle_++;
  hal::Clock& clock = *parts_.clock;
  // On the timer the cycle starts at the wake-up, read once by the timer: no
  // clock read between the tick and the send that the send does not need
  // (under user-mode-linux each read is a syscall of tens of microseconds).
  const std::int64_t start = use_timer_ ? woke_ns_ : clock.now_ns();
  record_.start_ns = start;

  std::int64_t t = start;
  auto lap = [&](Step step) noexcept {
    const std::int64_t now = clock.now_ns();
    record_.step_ns[static_cast<std::size_t>(index_of(step))] += now - t;
    t = now;
  };

  if (publish_first_) {
    step_publish(trigger_ns);
    lap(Step::kPublish);
  }
  const bool have_frame = step_acquire();
  lap(Step::kAcquire);
  if (have_frame) {
    t = run_pipeline();  // times its own steps
  }
  make_publication();
  if (!publish_first_) {
    step_publish(trigger_ns);
    lap(Step::kPublish);
  }
  step_housekeeping();
  lap(Step::kHousekeeping);

  record_.end_ns = t;
  record_.total_ns = t - start;
  record_.mode = parts_.node->mode();
  record_.camera_lost = camera_lost_;
  record_.bus_lost = bus_lost_;
  record_.overrun = record_.total_ns > cycle_budget_ns_;

  LoopStats& s = *stats_;
  ++s.cycles;
  s.slips += record_.slipped;
  for (int i = 0; i < kNumSteps; ++i) {
    const std::int64_t ns = record_.step_ns[static_cast<std::size_t>(i)];
    s.step[static_cast<std::size_t>(i)].add(ns);
    if (ns > kSchedule[static_cast<std::size_t>(i)].budget_us * hal::kNsPerUs) {
      ++s.step_overruns[static_cast<std::size_t>(i)];
    }
  }
  s.total.add(record_.total_ns);
  if (record_.overrun) {
    ++s.cycle_overruns;
  }
  if (record_.overrun != overrun_reported_) {
    // One EMCY when a run of overruns starts, one (error reset) when it ends.
    parts_.node->set_fault(Fault::kCycleOverrun, record_.overrun,
                           static_cast<std::uint32_t>(record_.total_ns / hal::kNsPerUs));
    overrun_reported_ = record_.overrun;
    // Its EMCY goes out now, not at the next flush: with the period and SYNC
    // triggers that is the tick's, where it would be sent before the TCP
    // frame and delay it by one frame (measured on vcan: docs/loop.md).
    // It is outside the cycle's timing, which decided the overrun: one
    // frame, on a run's first and last cycle only.
    flush_node(clock.now_ns());
  }
  if (camera_cycle()) {
    ++s.status[static_cast<std::size_t>(record_.publication.status)];
  }

  if (observer_ != nullptr) {
    observer_->on_cycle(record_, frame_view_.view());
  }
  return CycleOutcome::kContinue;
}

CycleOutcome Executive::run(const std::atomic<bool>* stop) noexcept {
  start();
  for (;;) {  // bounded by the source's end, the frame limit or the stop flag
    if (stop != nullptr && stop->load(std::memory_order_relaxed)) {
      return CycleOutcome::kInterrupted;
    }
    const CycleOutcome outcome = run_cycle();
    if (outcome == CycleOutcome::kFinished) {
      return outcome;
    }
  }
}

void Executive::step_publish(std::int64_t trigger_ns) noexcept {
  NodePort& node = *parts_.node;
  if (node.mode() != NodeMode::kOperational || bus_lost_) {
    return;
  }
  Publication p{};
  if (publish_first_) {
    if (sync_missed_) {
      return;  // no SYNC: nothing to answer
    }
    if (!have_pending_) {
      // Nothing finished yet: an invalid estimate, so the robot sees the node is alive.
      p.status = EstimateStatus::kInvalid;
      p.frame_timestamp_ns = trigger_ns;
      p.frame_counter = frame_counter_;
    } else {
      p = last_publication_;
    }
  } else {
    if (!camera_cycle()) {
      return;  // nothing happened at the camera: nothing to say (e.g. the end of a replay)
    }
    p = record_.publication;
  }
  std::int64_t latency_ns = -1;
  const auto sent = node.publish(p, latency_ns);
  if (!sent.ok()) {
    ++stats_->publish_errors;
    if (sent.error() == PortError::kBusDown) {
      on_bus_lost();
    }
    return;
  }
  ++stats_->published;
  // The port read the send time once, for the latency (send - frame time
  // stamp): the send offset is taken from the same reading.
  const std::int64_t send_ns = p.frame_timestamp_ns + latency_ns;
  record_.latency_ns = latency_ns;
  record_.send_offset_ns = send_ns - trigger_ns;
  stats_->latency.add(latency_ns);
  stats_->send_offset.add(record_.send_offset_ns < 0 ? -record_.send_offset_ns : record_.send_offset_ns);
}

bool Executive::step_acquire() noexcept {
  NodePort& node = *parts_.node;
  hal::Clock& clock = *parts_.clock;
  const auto received = node.receive(clock.now_ns());
  if (!received.ok() && received.error() == PortError::kBusDown) {
    on_bus_lost();
  }
  if (node.take_reset()) {
    ++stats_->resets;
    parts_.pipeline->reset_appearance();  // a reset node forgets what it learned too
    if (track_.alive()) {
      on_track_dropped();
    }
    track_.reset();
    have_pending_ = false;
    // A reset node forgot its faults: say again those that still hold.
    if (camera_lost_) {
      node.set_fault(Fault::kCameraTimeout, true, ms_without_frame(clock.now_ns()));
    }
    if (bus_lost_) {
      node.set_fault(Fault::kCanTxDropped, true, take_new_drops());
    }
    overrun_reported_ = false;
    frame_error_reported_ = false;
    tracking_lost_reported_ = false;
  }
  if (node.mode() == NodeMode::kStopped || camera_lost_) {
    return false;
  }
  const auto got = parts_.source->acquire(frame_view_, info_);
  if (got.ok()) {
    not_ready_run_ = 0;
    dropped_run_ = 0;
    ++stats_->frames;
    last_frame_ns_ = clock.now_ns();
    record_.have_frame = true;
    record_.frame_sequence = info_.sequence;
    // Replay frames "arrive" at the trigger; a live camera's own time stamp travels with its frame.
    record_.frame_timestamp_ns = parts_.source->live() ? info_.timestamp_ns : record_.trigger_ns;
    if (frame_error_reported_) {
      node.set_fault(Fault::kImageCorrupt, false, 0U);
      frame_error_reported_ = false;
    }
    return true;
  }
  const hal::CameraError e = got.error();
  record_.frame_error = e;
  if (e == hal::CameraError::kEndOfStream) {
    finished_ = true;
  } else if (e == hal::CameraError::kNotReady) {
    ++stats_->not_ready;
    if (++not_ready_run_ >= config_.loop.camera_lost_after) {
      camera_lost_ = true;
    }
  } else if (is_device_failure(e) && parts_.source->live()) {
    camera_lost_ = true;
  } else {
    // A corrupt, truncated or wrongly sized frame: one dropped frame.
    ++stats_->frame_errors;
    if (++dropped_run_ >= config_.loop.camera_lost_after) {
      camera_lost_ = true;                 // only damaged frames: the camera is lost too
      finished_ = !parts_.source->live();  // a replay would replay its damage after reopen(): it ends here
    }
    if (track_.frame_failed()) {
      on_track_dropped();
    }
    if (!frame_error_reported_) {
      node.set_fault(Fault::kImageCorrupt, true, frame_counter_);  // the counter this cycle's QUALITY carries
      frame_error_reported_ = true;
    }
  }
  if (camera_lost_) {
    ++stats_->camera_lost_events;
    node.set_fault(Fault::kCameraTimeout, true, ms_without_frame(clock.now_ns()));
    next_retry_ns_ = clock.now_ns() + ms_to_ns(config_.loop.retry_ms);
  }
  return false;
}

void Executive::choose_prior(std::int64_t now_ns) noexcept {
  JointPrior joints{};
  const bool fresh = parts_.node->encoder_prior(now_ns, joints);
  const double encoder_joints[3] = {joints.lambda_mm, joints.phi_rad, joints.theta_rad};
  prior_ = track_.choose(fresh ? encoder_joints : nullptr);
  record_.prior = prior_.source;
  ++stats_->prior[static_cast<std::size_t>(record_.prior)];
}

namespace {
// Laps the estimator's steps into the cycle record on the loop's clock.
class StepLaps final : public vision::StepObserver {
 public:
  // `start_ns`: the clock's reading the first step is timed from.
  StepLaps(hal::Clock& clock, CycleRecord& record, std::int64_t start_ns) noexcept
      : clock_(clock), record_(record), t_(start_ns) {}
  void step_done(vision::EstimationStep step) noexcept override {
    const std::int64_t now = clock_.now_ns();
    record_.step_ns[static_cast<std::size_t>(index_of(step_of(step)))] += now - t_;
    t_ = now;
  }
  std::int64_t last_ns() const noexcept { return t_; }

 private:
  hal::Clock& clock_;
  CycleRecord& record_;
  std::int64_t t_;
};
}  // namespace

std::int64_t Executive::run_pipeline() noexcept {
  FeaturePipeline& pipeline = *parts_.pipeline;
  // One reading for the prior's freshness and the first step's lap (the
  // prior's choice is timed with classify, as before).
  const std::int64_t now_ns = parts_.clock->now_ns();
  choose_prior(now_ns);
  StepLaps laps(*parts_.clock, record_, now_ns);
  const vision::FrameEstimate e = pipeline.estimate(frame_view_.view(), prior_, laps);
  if (!e.extraction_ok) {
    record_.failed_stage = index_of(step_of(e.failed_step));
    record_.stage_error = static_cast<std::uint8_t>(e.stage_error);
  }
  // QUALITY's counts: corners measured in the image, and those the final solve used.
  record_.publication.corners_detected = static_cast<std::uint8_t>(vision::corners_measured(e));
  record_.refined = e.guided.rounds_kept > 0;
  record_.fit_disagrees = record_.refined && e.guided.disagreement_demoted;
  record_.encoder_disagrees = e.encoder_disagrees;
  record_.solve_status = e.estimate.summary.status;
  record_.quality = e.estimate.quality;
  record_.corners_rejected = e.estimate.corners_rejected;
  record_.publication.corners_used = static_cast<std::uint8_t>(vision::measured_corners_used(e));
  record_.publication.rms_px = e.estimate.summary.rms_px;
  record_.solved = e.solved();
  if (track_.update(e)) {
    on_track_dropped();
  }
  if (record_.solved && tracking_lost_reported_) {
    parts_.node->set_fault(Fault::kTrackingLost, false, 0U);
    tracking_lost_reported_ = false;
  }
  return laps.last_ns();
}

bool Executive::camera_cycle() const noexcept {
  return record_.have_frame || camera_lost_ ||
         (record_.frame_error != hal::CameraError::kNone && record_.frame_error != hal::CameraError::kEndOfStream);
}

void Executive::reset_sequence() noexcept {
  track_.reset();
  parts_.pipeline->drop_track();
  parts_.pipeline->reset_appearance();
}

void Executive::on_track_dropped() noexcept {
  ++stats_->track_drops;
  if (!tracking_lost_reported_) {
    parts_.node->set_fault(Fault::kTrackingLost, true, static_cast<std::uint32_t>(config_.loop.track_drop_after));
    tracking_lost_reported_ = true;
  }
  parts_.pipeline->drop_track();
}

void Executive::make_publication() noexcept {
  Publication& p = record_.publication;
  p.frame_timestamp_ns = record_.have_frame ? record_.frame_timestamp_ns : record_.trigger_ns;
  p.frame_counter = frame_counter_;
  if (record_.solved) {
    p.status = record_.quality == solver::EstimateQuality::Valid ? EstimateStatus::kValid : EstimateStatus::kDegraded;
  } else if (!camera_lost_ && track_.has_estimate() && track_.alive()) {
    p.status = EstimateStatus::kHeld;
  } else {
    p.status = EstimateStatus::kInvalid;
  }
  if (track_.has_estimate()) {
    p.r = track_.last_r();
    const solver::Vec3 tcp = parts_.instrument->tcp(track_.last_r());
    p.tcp_mm[0] = tcp.x();
    p.tcp_mm[1] = tcp.y();
    p.tcp_mm[2] = tcp.z();
  }
  if (camera_cycle()) {
    // One frame counter step per camera cycle (a dropped frame counts: the robot sees the gap).
    ++frame_counter_;
    last_publication_ = p;
    have_pending_ = true;
  }
}

void Executive::flush_node(std::int64_t now_ns) noexcept {
  const auto kept = parts_.node->housekeeping(now_ns);
  if (!kept.ok() && kept.error() == PortError::kBusDown) {
    on_bus_lost();
  }
}

void Executive::on_bus_lost() noexcept {
  if (bus_lost_) {
    return;
  }
  bus_lost_ = true;
  ++stats_->bus_lost_events;
  // Held until the bus is back: its EMCY gets out only if the bus still
  // carries some frames; after an outage the controllers see its reset.
  parts_.node->set_fault(Fault::kCanTxDropped, true, take_new_drops());
}

std::uint32_t Executive::take_new_drops() noexcept {
  const std::uint64_t dropped = parts_.node->frames_dropped();
  const std::uint64_t fresh = dropped >= drops_seen_ ? dropped - drops_seen_ : 0U;
  drops_seen_ = dropped;
  return fresh > 0xFFFFFFFFU ? 0xFFFFFFFFU : static_cast<std::uint32_t>(fresh);
}

void Executive::step_housekeeping() noexcept {
  NodePort& node = *parts_.node;
  hal::Clock& clock = *parts_.clock;
  const std::int64_t now = clock.now_ns();
  flush_node(now);
  if (!bus_lost_) {
    // Frames dropped on a full transmit queue: fault 12 for the cycles that
    // dropped some (detail: how many), reset by the next cycle that dropped none.
    const std::uint32_t dropped = take_new_drops();
    node.set_fault(Fault::kCanTxDropped, dropped > 0U, dropped);
  }
  if ((camera_lost_ || bus_lost_) && now >= next_retry_ns_) {
    next_retry_ns_ = now + ms_to_ns(config_.loop.retry_ms);
    if (camera_lost_ && parts_.source->reopen().ok()) {
      camera_lost_ = false;
      not_ready_run_ = 0;
      dropped_run_ = 0;
      ++stats_->camera_recoveries;
      node.set_fault(Fault::kCameraTimeout, false, 0U);
    }
    if (bus_lost_ && node.recover().ok()) {
      bus_lost_ = false;
      ++stats_->bus_recoveries;
      static_cast<void>(take_new_drops());  // the outage's drops were its EMCY's; the count starts again
      node.set_fault(Fault::kCanTxDropped, false, 0U);
    }
  }
}

}  // namespace loop
}  // namespace tcpest
