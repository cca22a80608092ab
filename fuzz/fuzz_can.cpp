// libFuzzer target: the CAN node's receive path, cycle by cycle, with a fake
// clock. The input is a node configuration (2 bytes) followed by 12-byte
// frame records; a record's flags choose the COB-ID (NMT, SYNC, this node's
// ENCODER_PRIOR, or any 11-bit ID), can turn its bytes into a well-formed
// ENCODER_PRIOR (valid CRC, so that the counter and timeout checks are
// reached too), and can end the cycle: receive() the frames gathered so far,
// read the prior, publish, report lost frames, collect. Lengths run 0..15 to
// cover frames longer than classic CAN's 8 bytes.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "tcpest/can_iface/messages.hpp"
#include "tcpest/can_iface/node.hpp"

namespace {

using namespace tcpest;

constexpr std::size_t kConfigBytes = 2U;
constexpr std::size_t kRecordBytes = 12U;
// More than one receive() handles: the over-budget drop path is reached.
constexpr std::size_t kBatch = can::kMaxRxPerCycle + 8U;

struct Clock {
  std::int64_t now_us = 1000000;
  void advance(std::uint8_t step) noexcept { now_us += static_cast<std::int64_t>(step) * 997; }
};

can::NodeConfig config_from(const std::uint8_t* bytes) {
  can::NodeConfig config;
  config.node_id = static_cast<std::uint8_t>(bytes[0] & 0x7FU);  // 0 is invalid: configure() refuses it
  config.sync_mode = (bytes[1] & 0x01U) != 0U;
  config.start_operational = (bytes[1] & 0x02U) != 0U;
  config.prior_expected = (bytes[1] & 0x04U) != 0U;
  config.heartbeat_period_us = (bytes[1] & 0x08U) != 0U ? 0 : 50000;
  config.prior_e2e.max_counter_step = static_cast<std::uint8_t>(1U + (bytes[1] >> 4U));  // 1..16: 15, 16 invalid
  return config;
}

can::Frame frame_from(const std::uint8_t* record, std::uint8_t node_id) {
  can::Frame frame;
  const std::uint8_t flags = record[0];
  switch (flags & 0x03U) {
    case 0U: frame.id = can::kNmtId; break;
    case 1U: frame.id = can::kSyncId; break;
    case 2U: frame.id = can::encoder_prior_id(node_id); break;
    default: frame.id = (static_cast<std::uint32_t>(record[1]) << 8U | record[2]) & can::kMaxStandardId; break;
  }
  frame.length = static_cast<std::uint8_t>(record[3] & 0x0FU);
  std::memcpy(frame.data.data(), record + 4, can::kMaxDataLength);
  if ((flags & 0x04U) != 0U) {
    can::EncoderPriorMessage prior;
    prior.lambda_mm = static_cast<double>(static_cast<std::int8_t>(record[4])) * 0.5;
    prior.phi_rad = static_cast<double>(static_cast<std::int8_t>(record[5])) * 0.01;
    prior.theta_rad = static_cast<double>(static_cast<std::int8_t>(record[6])) * 0.01;
    prior.status = static_cast<can::EstimateStatus>(record[7] & 0x03U);
    prior.counter = static_cast<std::uint8_t>(record[8] & 0x0FU);  // 15: out of range, refused
    static_cast<void>(can::encode_encoder_prior(node_id, prior, frame));  // a refusal leaves the raw frame
  }
  return frame;
}

// The estimates the loop may hand over, normal or not: the node saturates
// what does not fit and must never convert out of range.
double extreme(std::uint8_t selector) {
  constexpr double kValues[8] = {0.0, 12.5, -7.25, 1e300, -1e300, __builtin_inf(), -__builtin_inf(), __builtin_nan("")};
  return kValues[selector & 0x07U];
}

void end_cycle(can::Node& node, const can::Frame* frames, std::size_t count, const std::uint8_t* record,
               Clock& clock) {
  static_cast<void>(node.receive(frames, count, clock.now_us));  // the summary is not checked here
  static_cast<void>(node.encoder_prior(clock.now_us));
  can::Estimate estimate;
  estimate.status = static_cast<can::EstimateStatus>(record[9] & 0x03U);
  estimate.tcp_x_mm = extreme(record[10]);
  estimate.tcp_z_mm = extreme(static_cast<std::uint8_t>(record[10] >> 3U));
  estimate.theta_rad = extreme(static_cast<std::uint8_t>(record[11] >> 4U));
  estimate.psi_rad = extreme(record[9] >> 2U);
  estimate.rms_px = extreme(record[9] >> 5U);
  estimate.latency_us = static_cast<std::int64_t>(static_cast<std::int8_t>(record[11])) * 1000;
  estimate.corners_used = static_cast<std::uint8_t>(record[11] & 0x0FU);
  static_cast<void>(node.publish(estimate));
  if ((record[0] & 0x10U) != 0U) {
    static_cast<void>(node.report_rx_lost(record[11]));
  }
  can::TxBatch out;
  static_cast<void>(node.collect(clock.now_us, out));  // kFull keeps the rest pending
  clock.advance(record[1]);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < kConfigBytes) {
    return 0;
  }
  can::Node node;
  const can::NodeConfig config = config_from(data);
  if (!node.configure(config).ok()) {
    return 0;
  }
  Clock clock;
  can::Frame frames[kBatch];
  std::size_t count = 0U;
  for (std::size_t at = kConfigBytes; at + kRecordBytes <= size; at += kRecordBytes) {
    const std::uint8_t* record = data + at;
    if (count < kBatch) {
      frames[count++] = frame_from(record, config.node_id);
    }
    if ((record[0] & 0x08U) != 0U || count == kBatch) {
      end_cycle(node, frames, count, record, clock);
      count = 0U;
    }
  }
  return 0;
}
