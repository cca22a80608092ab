#include "tcpest/loop/memory_node.hpp"

namespace tcpest {
namespace loop {

MemoryNode::MemoryNode(hal::Clock& clock, bool start_operational, std::int64_t heartbeat_ns,
                       std::int64_t prior_timeout_ns) noexcept
    : clock_(clock), start_operational_(start_operational), heartbeat_ns_(heartbeat_ns), prior_timeout_ns_(prior_timeout_ns) {}

Status<PortError> MemoryNode::receive(std::int64_t now_ns) noexcept {
  static_cast<void>(now_ns);
  if (!bus_up_) {
    return Status<PortError>::failure(PortError::kBusDown);
  }
  if (mode_ == NodeMode::kBootUp) {
    // CiA 301: boot-up, then pre-operational by itself (operational with start_operational).
    mode_ = start_operational_ ? NodeMode::kOperational : NodeMode::kPreOperational;
  }
  return ok_status<PortError>();
}

bool MemoryNode::take_reset() noexcept {
  const bool was = reset_pending_;
  reset_pending_ = false;
  return was;
}

void MemoryNode::inject_reset() noexcept {
  reset_pending_ = true;
  mode_ = NodeMode::kBootUp;
  have_prior_ = false;
  faults_ = 0U;  // as the CAN node's reset node: its faults are forgotten (can_iface Node::reset_application)
}

Status<PortError> MemoryNode::wait_sync(std::int64_t deadline_ns) noexcept {
  if (pending_syncs_ > 0) {
    --pending_syncs_;
    return ok_status<PortError>();
  }
  static_cast<void>(clock_.sleep_until_ns(deadline_ns));  // a stand-in: the timeout is the only outcome
  return Status<PortError>::failure(PortError::kTimeout);
}

void MemoryNode::inject_prior(const JointPrior& prior, std::int64_t received_ns) noexcept {
  prior_ = prior;
  prior_ns_ = received_ns;
  have_prior_ = true;
}

bool MemoryNode::encoder_prior(std::int64_t now_ns, JointPrior& out) noexcept {
  if (!have_prior_ || now_ns - prior_ns_ > prior_timeout_ns_) {
    return false;
  }
  out = prior_;
  return true;
}

Status<PortError> MemoryNode::publish(const Publication& publication, std::int64_t& latency_ns) noexcept {
  if (!bus_up_) {
    return Status<PortError>::failure(PortError::kBusDown);
  }
  if (mode_ != NodeMode::kOperational) {
    return Status<PortError>::failure(PortError::kNotAllowed);
  }
  if (tx_full_) {
    dropped_ += 4U;  // TCP, JOINTS, MECHANICAL, QUALITY
    return Status<PortError>::failure(PortError::kBusFull);
  }
  latency_ns = clock_.now_ns() - publication.frame_timestamp_ns;
  ring_[published_ % kRing] = publication;
  ++published_;
  return ok_status<PortError>();
}

const Publication& MemoryNode::publication(std::size_t age) const noexcept {
  const std::uint64_t index = (published_ + kRing - 1U - (age % kRing)) % kRing;
  return ring_[index];
}

Status<PortError> MemoryNode::housekeeping(std::int64_t now_ns) noexcept {
  if (!bus_up_) {
    return Status<PortError>::failure(PortError::kBusDown);
  }
  if (now_ns >= next_heartbeat_ns_) {
    if (tx_full_) {
      ++dropped_;
      next_heartbeat_ns_ = now_ns + heartbeat_ns_;
      return Status<PortError>::failure(PortError::kBusFull);
    }
    ++heartbeats_;
    next_heartbeat_ns_ = now_ns + heartbeat_ns_;
  }
  return ok_status<PortError>();
}

void MemoryNode::set_fault(Fault fault, bool active, std::uint32_t detail) noexcept {
  const auto id = static_cast<unsigned>(fault);
  const std::uint32_t bit = 1U << id;
  const bool was = (faults_ & bit) != 0U;
  if (was != active) {
    ++emcy_;
    faults_ = active ? (faults_ | bit) : (faults_ & ~bit);
    if (active) {
      fault_details_[id] = detail;
    }
  }
}

std::uint32_t MemoryNode::fault_detail(Fault fault) const noexcept {
  return fault_details_[static_cast<unsigned>(fault)];
}

bool MemoryNode::fault_active(Fault fault) const noexcept {
  return (faults_ & (1U << static_cast<unsigned>(fault))) != 0U;
}

Status<PortError> MemoryNode::recover() noexcept {
  return bus_up_ ? ok_status<PortError>() : Status<PortError>::failure(PortError::kBusDown);
}

}  // namespace loop
}  // namespace tcpest
