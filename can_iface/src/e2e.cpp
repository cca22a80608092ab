#include "tcpest/can_iface/e2e.hpp"

namespace tcpest {
namespace can {

namespace {
constexpr std::uint8_t kCounterModulo = kMaxAliveCounter + 1U;
}

Status<CanError> validate(const E2eConfig& config) noexcept {
  if (config.max_counter_step < 1U || config.max_counter_step > kMaxAliveCounter || config.timeout_us <= 0) {
    return Status<CanError>::failure(CanError::kInvalidArgument);
  }
  return ok_status<CanError>();
}

Status<CanError> E2eReceiver::check_counter(std::uint8_t counter, std::int64_t now_us) noexcept {
  if (counter > kMaxAliveCounter) {
    ++counters_.bad_counter;
    return Status<CanError>::failure(CanError::kBadCounter);
  }
  // A stale stream loses its reference: the next message restarts it.
  static_cast<void>(freshness(now_us));  // only its side effect on the reference matters here
  // Without a reference the stream restarts with any counter but the one it
  // stopped at: a sender frozen on its last frame (or that frame replayed)
  // stays refused as a repeat.
  const bool stopped_at = have_accepted_ && counter == last_counter_;
  if (have_reference_ || stopped_at) {
    const auto step =
        static_cast<std::uint8_t>((counter + kCounterModulo - last_counter_) % kCounterModulo);
    if (step == 0U) {
      ++counters_.repeated;
      return Status<CanError>::failure(CanError::kCounterRepeated);
    }
    if (step > config_.max_counter_step) {
      ++counters_.jumped;
      last_counter_ = counter;
      return Status<CanError>::failure(CanError::kCounterJump);
    }
  }
  have_reference_ = true;
  have_accepted_ = true;
  last_counter_ = counter;
  last_accept_us_ = now_us;
  ++counters_.accepted;
  return ok_status<CanError>();
}

void E2eReceiver::count_decode_error(CanError error) noexcept {
  switch (error) {
    case CanError::kBadCrc: ++counters_.bad_crc; break;
    case CanError::kWrongLength: ++counters_.bad_length; break;
    case CanError::kBadCounter: ++counters_.bad_counter; break;
    default: break;
  }
}

Status<CanError> E2eReceiver::freshness(std::int64_t now_us) noexcept {
  if (!have_accepted_) {
    return Status<CanError>::failure(CanError::kNoData);
  }
  if (now_us - last_accept_us_ > config_.timeout_us) {
    if (have_reference_) {
      ++counters_.timeouts;
      have_reference_ = false;
    }
    return Status<CanError>::failure(CanError::kStale);
  }
  return ok_status<CanError>();
}

void E2eReceiver::reset() noexcept {
  have_reference_ = false;
  have_accepted_ = false;
  last_counter_ = 0U;
  last_accept_us_ = 0;
}

}  // namespace can
}  // namespace tcpest
