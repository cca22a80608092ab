#include "tcpest/loop/can_node_port.hpp"

#include <poll.h>

#include <cstdio>
#include <ctime>

#include "tcpest/hal/can/socketcan_bus.hpp"

namespace tcpest {
namespace loop {

namespace {

constexpr std::int64_t kSyncPollSliceNs = hal::kNsPerMs;  // the wait's step when the bus has no fd

std::int64_t to_us(std::int64_t ns) noexcept { return ns / hal::kNsPerUs; }

bool bus_gone(hal::CanBusError e) noexcept {
  return e == hal::CanBusError::kInterfaceDown || e == hal::CanBusError::kNoSuchInterface ||
         e == hal::CanBusError::kNotOpen || e == hal::CanBusError::kBusOff;
}

}  // namespace

can::NodeConfig node_config(const LoopConfig& config) noexcept {
  can::NodeConfig n;
  n.node_id = config.can.node_id;
  n.heartbeat_period_us = static_cast<std::int64_t>(config.can.heartbeat_ms) * 1000;
  n.sync_mode = config.loop.trigger == Trigger::kSync;
  n.start_operational = config.can.start_operational;
  n.prior_expected = false;
  n.prior_e2e.max_counter_step = static_cast<std::uint8_t>(config.can.prior_max_counter_gap);
  n.prior_e2e.timeout_us = static_cast<std::int64_t>(config.can.prior_timeout_ms) * 1000;
  return n;
}

CanNodePort::CanNodePort(hal::Clock& clock, hal::CanBus& bus, hal::SimBus* sim, hal::CandumpLogWriter* log,
                         const char* log_interface) noexcept
    : clock_(clock), bus_(bus), sim_(sim), log_(log) {
  static_cast<void>(std::snprintf(log_interface_, sizeof log_interface_, "%s",
                                  log_interface != nullptr ? log_interface : "sim0"));  // truncation is harmless
  timespec wall{};
  static_cast<void>(clock_gettime(CLOCK_REALTIME, &wall));  // cannot fail with a valid pointer
  wall_offset_ns_ = static_cast<std::int64_t>(wall.tv_sec) * hal::kNsPerS + static_cast<std::int64_t>(wall.tv_nsec) -
                    clock.now_ns();
}

Status<can::CanError> CanNodePort::configure(const can::NodeConfig& config) noexcept {
  return node_.configure(config);
}

void CanNodePort::set_bus_time(std::int64_t now_ns) noexcept {
  if (sim_ != nullptr) {
    sim_->set_time_us(to_us(now_ns));
  }
}

void CanNodePort::log(const can::Frame& frame, std::int64_t now_ns) noexcept {
  if (tap_ != nullptr) {
    tap_->on_frame(frame, to_us(now_ns + wall_offset_ns_));
  }
  if (log_ != nullptr) {
    // A full disk loses log lines, never a cycle: the writer counts its failures (write_errors()),
    // which the command reports at the end of the run.
    static_cast<void>(log_->write(frame, to_us(now_ns + wall_offset_ns_)));
  }
}

Status<PortError> CanNodePort::receive(std::int64_t now_ns) noexcept {
  set_bus_time(now_ns);
  const auto got = bus_.receive(rx_.data(), rx_.size());
  std::size_t n = 0U;
  Status<PortError> status = ok_status<PortError>();
  if (got.ok()) {
    n = got.value();
  } else if (bus_gone(got.error())) {
    status = Status<PortError>::failure(PortError::kBusDown);
  }
  for (std::size_t i = 0; i < n; ++i) {
    rx_frames_[i] = rx_[i].frame;
    log(rx_[i].frame, now_ns);
  }
  const can::NmtState before = node_.state();
  const can::RxSummary summary = node_.receive(rx_frames_.data(), n, to_us(now_ns));
  syncs_ += summary.syncs;
  if (summary.nmt_changed && node_.state() == can::NmtState::kBootUp && before != can::NmtState::kBootUp) {
    reset_ = true;
  }
  // Only a pending boot-up goes out here (the node leaves boot-up with it, and
  // ignores SYNC until then). Anything else that became due, the PDOs a SYNC
  // asked for in particular, goes out at this cycle's publish or housekeeping,
  // so that a SYNC's PDOs carry the estimate handed over at the publish step.
  if (node_.state() == can::NmtState::kBootUp) {
    const auto flushed = flush(now_ns);
    if (!flushed.ok() && status.ok()) {
      status = flushed;
    }
  }
  return status;
}

NodeMode CanNodePort::mode() const noexcept {
  switch (node_.state()) {
    case can::NmtState::kBootUp:
      return NodeMode::kBootUp;
    case can::NmtState::kPreOperational:
      return NodeMode::kPreOperational;
    case can::NmtState::kOperational:
      return NodeMode::kOperational;
    case can::NmtState::kStopped:
      return NodeMode::kStopped;
  }
  return NodeMode::kBootUp;
}

bool CanNodePort::take_reset() noexcept {
  const bool was = reset_;
  reset_ = false;
  return was;
}

Status<PortError> CanNodePort::wait_sync(std::int64_t deadline_ns) noexcept {
  // Bounded: every pass waits at least a slice or returns.
  for (;;) {
    std::int64_t now = clock_.now_ns();
    const auto received = receive(now);
    if (!received.ok() && received.error() == PortError::kBusDown) {
      return received;
    }
    if (syncs_ > 0U) {
      syncs_ = 0U;
      return ok_status<PortError>();
    }
    if (now >= deadline_ns) {
      return Status<PortError>::failure(PortError::kTimeout);
    }
    if (socket_ != nullptr && socket_->fd() >= 0) {
      pollfd pfd{socket_->fd(), POLLIN, 0};
      const std::int64_t remaining_ms = (deadline_ns - now + hal::kNsPerMs - 1) / hal::kNsPerMs;
      const int rc = ::poll(&pfd, 1U, static_cast<int>(remaining_ms > 1000 ? 1000 : remaining_ms));
      if (rc < 0) {
        return Status<PortError>::failure(PortError::kInterrupted);
      }
    } else {
      now = clock_.now_ns();
      const std::int64_t next = now + kSyncPollSliceNs < deadline_ns ? now + kSyncPollSliceNs : deadline_ns;
      const auto slept = clock_.sleep_until_ns(next);
      if (!slept.ok()) {
        return Status<PortError>::failure(PortError::kInterrupted);
      }
    }
  }
}

bool CanNodePort::encoder_prior(std::int64_t now_ns, JointPrior& out) noexcept {
  const auto prior = node_.encoder_prior(to_us(now_ns));
  if (!prior.ok()) {
    return false;
  }
  out.lambda_mm = prior.value().lambda_mm;
  out.phi_rad = prior.value().phi_rad;
  out.theta_rad = prior.value().theta_rad;
  return true;
}

Status<PortError> CanNodePort::publish(const Publication& p, std::int64_t& latency_ns) noexcept {
  if (node_.state() != can::NmtState::kOperational) {
    return Status<PortError>::failure(PortError::kNotAllowed);
  }
  const std::int64_t now = clock_.now_ns();
  latency_ns = now - p.frame_timestamp_ns;
  can::Estimate e;
  e.status = p.status;
  e.tcp_x_mm = p.tcp_mm[0];
  e.tcp_y_mm = p.tcp_mm[1];
  e.tcp_z_mm = p.tcp_mm[2];
  e.x_ch_mm = p.r[solver::kXch];
  e.y_ch_mm = p.r[solver::kYch];
  e.psi_rad = p.r[solver::kPsi];
  e.mu_rad = p.r[solver::kMu];
  e.lambda_mm = p.r[solver::kLambda];
  e.phi_rad = p.r[solver::kPhi];
  e.theta_rad = p.r[solver::kTheta];
  e.corners_detected = p.corners_detected;
  e.corners_used = p.corners_used;
  e.rms_px = p.rms_px;
  e.latency_us = latency_ns / hal::kNsPerUs;
  e.frame_counter = p.frame_counter;
  if (!node_.publish(e).ok()) {
    return Status<PortError>::failure(PortError::kNotAllowed);
  }
  return flush(now);
}

Status<PortError> CanNodePort::housekeeping(std::int64_t now_ns) noexcept {
  // Once per cycle (the loop's housekeeping step): kernel drops, error
  // passive and a bus-off recovery become faults 9-11, sent by this flush.
  // update() fails only for a fault outside the table, which it never names.
  static_cast<void>(monitor_.update(bus_, node_));
  return flush(now_ns);
}

Status<PortError> CanNodePort::flush(std::int64_t now_ns) noexcept {
  set_bus_time(now_ns);
  Status<PortError> status = ok_status<PortError>();
  // Two passes at most: what did not fit in the batch stays pending in the node.
  for (int pass = 0; pass < 2; ++pass) {
    batch_.clear();
    const auto collected = node_.collect(to_us(now_ns), batch_);
    for (const can::Frame& frame : batch_) {
      const auto sent = bus_.send(frame);
      if (sent.ok()) {
        ++frames_sent_;
        log(frame, now_ns);
      } else {
        ++send_errors_;
        if (status.ok()) {
          status = Status<PortError>::failure(bus_gone(sent.error()) ? PortError::kBusDown : PortError::kBusFull);
        }
      }
    }
    if (collected.ok()) {
      break;
    }
  }
  return status;
}

void CanNodePort::set_fault(Fault fault, bool active, std::uint32_t detail) noexcept {
  // Only kInvalidArgument can come back, for an id outside the table: the loop raises table entries only.
  static_cast<void>(node_.set_fault(fault, active, detail));
}

Status<PortError> CanNodePort::recover() noexcept {
  const auto received = receive(clock_.now_ns());  // SocketCAN reopens inside receive when the interface is back
  if (!received.ok() && received.error() == PortError::kBusDown) {
    return received;
  }
  // A controller still in bus-off cannot send either: calling the bus back
  // then would only lose it again at the next send.
  const hal::BusState state = bus_.state();
  return state == hal::BusState::kDown || state == hal::BusState::kBusOff
             ? Status<PortError>::failure(PortError::kBusDown)
             : ok_status<PortError>();
}

}  // namespace loop
}  // namespace tcpest
