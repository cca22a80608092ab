// Checks docs/tcpest.dbc against the encoders: every message is encoded with
// can_iface and decoded with a reading of the DBC written here from the DBC
// format alone (Intel byte order, two's complement, factor and offset), and
// the physical values must agree to the signal's resolution.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tcpest/can_iface/messages.hpp"

namespace tcpest {
namespace can {
namespace {

struct DbcSignal {
  std::string name;
  unsigned start = 0;
  unsigned length = 0;
  bool little_endian = true;
  bool is_signed = false;
  double factor = 1.0;
  double offset = 0.0;
  double minimum = 0.0;
  double maximum = 0.0;
};

struct DbcMessage {
  std::uint32_t id = 0;
  std::string name;
  unsigned dlc = 0;
  std::vector<DbcSignal> signals;
};

std::map<std::uint32_t, DbcMessage> read_dbc(const char* path) {
  std::map<std::uint32_t, DbcMessage> messages;
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::string line;
  DbcMessage* current = nullptr;
  while (std::getline(in, line)) {
    unsigned id = 0;
    unsigned dlc = 0;
    char name[64] = {};
    char sender[64] = {};
    if (std::sscanf(line.c_str(), "BO_ %u %63[^:]: %u %63s", &id, name, &dlc, sender) == 4) {
      DbcMessage& m = messages[id];
      m.id = id;
      m.name = name;
      m.dlc = dlc;
      current = &m;
      continue;
    }
    DbcSignal s;
    char order = 0;
    char sign = 0;
    if (std::sscanf(line.c_str(), " SG_ %63s : %u|%u@%c%c (%lf,%lf) [%lf|%lf]", name, &s.start, &s.length, &order,
                    &sign, &s.factor, &s.offset, &s.minimum, &s.maximum) == 9) {
      EXPECT_NE(current, nullptr) << line;
      s.name = name;
      s.little_endian = order == '1';
      s.is_signed = sign == '-';
      current->signals.push_back(s);
    } else if (line.rfind("BO_ ", 0) == 0 || line.rfind(" SG_ ", 0) == 0) {
      ADD_FAILURE() << "unreadable DBC line: " << line;
    }
  }
  return messages;
}

double decode_signal(const DbcSignal& s, const Frame& frame) {
  EXPECT_TRUE(s.little_endian) << s.name;  // the protocol is little-endian throughout
  std::uint64_t raw = 0;
  for (unsigned bit = 0; bit < s.length; ++bit) {
    const unsigned pos = s.start + bit;
    const std::uint64_t value = (frame.data[pos / 8] >> (pos % 8)) & 1U;
    raw |= value << bit;
  }
  double numeric = static_cast<double>(raw);
  if (s.is_signed && (raw >> (s.length - 1)) != 0U) {
    numeric -= std::ldexp(1.0, static_cast<int>(s.length));
  }
  return numeric * s.factor + s.offset;
}

class DbcTest : public ::testing::Test {
 public:
  static void SetUpTestSuite() { dbc = new std::map<std::uint32_t, DbcMessage>(read_dbc(TCPEST_DBC_PATH)); }
  static void TearDownTestSuite() {
    delete dbc;
    dbc = nullptr;
  }

  // Decodes `frame` with the DBC and compares every signal with `expected`.
  void expect_signals(const Frame& frame, const std::map<std::string, double>& expected) {
    const auto it = dbc->find(frame.id);
    ASSERT_NE(it, dbc->end()) << "no DBC message for 0x" << std::hex << frame.id;
    const DbcMessage& m = it->second;
    EXPECT_EQ(m.dlc, frame.length) << m.name;
    std::size_t covered_bits = 0;
    for (const DbcSignal& s : m.signals) {
      covered_bits += s.length;
      const auto want = expected.find(s.name);
      ASSERT_NE(want, expected.end()) << "test does not check " << s.name;
      const double got = decode_signal(s, frame);
      EXPECT_NEAR(got, want->second, s.factor / 2 + 1e-12) << s.name;
      EXPECT_GE(got, s.minimum - 1e-9) << s.name;
      EXPECT_LE(got, s.maximum + 1e-9) << s.name;
    }
    EXPECT_EQ(covered_bits, 8U * frame.length) << m.name << ": every payload bit belongs to one signal";
    EXPECT_EQ(m.signals.size(), expected.size()) << m.name;
    ++checked[frame.id];
  }

  static std::map<std::uint32_t, DbcMessage>* dbc;
  static std::map<std::uint32_t, int> checked;
};
std::map<std::uint32_t, DbcMessage>* DbcTest::dbc = nullptr;
std::map<std::uint32_t, int> DbcTest::checked;

constexpr std::uint8_t kNode = kDefaultNodeId;

void check_random_values(DbcTest& t, int rounds);
void check_small_messages(DbcTest& t);

// Verifies: REQ-CAN-013
TEST_F(DbcTest, EncodersAgreeWithTheDbcOnRandomValues) { check_random_values(*this, 200); }
// Verifies: REQ-CAN-013
TEST_F(DbcTest, SmallMessagesAgreeWithTheDbc) { check_small_messages(*this); }

void check_random_values(DbcTest& t, int rounds) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> mm(-327.0, 327.0);
  std::uniform_real_distribution<double> rad(-3.27, 3.27);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> u16(0, 65535);
  for (int round = 0; round < rounds; ++round) {
    const auto counter = static_cast<std::uint8_t>(round % 15);
    const auto status = static_cast<EstimateStatus>(round % 4);
    Frame frame;

    TcpMessage tcp{mm(rng), mm(rng), mm(rng), status, counter};
    ASSERT_TRUE(encode_tcp(kNode, tcp, frame).ok());
    t.expect_signals(frame, {{"TCP_X", tcp.x_mm}, {"TCP_Y", tcp.y_mm}, {"TCP_Z", tcp.z_mm},
                           {"TCP_Counter", counter}, {"TCP_Status", static_cast<double>(status)},
                           {"TCP_CRC", e2e_crc(frame.id, frame)}});

    JointsMessage joints{mm(rng), rad(rng), rad(rng), status, counter};
    ASSERT_TRUE(encode_joints(kNode, joints, frame).ok());
    t.expect_signals(frame, {{"JOINTS_Lambda", joints.lambda_mm}, {"JOINTS_Phi", joints.phi_rad},
                           {"JOINTS_Theta", joints.theta_rad}, {"JOINTS_Counter", counter},
                           {"JOINTS_Status", static_cast<double>(status)}, {"JOINTS_CRC", e2e_crc(frame.id, frame)}});

    ASSERT_TRUE(encode_encoder_prior(kNode, joints, frame).ok());
    t.expect_signals(frame, {{"PRIOR_Lambda", joints.lambda_mm}, {"PRIOR_Phi", joints.phi_rad},
                           {"PRIOR_Theta", joints.theta_rad}, {"PRIOR_Counter", counter},
                           {"PRIOR_Status", static_cast<double>(status)}, {"PRIOR_CRC", e2e_crc(frame.id, frame)}});

    MechanicalMessage mech{mm(rng), mm(rng), rad(rng), rad(rng)};
    ASSERT_TRUE(encode_mechanical(kNode, mech, frame).ok());
    t.expect_signals(frame, {{"MECH_XCh", mech.x_ch_mm}, {"MECH_YCh", mech.y_ch_mm}, {"MECH_Psi", mech.psi_rad},
                           {"MECH_Mu", mech.mu_rad}});

    QualityMessage quality;
    quality.corners_detected = static_cast<std::uint8_t>(byte(rng));
    quality.corners_used = static_cast<std::uint8_t>(byte(rng));
    quality.rms_px = u16(rng) * 0.01;
    quality.latency_us = u16(rng);
    quality.frame_counter = static_cast<std::uint16_t>(u16(rng));
    ASSERT_TRUE(encode_quality(kNode, quality, frame).ok());
    t.expect_signals(frame, {{"QUALITY_CornersDetected", quality.corners_detected},
                           {"QUALITY_CornersUsed", quality.corners_used},
                           {"QUALITY_RmsError", quality.rms_px},
                           {"QUALITY_Latency", static_cast<double>(quality.latency_us)},
                           {"QUALITY_FrameCounter", quality.frame_counter}});

    EmcyMessage emcy;
    emcy.error_code = static_cast<std::uint16_t>(u16(rng));
    emcy.error_register = static_cast<std::uint8_t>(byte(rng));
    emcy.fault_id = static_cast<std::uint8_t>(byte(rng));
    emcy.detail = static_cast<std::uint32_t>(rng());
    ASSERT_TRUE(encode_emcy(kNode, emcy, frame).ok());
    t.expect_signals(frame, {{"EMCY_ErrorCode", emcy.error_code},
                           {"EMCY_ErrorRegister", emcy.error_register},
                           {"EMCY_FaultId", emcy.fault_id},
                           {"EMCY_Detail", static_cast<double>(emcy.detail)}});
  }
}

void check_small_messages(DbcTest& t) {
  Frame frame;
  for (const NmtState state :
       {NmtState::kBootUp, NmtState::kStopped, NmtState::kOperational, NmtState::kPreOperational}) {
    ASSERT_TRUE(encode_heartbeat(kNode, state, frame).ok());
    t.expect_signals(frame, {{"HEARTBEAT_State", static_cast<double>(state)}});
  }
  for (const NmtCommand command : {NmtCommand::kStart, NmtCommand::kStop, NmtCommand::kEnterPreOperational,
                                   NmtCommand::kResetNode, NmtCommand::kResetCommunication}) {
    NmtMessage nmt{command, kNode};
    ASSERT_TRUE(encode_nmt(nmt, frame).ok());
    t.expect_signals(frame, {{"NMT_Command", static_cast<double>(command)}, {"NMT_NodeId", kNode}});
  }
  ASSERT_TRUE(encode_sync(frame).ok());
  t.expect_signals(frame, {});
}

// Verifies: REQ-CAN-013
TEST_F(DbcTest, SaturatedValuesDecodeToTheRangeLimits) {
  Frame frame;
  TcpMessage tcp{1e6, -1e6, 0.0, EstimateStatus::kValid, 0};
  ASSERT_TRUE(encode_tcp(kNode, tcp, frame).ok());
  expect_signals(frame, {{"TCP_X", 327.67}, {"TCP_Y", -327.68}, {"TCP_Z", 0.0}, {"TCP_Counter", 0},
                         {"TCP_Status", 3}, {"TCP_CRC", e2e_crc(frame.id, frame)}});
}

// Verifies: REQ-CAN-013
TEST_F(DbcTest, EveryDbcMessageIsEncodedAndChecked) {
  checked.clear();
  check_random_values(*this, 1);
  check_small_messages(*this);
  for (const auto& entry : *dbc) {
    EXPECT_GT(checked[entry.first], 0) << entry.second.name << " in the DBC but never encoded";
  }
  EXPECT_EQ(dbc->size(), 9U);  // TCP JOINTS MECHANICAL QUALITY HEARTBEAT EMCY NMT SYNC ENCODER_PRIOR
}

}  // namespace
}  // namespace can
}  // namespace tcpest
