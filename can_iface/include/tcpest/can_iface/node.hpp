// The estimator as a CANopen-shaped node (docs/can-protocol.md): it takes the
// frames the bus delivered and the current time, keeps the NMT state, the
// latest valid ENCODER_PRIOR and the active faults, and produces the frames
// of the cycle (boot-up, EMCY, PDOs, heartbeat). It never touches the bus or
// the clock itself; see README.md for the per-cycle call sequence.
//
// Memory: everything inside the object (576 B on x86-64), no heap. Time: each
// call is bounded by kMaxRxPerCycle frames and kMaxTxPerCycle frames.
#pragma once

#include <cstddef>
#include <cstdint>

#include "tcpest/can_iface/e2e.hpp"
#include "tcpest/can_iface/emcy.hpp"
#include "tcpest/can_iface/error.hpp"
#include "tcpest/can_iface/frame.hpp"
#include "tcpest/can_iface/messages.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/common/static_vector.hpp"

namespace tcpest {
namespace can {

// Frames handled per receive() call; the rest are dropped and counted (a
// flood cannot make one cycle's receive path longer than this).
constexpr std::size_t kMaxRxPerCycle = 64U;
// Worst case of one collect(): boot-up, a raise and a reset EMCY per fault,
// four PDOs, a heartbeat.
constexpr std::size_t kMaxTxPerCycle = 1U + 2U * kFaultCount + 4U + 1U;
using TxBatch = StaticVector<Frame, kMaxTxPerCycle>;

struct NodeConfig {
  std::uint8_t node_id = kDefaultNodeId;       // 1..127
  std::int64_t heartbeat_period_us = 100000;   // 0: no heartbeat (boot-up still sent)
  bool sync_mode = false;                      // PDOs after each SYNC instead of after each publish()
  bool start_operational = false;              // go operational after boot-up without an NMT start
  bool prior_expected = false;                 // raise Fault::kPriorTimeout when ENCODER_PRIOR is missing
  E2eConfig prior_e2e{};                       // counter window and timeout of ENCODER_PRIOR
};

Status<CanError> validate(const NodeConfig& config) noexcept;

// One cycle's result, as the loop hands it over (physical units).
struct Estimate {
  EstimateStatus status = EstimateStatus::kInvalid;
  double tcp_x_mm = 0.0;
  double tcp_y_mm = 0.0;
  double tcp_z_mm = 0.0;
  double lambda_mm = 0.0;
  double phi_rad = 0.0;
  double theta_rad = 0.0;
  double x_ch_mm = 0.0;
  double y_ch_mm = 0.0;
  double psi_rad = 0.0;
  double mu_rad = 0.0;
  std::uint8_t corners_detected = 0U;
  std::uint8_t corners_used = 0U;
  double rms_px = 0.0;
  std::int64_t latency_us = 0;
  std::uint16_t frame_counter = 0U;
};

struct EncoderPrior {
  double lambda_mm = 0.0;
  double phi_rad = 0.0;
  double theta_rad = 0.0;
  EstimateStatus status = EstimateStatus::kInvalid;
  std::int64_t received_us = 0;  // the now_us of the receive() that accepted it
};

// What one receive() call saw.
struct RxSummary {
  std::uint32_t processed = 0U;  // frames looked at
  std::uint32_t ignored = 0U;    // frames rejected or not for this node
  std::uint32_t dropped = 0U;    // frames beyond kMaxRxPerCycle
  std::uint32_t syncs = 0U;      // SYNC frames accepted
  bool prior_updated = false;    // a new valid ENCODER_PRIOR was accepted
  bool nmt_changed = false;      // an NMT command was applied
};

// Cumulative diagnostics (never reset, not even by NMT reset commands).
struct NodeCounters {
  std::uint32_t rx_frames = 0U;
  std::uint32_t rx_dropped_over_budget = 0U;
  std::uint32_t rx_unknown_id = 0U;
  std::uint32_t rx_ignored_in_state = 0U;  // SYNC / ENCODER_PRIOR outside operational, anything during boot-up
  std::uint32_t nmt_applied = 0U;
  std::uint32_t nmt_wrong_length = 0U;
  std::uint32_t nmt_unknown_command = 0U;
  std::uint32_t nmt_other_node = 0U;
  std::uint32_t sync_received = 0U;
  std::uint32_t sync_wrong_length = 0U;
  std::uint32_t sync_coalesced = 0U;  // SYNCs that found PDOs already pending
  std::uint32_t prior_invalid_status = 0U;
  std::uint32_t prior_wrong_length = 0U;
  std::uint32_t pdo_cycles_sent = 0U;
  std::uint32_t pdo_saturated = 0U;     // PDO sets in which a value saturated
  std::uint32_t emcy_sent = 0U;
  std::uint32_t emcy_suppressed = 0U;   // fault edges while stopped
  std::uint32_t heartbeats_sent = 0U;
  std::uint32_t boot_ups_sent = 0U;
  std::uint32_t tx_batch_full = 0U;
};

// The faults the node raises and clears itself.
bool node_owned(Fault fault) noexcept;

class Node {
 public:
  // Default configuration, in initialisation (boot-up pending).
  Node() noexcept;

  // Validates and applies a configuration, then restarts as after power-on.
  Status<CanError> configure(const NodeConfig& config) noexcept;

  // Step 1 of a cycle: the frames read from the bus since the last call.
  // At most kMaxRxPerCycle are handled; NMT takes effect at once.
  RxSummary receive(const Frame* frames, std::size_t count, std::int64_t now_us) noexcept;

  // The latest accepted ENCODER_PRIOR if still fresh at now_us: kNoData
  // (none yet), kStale (older than prior_e2e.timeout_us).
  Result<EncoderPrior, CanError> encoder_prior(std::int64_t now_us) noexcept;

  // Step 2: the cycle's estimate. Status kHeld repeats the last estimate's
  // pose (kInvalid if there was none). In cyclic mode this schedules one PDO
  // set; in SYNC mode it becomes the set the next SYNC sends.
  Status<CanError> publish(const Estimate& estimate) noexcept;

  // Faults are edges: an EMCY goes out when a fault becomes active, an
  // error-reset EMCY when it clears. kInvalidArgument for an unknown fault,
  // kNotAllowed for the faults the node raises itself (kPriorTimeout,
  // kPriorE2eError, kCanRxOverrun).
  Status<CanError> set_fault(Fault fault, bool active, std::uint32_t detail) noexcept;
  bool fault_active(Fault fault) const noexcept;
  std::uint8_t error_register() const noexcept;

  // Frames lost before they reached receive() (e.g. the kernel's socket
  // queue overflowed): together with receive()'s own drops they raise
  // Fault::kCanRxOverrun at the next collect(), which clears it when a
  // cycle lost nothing.
  Status<CanError> report_rx_lost(std::uint32_t frames) noexcept;

  // Step 3: appends what is due at now_us, in this order: boot-up, EMCY,
  // PDOs (TCP, JOINTS, MECHANICAL, QUALITY), heartbeat. kFull if `out`
  // filled up (what did not fit stays pending for the next call).
  Status<CanError> collect(std::int64_t now_us, TxBatch& out) noexcept;

  NmtState state() const noexcept { return state_; }
  const NodeConfig& config() const noexcept { return config_; }
  const NodeCounters& counters() const noexcept { return counters_; }
  const E2eCounters& prior_counters() const noexcept { return prior_rx_.counters(); }

 private:
  Status<CanError> apply_fault(Fault fault, bool active, std::uint32_t detail) noexcept;
  void reset_communication() noexcept;
  void reset_application() noexcept;
  void handle_nmt(const Frame& frame, RxSummary& summary) noexcept;
  void handle_prior(const Frame& frame, std::int64_t now_us, RxSummary& summary) noexcept;
  bool push(TxBatch& out, const Frame& frame) noexcept;
  bool emit_emcy(TxBatch& out) noexcept;
  bool emit_emcy_edge(TxBatch& out, std::uint8_t id, bool raise) noexcept;
  bool emit_pdos(TxBatch& out) noexcept;
  void update_prior_timeout(std::int64_t now_us) noexcept;

  NodeConfig config_{};
  NodeCounters counters_{};
  NmtState state_ = NmtState::kBootUp;
  bool boot_pending_ = true;
  std::int64_t boot_us_ = 0;
  bool heartbeat_scheduled_ = false;
  std::int64_t next_heartbeat_us_ = 0;

  AliveCounter tcp_counter_{};
  AliveCounter joints_counter_{};
  E2eReceiver prior_rx_{};
  EncoderPrior prior_{};
  bool have_prior_ = false;

  Estimate latest_{};
  Estimate last_fresh_{};
  bool have_fresh_ = false;
  bool pdos_pending_ = false;
  std::uint32_t rx_lost_this_cycle_ = 0U;

  std::uint32_t active_faults_ = 0U;  // bit (id - 1)
  std::uint32_t pending_raise_ = 0U;
  std::uint32_t pending_clear_ = 0U;
  std::uint32_t fault_detail_[kFaultCount] = {};
};

}  // namespace can
}  // namespace tcpest
