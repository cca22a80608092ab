// The can_iface unit's status values. Every fallible function of the unit
// returns one of these (inside a Result/Status), never throws.
#pragma once

#include <cstdint>

namespace tcpest {
namespace can {

// The numbers of kWrongLength..kCounterJump (3..7) are sent in EMCY details
// (docs/can-protocol.md): do not renumber.
enum class CanError : std::uint8_t {
  kInvalidArgument,   // a caller-supplied value outside its documented domain
  kWrongId,           // the frame's COB-ID is not the message asked for
  kUnknownId,         // the frame's COB-ID is not one the node consumes
  kWrongLength,       // the frame's length is not the message's length
  kBadCrc,            // the E2E CRC does not match
  kBadCounter,        // alive counter 15 (never sent)
  kCounterRepeated,   // same alive counter as the last accepted message
  kCounterJump,       // counter moved backwards or more than the allowed gap
  kInvalidStatus,     // the sender marked the value invalid (status 3)
  kStale,             // older than the configured timeout
  kNoData,            // nothing received yet
  kUnknownCommand,    // NMT command byte not in CiA 301
  kOtherNode,         // NMT addressed to another node
  kNotAllowed,        // not allowed in the current NMT state
  kFull,              // a fixed-capacity output is full
};

const char* to_string(CanError error) noexcept;

}  // namespace can
}  // namespace tcpest
