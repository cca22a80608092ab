// End-to-end protection state (AUTOSAR E2E profile 11 style): the sender's
// alive counter and the receiver's sequence and age check.
#pragma once

#include <cstdint>

#include "tcpest/can_iface/error.hpp"
#include "tcpest/can_iface/messages.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace can {

// 0, 1, ..., 14, 0, ...: one step per message of one COB-ID.
class AliveCounter {
 public:
  std::uint8_t current() const noexcept { return value_; }
  // Returns the counter for this message and steps to the next one.
  std::uint8_t take() noexcept {
    const std::uint8_t now = value_;
    value_ = value_ >= kMaxAliveCounter ? std::uint8_t{0U} : static_cast<std::uint8_t>(value_ + 1U);
    return now;
  }
  void reset() noexcept { value_ = 0U; }

 private:
  std::uint8_t value_ = 0U;
};

struct E2eConfig {
  // Largest accepted counter step: 1 accepts only consecutive messages,
  // N accepts N-1 lost ones in between. 1..14.
  std::uint8_t max_counter_step = 3U;
  // A message older than this (receive time) is stale. > 0.
  std::int64_t timeout_us = 100000;
};

Status<CanError> validate(const E2eConfig& config) noexcept;

struct E2eCounters {
  std::uint32_t accepted = 0U;
  std::uint32_t bad_crc = 0U;
  std::uint32_t bad_length = 0U;
  std::uint32_t bad_counter = 0U;  // counter 15
  std::uint32_t repeated = 0U;
  std::uint32_t jumped = 0U;
  std::uint32_t timeouts = 0U;  // each time the latest accepted message went stale
};

// Sequence check on the receiving side. The first message after a reset (or
// after the stream went stale, unless it repeats the last accepted counter:
// a frozen or replayed frame) is accepted without a sequence reference;
// after that a message is accepted when its counter moved forward by
// 1..max_counter_step (modulo 15). A repeated counter is ignored; a jump
// (backwards or too far) is ignored and becomes the new reference, so the
// stream is accepted again from its next message.
class E2eReceiver {
 public:
  explicit E2eReceiver(const E2eConfig& config = E2eConfig{}) noexcept : config_(config) {}

  // Checks one already CRC-checked counter received at now_us.
  Status<CanError> check_counter(std::uint8_t counter, std::int64_t now_us) noexcept;
  // Records a CRC/length/counter-15 failure found by the decoder.
  void count_decode_error(CanError error) noexcept;
  // Whether the last accepted message is still fresh at now_us (counts a
  // timeout once when it goes stale, and drops the sequence reference).
  Status<CanError> freshness(std::int64_t now_us) noexcept;

  void reset() noexcept;
  const E2eCounters& counters() const noexcept { return counters_; }
  const E2eConfig& config() const noexcept { return config_; }

 private:
  E2eConfig config_;
  E2eCounters counters_{};
  bool have_reference_ = false;
  bool have_accepted_ = false;
  std::uint8_t last_counter_ = 0U;
  std::int64_t last_accept_us_ = 0;
};

}  // namespace can
}  // namespace tcpest
