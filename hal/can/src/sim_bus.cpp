#include "tcpest/hal/can/sim_bus.hpp"

namespace tcpest {
namespace hal {

SimBus::SimBus() noexcept {
  for (SimEndpoint& endpoint : endpoints_) {
    endpoint.bus_ = this;
  }
}

SimEndpoint& SimBus::endpoint(std::size_t index) noexcept {
  return endpoints_[index < kMaxEndpoints ? index : kMaxEndpoints - 1U];
}

void SimBus::set_bus_off(bool bus_off) noexcept {
  if (bus_off == faults_.bus_off) {
    return;
  }
  faults_.bus_off = bus_off;
  for (SimEndpoint& endpoint : endpoints_) {
    ++endpoint.stats_.error_frames;
    if (bus_off) {
      ++endpoint.stats_.bus_off;
    } else {
      ++endpoint.stats_.restarts;
    }
  }
}

void SimBus::transmit(const SimEndpoint& sender, const can::Frame& frame) noexcept {
  ++frames_on_wire_;
  if (faults_.drop_next > 0U) {
    --faults_.drop_next;
    ++fault_counters_.dropped;
    return;
  }
  if (faults_.drop_every > 0U && frames_on_wire_ % faults_.drop_every == 0U) {
    ++fault_counters_.dropped;
    return;
  }
  can::Frame delivered = frame;
  if (faults_.corrupt_next > 0U && faults_.corrupt_byte < can::kMaxDataLength) {
    --faults_.corrupt_next;
    ++fault_counters_.corrupted;
    delivered.data[faults_.corrupt_byte] =
        static_cast<std::uint8_t>(delivered.data[faults_.corrupt_byte] ^ faults_.corrupt_mask);
  }
  const std::int64_t due_us = now_us_ + (faults_.delay_us > 0 ? faults_.delay_us : 0);
  for (SimEndpoint& endpoint : endpoints_) {
    if (&endpoint != &sender) {
      endpoint.deliver(delivered, now_us_, due_us);
    }
  }
}

Status<CanBusError> SimEndpoint::set_rx_ids(const std::uint32_t* ids, std::size_t count) noexcept {
  if (count > kMaxRxIds || (ids == nullptr && count > 0U)) {
    return Status<CanBusError>::failure(CanBusError::kInvalidArgument);
  }
  rx_ids_.clear();
  for (std::size_t i = 0U; i < count; ++i) {
    if (ids[i] > can::kMaxStandardId || !rx_ids_.push_back(ids[i])) {
      return Status<CanBusError>::failure(CanBusError::kInvalidArgument);
    }
  }
  return ok_status<CanBusError>();
}

bool SimEndpoint::accepts(std::uint32_t id) const noexcept {
  if (rx_ids_.empty()) {
    return true;
  }
  for (const std::uint32_t wanted : rx_ids_) {
    if (wanted == id) {
      return true;
    }
  }
  return false;
}

void SimEndpoint::deliver(const can::Frame& frame, std::int64_t sent_us, std::int64_t due_us) noexcept {
  if (!accepts(frame.id)) {
    return;
  }
  if (size_ == kQueueCapacity) {
    ++stats_.rx_kernel_dropped;  // like a full socket receive queue
    return;
  }
  Pending& slot = queue_[(head_ + size_) % kQueueCapacity];
  slot.received.frame = frame;
  slot.received.timestamp_us = due_us > sent_us ? due_us : sent_us;
  slot.due_us = due_us;
  ++size_;
}

BusState SimEndpoint::state() const noexcept {
  return (bus_ != nullptr && bus_->faults_.bus_off) ? BusState::kBusOff : BusState::kUp;
}

Status<CanBusError> SimEndpoint::send(const can::Frame& frame) noexcept {
  if (frame.id > can::kMaxStandardId || frame.length > can::kMaxDataLength) {
    ++stats_.tx_dropped;
    return Status<CanBusError>::failure(CanBusError::kBadFrame);
  }
  if (bus_ == nullptr) {
    return Status<CanBusError>::failure(CanBusError::kNotOpen);
  }
  if (bus_->faults_.bus_off) {
    ++stats_.tx_dropped;
    return Status<CanBusError>::failure(CanBusError::kBusOff);
  }
  ++stats_.tx_frames;
  bus_->transmit(*this, frame);
  return ok_status<CanBusError>();
}

Result<std::size_t, CanBusError> SimEndpoint::receive(ReceivedFrame* out, std::size_t max_frames) noexcept {
  using R = Result<std::size_t, CanBusError>;
  if (bus_ == nullptr) {
    return R::failure(CanBusError::kNotOpen);
  }
  if (out == nullptr && max_frames > 0U) {
    return R::failure(CanBusError::kInvalidArgument);
  }
  std::size_t count = 0U;
  while (count < max_frames && size_ > 0U && queue_[head_].due_us <= bus_->now_us_) {
    out[count] = queue_[head_].received;
    head_ = (head_ + 1U) % kQueueCapacity;
    --size_;
    ++count;
    ++stats_.rx_frames;
  }
  return R::success(count);
}

}  // namespace hal
}  // namespace tcpest
