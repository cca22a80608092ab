// The loop's two seams besides the frame source and the clock (hal/): the
// feature-extraction stages and the CAN node. The executive calls them in
// the order of the schedule (schedule.hpp) and knows nothing else of them,
// so that it can be tested with stand-ins and replayed deterministically.
#pragma once

#include <cstdint>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/can_iface/emcy.hpp"
#include "tcpest/can_iface/messages.hpp"
#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/solver/pose_estimator.hpp"
#include "tcpest/vision/frame_estimator.hpp"

namespace tcpest {
namespace loop {

// Where a frame's prior came from: one definition, the estimator's.
using PriorSource = vision::PriorSource;

// The frame estimator (tcpest_vision's FrameEstimator, or a stand-in in the
// loop's tests): one frame and its prior in, one estimate out.
class FeaturePipeline {
 public:
  FeaturePipeline() noexcept = default;
  virtual ~FeaturePipeline() = default;
  FeaturePipeline(const FeaturePipeline&) = delete;
  FeaturePipeline& operator=(const FeaturePipeline&) = delete;
  FeaturePipeline(FeaturePipeline&&) = delete;
  FeaturePipeline& operator=(FeaturePipeline&&) = delete;

  virtual const char* name() const noexcept = 0;
  // The observer is told when each step ends (the loop times the steps).
  virtual vision::FrameEstimate estimate(const ImageView& image, const vision::FramePrior& prior,
                                         vision::StepObserver& observer) noexcept = 0;
  // The track is dropped: forget the temporal priors.
  virtual void drop_track() noexcept = 0;
  // Forget what was learned of the scene's appearance (a reset node, a new
  // sequence). A pipeline that learns nothing has nothing to forget.
  virtual void reset_appearance() noexcept {}
};

// The CiA 301 state the node is in (the CAN unit's NMT state machine).
enum class NodeMode : std::uint8_t { kBootUp, kPreOperational, kOperational, kStopped };
const char* to_string(NodeMode mode) noexcept;

// Status nibble of TCP/JOINTS (can-protocol.md): one definition, the protocol's.
using EstimateStatus = can::EstimateStatus;

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

// Faults the loop reports (EMCY): one definition, the protocol's
// (can_iface/emcy.hpp). The loop raises kCameraTimeout (no frames: device
// gone or silent), kCanTxDropped (frames dropped on send:
// in the cycles that dropped some, and while the bus is lost), kCycleOverrun
// (once per run of overruns), kImageCorrupt (frames dropped as corrupt, once
// per run) and kTrackingLost (the track was dropped, until re-acquired).
// The port raises the bus's own faults (9-11: receive overrun, error
// passive, bus-off recovered).
using Fault = can::Fault;

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
  // Frames the port could not send since it was made (dropped, never sent
  // late): the loop's fault 12 says how many each cycle dropped.
  virtual std::uint64_t frames_dropped() const noexcept = 0;
};

}  // namespace loop
}  // namespace tcpest
