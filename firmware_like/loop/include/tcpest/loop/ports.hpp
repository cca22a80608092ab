// The loop's two seams besides the frame source and the clock (hal/): the
// feature-extraction stages and the CAN node. The executive calls them in
// the order of the schedule (schedule.hpp) and knows nothing else of them,
// so that it can be tested with stand-ins and replayed deterministically.
#pragma once

#include <cstdint>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/solver/pose_estimator.hpp"

namespace tcpest {
namespace loop {

// Where the start of a frame's interpretation and solve came from.
enum class PriorSource : std::uint8_t {
  kGeneric = 0,   // no track: the documented generic prior (nominal pose)
  kTemporal = 1,  // the last successful frames of the current track
  kEncoder = 2,   // a fresh, E2E-valid ENCODER_PRIOR from the robot
};
const char* to_string(PriorSource source) noexcept;

// A stage's failure: its unit's own error code (the pipeline names it).
struct StageError {
  std::uint8_t code = 0U;
};

// Vision stages 1-4 (tcpest_vision's FeatureExtractor, or a stand-in).
class FeaturePipeline {
 public:
  FeaturePipeline() noexcept = default;
  virtual ~FeaturePipeline() = default;
  FeaturePipeline(const FeaturePipeline&) = delete;
  FeaturePipeline& operator=(const FeaturePipeline&) = delete;
  FeaturePipeline(FeaturePipeline&&) = delete;
  FeaturePipeline& operator=(FeaturePipeline&&) = delete;

  virtual const char* name() const noexcept = 0;
  // Called before the stages with what the source knows (the oracle uses the truth).
  virtual void begin_frame(const hal::FrameInfo& info) noexcept { static_cast<void>(info); }
  virtual Status<StageError> classify(const ImageView& image) noexcept = 0;
  // prior_r: the configuration the prior comes from (encoder / last estimate / nominal).
  virtual Status<StageError> interpret(PriorSource source, const solver::PoseVector& prior_r) noexcept = 0;
  virtual Status<StageError> borders(const ImageView& image) noexcept = 0;
  virtual Status<StageError> corners(const ImageView& image, solver::CornerObservation& out) noexcept = 0;
  // After the first solve from corners() (which may have given no pose):
  // the model-guided rounds (vision's guided_rounds; `start` is the prior's
  // configuration, a fallback seed), which may replace `estimate`; false when
  // none was kept. A stand-in pipeline keeps the first estimate.
  virtual bool refine(const ImageView& image, solver::PoseEstimator& estimator, solver::SolveMode mode,
                      const solver::PoseVector& start, solver::Estimate& estimate) noexcept {
    static_cast<void>(image);
    static_cast<void>(estimator);
    static_cast<void>(mode);
    static_cast<void>(start);
    static_cast<void>(estimate);
    return false;
  }
  // After a refine() that returned true: it degraded a valid solve that its
  // image fit contradicts at the TCP (vision::GuidedOptions::
  // max_valid_tcp_disagreement_mm), for the cycle's record. A stand-in
  // pipeline never does.
  virtual bool refine_degraded_by_fit() const noexcept { return false; }
  // End of a frame: `success` feeds the temporal prior.
  virtual void end_frame(bool success) noexcept = 0;
  // The track is dropped: forget the temporal prior.
  virtual void drop_track() noexcept = 0;
  // The temporal prior has enough frames to be used.
  virtual bool has_temporal_prior() const noexcept = 0;
  virtual const char* describe(StageError error) const noexcept = 0;
};

// The CiA 301 state the node is in (the CAN unit's NMT state machine).
enum class NodeMode : std::uint8_t { kBootUp, kPreOperational, kOperational, kStopped };
const char* to_string(NodeMode mode) noexcept;

// Status nibble of TCP/JOINTS (can-protocol.md).
enum class EstimateStatus : std::uint8_t { kValid = 0U, kDegraded = 1U, kHeld = 2U, kInvalid = 3U };
const char* to_string(EstimateStatus status) noexcept;

// What one cycle publishes, in physical units (the node encodes it).
struct Publication {
  EstimateStatus status = EstimateStatus::kInvalid;
  double tcp_mm[3] = {0.0, 0.0, 0.0};
  solver::PoseVector r = solver::PoseVector::Zero();
  std::uint8_t corners_detected = 0U;
  std::uint8_t corners_used = 0U;
  double rms_px = 0.0;
  std::int64_t frame_timestamp_ns = 0;  // latency = send time - this (the node measures at send)
  std::uint16_t frame_counter = 0U;
};

struct JointPrior {
  double lambda_mm = 0.0;
  double phi_rad = 0.0;
  double theta_rad = 0.0;
};

// Faults the loop reports (EMCY; bytes 3-7 manufacturer-specific).
enum class Fault : std::uint8_t {
  kCameraLost = 1,    // no frames: device gone or silent
  kBusLost = 2,       // sends or receives fail
  kCycleOverrun = 3,  // a cycle ran past its period (reported once per run of overruns)
  kFrameErrors = 4,   // frames dropped as corrupt (reported once per run of errors)
  kTrackingLost = 5,  // the track was dropped after the configured failed frames (until re-acquired)
};
const char* to_string(Fault fault) noexcept;

enum class PortError : std::uint8_t {
  kNone = 0,
  kBusDown,      // the interface is down or gone (ENETDOWN, ENODEV)
  kBusFull,      // the transmit queue is full (ENOBUFS): frames dropped
  kTimeout,      // no SYNC within the deadline
  kInterrupted,  // a signal cut a wait short
  kNotAllowed,   // not in the NMT state that allows it
};
const char* to_string(PortError error) noexcept;

// The CAN node (can_iface's protocol over a hal/can bus, or a stand-in).
class NodePort {
 public:
  NodePort() noexcept = default;
  virtual ~NodePort() = default;
  NodePort(const NodePort&) = delete;
  NodePort& operator=(const NodePort&) = delete;
  NodePort(NodePort&&) = delete;
  NodePort& operator=(NodePort&&) = delete;

  // Reads what the bus has for us (NMT, SYNC, ENCODER_PRIOR), without waiting.
  virtual Status<PortError> receive(std::int64_t now_ns) noexcept = 0;
  virtual NodeMode mode() const noexcept = 0;
  // An NMT reset (node or communication) arrived since the last call.
  virtual bool take_reset() noexcept = 0;
  // Waits for the next SYNC (kSync trigger) until deadline_ns.
  virtual Status<PortError> wait_sync(std::int64_t deadline_ns) noexcept = 0;
  // The latest ENCODER_PRIOR if it passed its E2E checks and is fresh at now_ns.
  virtual bool encoder_prior(std::int64_t now_ns, JointPrior& out) noexcept = 0;
  // Sends TCP, JOINTS, MECHANICAL, QUALITY (only in operational). The
  // latency (send time - frame timestamp) is measured here, returned in
  // latency_ns, and put in QUALITY.
  virtual Status<PortError> publish(const Publication& publication, std::int64_t& latency_ns) noexcept = 0;
  // Heartbeat when due, EMCY for fault changes.
  virtual Status<PortError> housekeeping(std::int64_t now_ns) noexcept = 0;
  virtual void set_fault(Fault fault, bool active, std::uint32_t detail) noexcept = 0;
  // After kBusDown: reopen the interface. kBusDown while it is down, gone or
  // still in bus-off.
  virtual Status<PortError> recover() noexcept = 0;
};

}  // namespace loop
}  // namespace tcpest
