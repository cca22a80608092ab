// The controllers' side of docs/can-protocol.md, as a reference: it takes
// the frames of one estimator node (TCP, JOINTS, MECHANICAL, QUALITY,
// heartbeat, EMCY) with their receive times, checks the E2E protection of
// TCP and JOINTS (CRC, counter window, age) with the same code the node uses
// for ENCODER_PRIOR, and answers what a motor controller asks: the latest
// values, whether the estimate is usable now, the node's NMT state, its last
// EMCY, and how many frames failed which check. Like can::Node it never
// touches the bus or the clock.
//
// Memory: everything inside the object (about 300 B on x86-64), no heap.
// Time: receive() and the queries are O(1).
#pragma once

#include <cstdint>

#include "tcpest/can_iface/e2e.hpp"
#include "tcpest/can_iface/error.hpp"
#include "tcpest/can_iface/frame.hpp"
#include "tcpest/can_iface/messages.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace can {

struct ReceiverConfig {
  std::uint8_t node_id = kDefaultNodeId;  // the estimator's node ID, 1..127
  // Counter window of TCP and JOINTS, and their age limit: no accepted TCP
  // for longer than e2e.timeout_us makes the estimate stale (invalid).
  E2eConfig e2e{};
};

Status<CanError> validate(const ReceiverConfig& config) noexcept;

// Which message a frame was.
enum class Message : std::uint8_t {
  kTcp,
  kJoints,
  kMechanical,
  kQuality,
  kHeartbeat,
  kEmcy,
};
const char* to_string(Message message) noexcept;

// The message a frame's COB-ID names for this node, or kUnknownId.
Result<Message, CanError> message_of(std::uint8_t node_id, std::uint32_t cob_id) noexcept;

// A value with the time it was received (the now_us of its receive()).
template <typename T>
struct Received {
  T value{};
  std::int64_t received_us = 0;
};

// Cumulative; never reset (not even by configure()'s restart of the streams).
struct ReceiverCounters {
  std::uint32_t frames = 0U;        // frames given to receive()
  std::uint32_t decoded = 0U;       // frames accepted as one of the node's messages
  std::uint32_t other_id = 0U;      // frames of identifiers this node does not send
  std::uint32_t malformed = 0U;     // MECHANICAL/QUALITY/heartbeat/EMCY of the wrong length or content
  std::uint32_t e2e_failures = 0U;  // TCP/JOINTS refused: CRC, length, counter 15, repeated counter
  std::uint32_t counter_jumps = 0U;  // TCP/JOINTS refused: counter backwards or beyond the window
  std::uint32_t stale_events = 0U;  // times the TCP stream went stale (no accepted TCP within e2e.timeout_us)
  std::uint32_t boot_ups = 0U;      // boot-up heartbeats (0x00): the node (re)started
  std::uint32_t emcy_raised = 0U;   // EMCY with a fault code
  std::uint32_t emcy_cleared = 0U;  // EMCY error resets (code 0x0000)
};

class Receiver {
 public:
  // Default configuration (node 0x10, E2E defaults).
  Receiver() noexcept = default;
  explicit Receiver(const ReceiverConfig& config) noexcept;

  // Validates and applies a configuration, and forgets every stream and
  // value (the counters stay).
  Status<CanError> configure(const ReceiverConfig& config) noexcept;

  // One frame received at now_us. Returns the message it was, or why it
  // was refused: kUnknownId (not this node's), kWrongLength, kBadCrc,
  // kBadCounter, kCounterRepeated, kCounterJump, kInvalidArgument (a
  // heartbeat byte that is no NMT state). Each refusal is counted.
  Result<Message, CanError> receive(const Frame& frame, std::int64_t now_us) noexcept;

  // Counts a stale event if the TCP stream went stale by now_us; receive()
  // does it too. Call it when polling without frames.
  void update(std::int64_t now_us) noexcept;

  // The estimate's status at now_us: the latest accepted TCP's status, or
  // kInvalid when there is none or it is older than e2e.timeout_us.
  EstimateStatus estimate_status(std::int64_t now_us) const noexcept;
  bool stale(std::int64_t now_us) const noexcept;

  // The latest accepted values (kNoData: none yet). Their age is the
  // caller's to judge (received_us); estimate_status() applies the rule.
  Result<Received<TcpMessage>, CanError> tcp() const noexcept;
  Result<Received<JointsMessage>, CanError> joints() const noexcept;
  Result<Received<MechanicalMessage>, CanError> mechanical() const noexcept;
  Result<Received<QualityMessage>, CanError> quality() const noexcept;
  // The NMT state of the latest heartbeat (kBootUp right after a boot-up).
  Result<Received<NmtState>, CanError> nmt_state() const noexcept;
  // The latest EMCY; its error_register is the node's current one.
  Result<Received<EmcyMessage>, CanError> last_emcy() const noexcept;

  const ReceiverCounters& counters() const noexcept { return counters_; }
  const E2eCounters& tcp_e2e() const noexcept { return tcp_rx_.counters(); }
  const E2eCounters& joints_e2e() const noexcept { return joints_rx_.counters(); }
  const ReceiverConfig& config() const noexcept { return config_; }

 private:
  Result<Message, CanError> refuse_e2e(E2eReceiver& stream, CanError error) noexcept;
  Result<Message, CanError> receive_e2e(Message message, const Frame& frame, std::int64_t now_us) noexcept;
  Result<Message, CanError> receive_plain(Message message, const Frame& frame, std::int64_t now_us) noexcept;

  ReceiverConfig config_{};
  ReceiverCounters counters_{};
  E2eReceiver tcp_rx_{};
  E2eReceiver joints_rx_{};
  std::uint32_t tcp_timeouts_seen_ = 0U;  // tcp_rx_'s timeouts already counted as stale events

  Received<TcpMessage> tcp_{};
  Received<JointsMessage> joints_{};
  Received<MechanicalMessage> mechanical_{};
  Received<QualityMessage> quality_{};
  Received<NmtState> nmt_{};
  Received<EmcyMessage> emcy_{};
  bool have_tcp_ = false;
  bool have_joints_ = false;
  bool have_mechanical_ = false;
  bool have_quality_ = false;
  bool have_nmt_ = false;
  bool have_emcy_ = false;
};

}  // namespace can
}  // namespace tcpest
