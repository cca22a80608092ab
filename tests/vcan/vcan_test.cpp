// SocketCAN against the kernel's real vcan driver, checked with can-utils
// (candump, cansend, canplayer), which are not our code. Needs a vcan
// interface (TCPEST_VCAN_IFACE, default vcan0) and root for `ip`/`tc`:
// run it through tests/vcan/run-vcan.sh (ctest -L vcan), which provides
// both, in a user-mode-linux guest when the host has no CAN.
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <net/if.h>
#include <poll.h>
#include <spawn.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "tcpest/can_iface/messages.hpp"
#include "tcpest/can_iface/node.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/hal/can/socketcan_bus.hpp"

extern char** environ;

namespace tcpest {
namespace {

using can::Frame;
using hal::ReceivedFrame;
using hal::SocketCanBus;
using hal::SocketCanConfig;

constexpr std::uint8_t kNode = can::kDefaultNodeId;

const char* iface() {
  const char* name = std::getenv("TCPEST_VCAN_IFACE");
  return name != nullptr && name[0] != '\0' ? name : "vcan0";
}

std::int64_t monotonic_us() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1000000 + t.tv_nsec / 1000;
}

void sleep_ms(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

std::string temp_path(const char* stem) {
  const char* dir = std::getenv("TCPEST_VCAN_WORKDIR");
  std::string path = dir != nullptr ? dir : "/tmp";
  path += "/";
  path += stem;
  path += "-";
  path += std::to_string(getpid());
  return path;
}

// Runs a program (PATH lookup), optionally with stdout to a file; returns
// its pid, or -1.
pid_t spawn(const std::vector<std::string>& args, const std::string& stdout_path = "") {
  std::vector<char*> argv;
  for (const std::string& a : args) {
    argv.push_back(const_cast<char*>(a.c_str()));
  }
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!stdout_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
  }
  pid_t pid = -1;
  if (posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ) != 0) {
    pid = -1;
  }
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

// Waits for a child at most timeout_ms; kills it after that. Exit code, or -1.
int wait_child(pid_t pid, int timeout_ms) {
  const std::int64_t deadline = monotonic_us() + timeout_ms * 1000LL;
  int status = 0;
  while (true) {
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) {
      return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    if (done < 0 || monotonic_us() > deadline) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    sleep_ms(5);
  }
}

int run(const std::vector<std::string>& args, int timeout_ms = 10000) {
  const pid_t pid = spawn(args);
  if (pid < 0) {
    return -1;
  }
  return wait_child(pid, timeout_ms);
}

// Receivers on the interface in the kernel's catch-all list. The "(vcan0: no
// entry)" line must not count.
int rx_all_entries() {
  std::ifstream in("/proc/net/can/rcvlist_all");
  std::string line;
  int count = 0;
  while (std::getline(in, line)) {
    const auto start = line.find_first_not_of(' ');
    if (start != std::string::npos && line.compare(start, std::strlen(iface()), iface()) == 0) {
      ++count;
    }
  }
  return count;
}

// candump running in the background, writing its log format to a file.
class Candump {
 public:
  explicit Candump(int expected_frames) : path_(temp_path("candump") + ".log") {
    const int before = rx_all_entries();
    pid_ = spawn({"candump", "-L", "-n", std::to_string(expected_frames), iface()}, path_);
    const std::int64_t deadline = monotonic_us() + 5000000;
    while (pid_ > 0 && rx_all_entries() <= before && monotonic_us() < deadline) {
      sleep_ms(5);
    }
    bound_ = pid_ > 0 && rx_all_entries() > before;
  }
  ~Candump() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
    std::remove(path_.c_str());
  }
  bool bound() const { return bound_; }
  // Waits for candump to exit (it does after -n frames); its lines.
  std::vector<std::string> finish(int timeout_ms) {
    if (pid_ > 0) {
      const int status = wait_child(pid_, timeout_ms);
      pid_ = -1;
      EXPECT_EQ(status, 0) << "candump did not receive every frame in time";
    }
    std::vector<std::string> lines;
    std::ifstream in(path_);
    std::string line;
    while (std::getline(in, line)) {
      lines.push_back(line);
    }
    return lines;
  }

 private:
  std::string path_;
  pid_t pid_ = -1;
  bool bound_ = false;
};

// "(1700000000.123456) vcan0 190#0011..." -> frame. Parsed here from the
// format alone, not with our writer's code.
bool parse_candump_line(const std::string& line, Frame& frame) {
  const auto hash = line.find('#');
  const auto space = line.rfind(' ', hash);
  if (hash == std::string::npos || space == std::string::npos) {
    return false;
  }
  frame = Frame{};
  frame.id = static_cast<std::uint32_t>(std::stoul(line.substr(space + 1, hash - space - 1), nullptr, 16));
  const std::string hex = line.substr(hash + 1);
  if (hex.size() % 2 != 0 || hex.size() > 16) {
    return false;
  }
  frame.length = static_cast<std::uint8_t>(hex.size() / 2);
  for (std::size_t i = 0; i < frame.length; ++i) {
    frame.data[i] = static_cast<std::uint8_t>(std::stoul(hex.substr(2 * i, 2), nullptr, 16));
  }
  return true;
}

std::string cansend_arg(const Frame& frame) {
  char buffer[32];
  int n = std::snprintf(buffer, sizeof buffer, "%03X#", frame.id);
  for (std::uint8_t i = 0; i < frame.length; ++i) {
    n += std::snprintf(buffer + n, sizeof buffer - static_cast<std::size_t>(n), "%02X", frame.data[i]);
  }
  return buffer;
}

SocketCanConfig node_rx_config() {
  SocketCanConfig config;
  EXPECT_TRUE(config.rx_ids.push_back(can::kNmtId));
  EXPECT_TRUE(config.rx_ids.push_back(can::kSyncId));
  EXPECT_TRUE(config.rx_ids.push_back(can::encoder_prior_id(kNode)));
  return config;
}

can::Estimate sample_estimate(int i) {
  can::Estimate e;
  e.status = can::EstimateStatus::kValid;
  e.tcp_x_mm = 1.25 + i;
  e.tcp_y_mm = -2.5;
  e.tcp_z_mm = 45.67;
  e.lambda_mm = 20.0;
  e.phi_rad = 0.3;
  e.theta_rad = -0.8;
  e.x_ch_mm = -13.3;
  e.y_ch_mm = 6.2;
  e.psi_rad = 0.1745;
  e.mu_rad = 0.0123;
  e.corners_detected = 12;
  e.corners_used = 10;
  e.rms_px = 0.42;
  e.latency_us = 8123;
  e.frame_counter = static_cast<std::uint16_t>(1000 + i);
  return e;
}

class Vcan : public ::testing::Test {
 protected:
  void SetUp() override {
    const int probe = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (probe < 0) {
      GTEST_SKIP() << "no kernel CAN here: run through tests/vcan/run-vcan.sh";
    }
    close(probe);
    if (if_nametoindex(iface()) == 0) {
      GTEST_SKIP() << iface() << " does not exist: run through tests/vcan/run-vcan.sh";
    }
    // A previous test may have left it down.
    ASSERT_EQ(run({"ip", "link", "set", iface(), "up"}), 0);
  }
};

// Node side of a cycle: read, handle, produce, send. Returns what was sent.
std::vector<Frame> pump(SocketCanBus& bus, can::Node& node, std::int64_t now_us) {
  ReceivedFrame rx[can::kMaxRxPerCycle];
  Frame frames[can::kMaxRxPerCycle];
  const auto got = bus.receive(rx, can::kMaxRxPerCycle);
  std::size_t n = got.ok() ? got.value() : 0U;
  for (std::size_t i = 0; i < n; ++i) {
    frames[i] = rx[i].frame;
  }
  static_cast<void>(node.receive(frames, n, now_us));
  can::TxBatch batch;
  EXPECT_TRUE(node.collect(now_us, batch).ok());
  std::vector<Frame> sent;
  for (const Frame& f : batch) {
    EXPECT_TRUE(bus.send(f).ok());
    sent.push_back(f);
  }
  return sent;
}

template <typename Predicate>
bool pump_until(SocketCanBus& bus, can::Node& node, Predicate done, int timeout_ms,
                std::vector<Frame>* sent = nullptr) {
  const std::int64_t deadline = monotonic_us() + timeout_ms * 1000LL;
  while (monotonic_us() < deadline) {
    const auto out = pump(bus, node, monotonic_us());
    if (sent != nullptr) {
      sent->insert(sent->end(), out.begin(), out.end());
    }
    if (done()) {
      return true;
    }
    sleep_ms(2);
  }
  return false;
}

// Verifies: REQ-CAN-014
TEST_F(Vcan, EveryMessageTypeReachesCandumpIntact) {
  SocketCanBus bus;
  ASSERT_TRUE(bus.open(iface(), node_rx_config()).ok());
  can::NodeConfig config;
  config.start_operational = true;
  can::Node node;
  ASSERT_TRUE(node.configure(config).ok());

  std::vector<Frame> sent;
  can::TxBatch batch;
  // Boot-up, an EMCY, two PDO sets, a heartbeat, an error reset EMCY.
  ASSERT_TRUE(node.collect(0, batch).ok());
  ASSERT_TRUE(node.set_fault(can::Fault::kCameraTimeout, true, 77).ok());
  ASSERT_TRUE(node.publish(sample_estimate(0)).ok());
  ASSERT_TRUE(node.collect(1000, batch).ok());
  ASSERT_TRUE(node.publish(sample_estimate(1)).ok());
  ASSERT_TRUE(node.set_fault(can::Fault::kCameraTimeout, false, 0).ok());
  ASSERT_TRUE(node.collect(100000, batch).ok());
  // What the estimator does not send but the robot does, for completeness.
  Frame extra;
  can::NmtMessage nmt{can::NmtCommand::kStart, kNode};
  ASSERT_TRUE(can::encode_nmt(nmt, extra).ok());
  ASSERT_TRUE(batch.push_back(extra));
  ASSERT_TRUE(can::encode_sync(extra).ok());
  ASSERT_TRUE(batch.push_back(extra));
  can::EncoderPriorMessage prior{12.34, -0.5, 0.25, can::EstimateStatus::kDegraded, 9};
  ASSERT_TRUE(can::encode_encoder_prior(kNode, prior, extra).ok());
  ASSERT_TRUE(batch.push_back(extra));
  sent.assign(batch.begin(), batch.end());
  ASSERT_EQ(sent.size(), 1U + 1U + 4U + 4U + 1U + 1U + 3U);

  Candump candump(static_cast<int>(sent.size()));
  ASSERT_TRUE(candump.bound()) << "candump never appeared in /proc/net/can/rcvlist_all";
  for (const Frame& f : sent) {
    ASSERT_TRUE(bus.send(f).ok());
  }
  const std::vector<std::string> lines = candump.finish(10000);
  ASSERT_EQ(lines.size(), sent.size());

  int pdo_set = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    Frame got;
    ASSERT_TRUE(parse_candump_line(lines[i], got)) << lines[i];
    EXPECT_NE(lines[i].find(std::string(" ") + iface() + " "), std::string::npos) << lines[i];
    EXPECT_EQ(got, sent[i]) << lines[i];
    // Every field, decoded from what candump saw, against what was sent.
    if (got.id == can::heartbeat_id(kNode)) {
      const auto state = can::decode_heartbeat(kNode, got);
      ASSERT_TRUE(state.ok());
      EXPECT_EQ(state.value(), i == 0 ? can::NmtState::kBootUp : can::NmtState::kOperational);
    } else if (got.id == can::emcy_id(kNode)) {
      const auto emcy = can::decode_emcy(kNode, got);
      ASSERT_TRUE(emcy.ok());
      const bool raise = i == 1;
      EXPECT_EQ(emcy.value().error_code, raise ? 0xFF01U : 0x0000U);
      EXPECT_EQ(emcy.value().error_register, raise ? 0x81U : 0x00U);
      EXPECT_EQ(emcy.value().fault_id, 1U);
      EXPECT_EQ(emcy.value().detail, raise ? 77U : 0U);
    } else if (got.id == can::tcp_id(kNode)) {
      const auto tcp = can::decode_tcp(kNode, got);
      ASSERT_TRUE(tcp.ok());
      const can::Estimate e = sample_estimate(pdo_set);
      EXPECT_NEAR(tcp.value().x_mm, e.tcp_x_mm, 0.005);
      EXPECT_NEAR(tcp.value().y_mm, e.tcp_y_mm, 0.005);
      EXPECT_NEAR(tcp.value().z_mm, e.tcp_z_mm, 0.005);
      EXPECT_EQ(tcp.value().status, can::EstimateStatus::kValid);
      EXPECT_EQ(tcp.value().counter, pdo_set);
    } else if (got.id == can::joints_id(kNode)) {
      const auto joints = can::decode_joints(kNode, got);
      ASSERT_TRUE(joints.ok());
      EXPECT_NEAR(joints.value().lambda_mm, 20.0, 0.005);
      EXPECT_NEAR(joints.value().phi_rad, 0.3, 0.00005);
      EXPECT_NEAR(joints.value().theta_rad, -0.8, 0.00005);
      EXPECT_EQ(joints.value().status, can::EstimateStatus::kValid);
      EXPECT_EQ(joints.value().counter, pdo_set);
    } else if (got.id == can::mechanical_id(kNode)) {
      const auto mech = can::decode_mechanical(kNode, got);
      ASSERT_TRUE(mech.ok());
      EXPECT_NEAR(mech.value().x_ch_mm, -13.3, 0.005);
      EXPECT_NEAR(mech.value().y_ch_mm, 6.2, 0.005);
      EXPECT_NEAR(mech.value().psi_rad, 0.1745, 0.00005);
      EXPECT_NEAR(mech.value().mu_rad, 0.0123, 0.00005);
    } else if (got.id == can::quality_id(kNode)) {
      const auto quality = can::decode_quality(kNode, got);
      ASSERT_TRUE(quality.ok());
      const can::Estimate e = sample_estimate(pdo_set);
      EXPECT_EQ(quality.value().corners_detected, 12U);
      EXPECT_EQ(quality.value().corners_used, 10U);
      EXPECT_NEAR(quality.value().rms_px, 0.42, 0.005);
      EXPECT_EQ(quality.value().latency_us, 8123);
      EXPECT_EQ(quality.value().frame_counter, e.frame_counter);
      ++pdo_set;
    } else if (got.id == can::kNmtId) {
      const auto decoded = can::decode_nmt(got);
      ASSERT_TRUE(decoded.ok());
      EXPECT_EQ(decoded.value().command, can::NmtCommand::kStart);
      EXPECT_EQ(decoded.value().node_id, kNode);
    } else if (got.id == can::kSyncId) {
      EXPECT_TRUE(can::decode_sync(got).ok());
      EXPECT_EQ(got.length, 0U);
    } else if (got.id == can::encoder_prior_id(kNode)) {
      const auto decoded = can::decode_encoder_prior(kNode, got);
      ASSERT_TRUE(decoded.ok());
      EXPECT_NEAR(decoded.value().lambda_mm, 12.34, 0.005);
      EXPECT_NEAR(decoded.value().phi_rad, -0.5, 0.00005);
      EXPECT_NEAR(decoded.value().theta_rad, 0.25, 0.00005);
      EXPECT_EQ(decoded.value().status, can::EstimateStatus::kDegraded);
      EXPECT_EQ(decoded.value().counter, 9U);
    } else {
      ADD_FAILURE() << "unexpected frame " << lines[i];
    }
  }
  EXPECT_EQ(pdo_set, 2);
}

// Verifies: REQ-CAN-014
TEST_F(Vcan, CansendNmtSyncAndEncoderPriorDriveTheNode) {
  SocketCanBus bus;
  ASSERT_TRUE(bus.open(iface(), node_rx_config()).ok());
  can::NodeConfig config;
  config.sync_mode = true;
  config.prior_e2e = can::E2eConfig{2, 2000000};
  can::Node node;
  ASSERT_TRUE(node.configure(config).ok());
  static_cast<void>(pump(bus, node, monotonic_us()));
  ASSERT_EQ(node.state(), can::NmtState::kPreOperational);

  // An unrelated ID is filtered by the kernel: the node never sees it.
  ASSERT_EQ(run({"cansend", iface(), "123#0102"}), 0);
  // NMT start for another node: ignored.
  ASSERT_EQ(run({"cansend", iface(), "000#0111"}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.counters().nmt_other_node == 1U; }, 3000));
  EXPECT_EQ(node.state(), can::NmtState::kPreOperational);
  // NMT start for us.
  ASSERT_EQ(run({"cansend", iface(), "000#0110"}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.state() == can::NmtState::kOperational; }, 3000));

  // SYNC: the latest estimate goes out, once.
  ASSERT_TRUE(node.publish(sample_estimate(3)).ok());
  std::vector<Frame> sent;
  ASSERT_EQ(run({"cansend", iface(), "080#"}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.counters().pdo_cycles_sent == 1U; }, 3000, &sent));
  const auto tcp_frames = std::count_if(sent.begin(), sent.end(), [](const Frame& f) { return f.id == 0x190U; });
  EXPECT_EQ(tcp_frames, 1);

  // A valid ENCODER_PRIOR, built by our encoder, sent by cansend.
  Frame prior;
  ASSERT_TRUE(can::encode_encoder_prior(kNode, {15.5, 0.125, -0.25, can::EstimateStatus::kValid, 0}, prior).ok());
  ASSERT_EQ(run({"cansend", iface(), cansend_arg(prior)}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.encoder_prior(monotonic_us()).ok(); }, 3000));
  auto latest = node.encoder_prior(monotonic_us());
  ASSERT_TRUE(latest.ok());
  EXPECT_NEAR(latest.value().lambda_mm, 15.5, 1e-9);
  EXPECT_NEAR(latest.value().phi_rad, 0.125, 1e-9);
  EXPECT_NEAR(latest.value().theta_rad, -0.25, 1e-9);

  // Corrupted: one payload bit flipped after the CRC was computed.
  Frame corrupt;
  ASSERT_TRUE(can::encode_encoder_prior(kNode, {99.0, 0.0, 0.0, can::EstimateStatus::kValid, 1}, corrupt).ok());
  corrupt.data[1] ^= 0x10;
  sent.clear();
  ASSERT_EQ(run({"cansend", iface(), cansend_arg(corrupt)}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.prior_counters().bad_crc == 1U; }, 3000, &sent));
  EXPECT_TRUE(node.fault_active(can::Fault::kPriorE2eError));
  EXPECT_NEAR(node.encoder_prior(monotonic_us()).value().lambda_mm, 15.5, 1e-9);
  const auto emcy = std::find_if(sent.begin(), sent.end(), [](const Frame& f) { return f.id == 0x090U; });
  ASSERT_NE(emcy, sent.end());
  EXPECT_EQ(can::decode_emcy(kNode, *emcy).value().error_code, 0x8200U);

  // Repeated counter (0 again), then wrong length: counted, ignored.
  ASSERT_EQ(run({"cansend", iface(), cansend_arg(prior)}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.prior_counters().repeated == 1U; }, 3000));
  ASSERT_EQ(run({"cansend", iface(), "210#0102"}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.prior_counters().bad_length == 1U; }, 3000));
  // The next in sequence is accepted again and clears the fault.
  Frame next;
  ASSERT_TRUE(can::encode_encoder_prior(kNode, {16.0, 0.0, 0.0, can::EstimateStatus::kValid, 1}, next).ok());
  ASSERT_EQ(run({"cansend", iface(), cansend_arg(next)}), 0);
  EXPECT_TRUE(pump_until(
      bus, node, [&] { return node.encoder_prior(monotonic_us()).value_or(can::EncoderPrior{}).lambda_mm == 16.0; },
      3000));
  EXPECT_FALSE(node.fault_active(can::Fault::kPriorE2eError));

  // Reset node: boot-up again, pre-operational.
  sent.clear();
  ASSERT_EQ(run({"cansend", iface(), "000#8110"}), 0);
  EXPECT_TRUE(pump_until(bus, node, [&] { return node.counters().boot_ups_sent == 2U; }, 3000, &sent));
  EXPECT_EQ(node.state(), can::NmtState::kPreOperational);
  EXPECT_EQ(node.counters().rx_unknown_id, 0U) << "0x123 should have been filtered by the kernel";
}

// Stand-in publisher: a Node at `rate_hz`, absolute sleeps; the receiver
// measures TCP periods from kernel timestamps.
void run_timing(int rate_hz, double seconds) {
  const int cycles = static_cast<int>(rate_hz * seconds);
  const std::int64_t period_us = 1000000 / rate_hz;
  SocketCanBus receiver;
  SocketCanConfig rx_config;
  ASSERT_TRUE(rx_config.rx_ids.push_back(can::tcp_id(kNode)));
  ASSERT_TRUE(receiver.open(iface(), rx_config).ok());

  std::atomic<int> failures{0};
  std::thread publisher([&] {
    SocketCanBus bus;
    if (!bus.open(iface(), SocketCanConfig{}).ok()) {
      failures = 1000;
      return;
    }
    can::NodeConfig config;
    config.start_operational = true;
    can::Node node;
    if (!node.configure(config).ok()) {
      failures = 1000;
      return;
    }
    timespec next{};
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (int i = 0; i < cycles; ++i) {
      next.tv_nsec += period_us * 1000;
      while (next.tv_nsec >= 1000000000) {
        next.tv_nsec -= 1000000000;
        ++next.tv_sec;
      }
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
      can::Estimate e = sample_estimate(0);
      e.frame_counter = static_cast<std::uint16_t>(i);
      e.tcp_x_mm = i * 0.01;  // the cycle index, in the TCP frame itself
      static_cast<void>(node.publish(e));
      can::TxBatch batch;
      static_cast<void>(node.collect(i * period_us, batch));
      for (const Frame& f : batch) {
        if (!bus.send(f).ok()) {
          ++failures;
        }
      }
    }
  });

  std::vector<ReceivedFrame> got;
  const std::int64_t deadline = monotonic_us() + static_cast<std::int64_t>((seconds + 5.0) * 1e6);
  ReceivedFrame rx[64];
  while (static_cast<int>(got.size()) < cycles && monotonic_us() < deadline) {
    pollfd p{receiver.fd(), POLLIN, 0};
    poll(&p, 1, 100);
    const auto n = receiver.receive(rx, 64);
    ASSERT_TRUE(n.ok());
    got.insert(got.end(), rx, rx + n.value());
  }
  publisher.join();
  EXPECT_EQ(failures.load(), 0);
  ASSERT_EQ(static_cast<int>(got.size()), cycles) << "frames lost";
  std::vector<double> deviations_us;
  for (int i = 0; i < cycles; ++i) {
    const auto tcp = can::decode_tcp(kNode, got[i].frame);
    ASSERT_TRUE(tcp.ok());
    EXPECT_EQ(std::lround(tcp.value().x_mm * 100.0), i) << "out of order";
    EXPECT_EQ(tcp.value().counter, i % 15);
    EXPECT_GT(got[i].timestamp_us, 0);
    if (i > 0) {
      const double period = static_cast<double>(got[i].timestamp_us - got[i - 1].timestamp_us);
      deviations_us.push_back(std::fabs(period - static_cast<double>(period_us)));
    }
  }
  const double mean_period =
      static_cast<double>(got.back().timestamp_us - got.front().timestamp_us) / (cycles - 1);
  std::sort(deviations_us.begin(), deviations_us.end());
  const double p50 = deviations_us[(deviations_us.size() - 1) / 2];
  const double p99 = deviations_us[(deviations_us.size() - 1) * 99 / 100];
  const double max = deviations_us.back();
  std::printf("timing %d Hz: %d frames, mean period %.1f us (nominal %lld), |period - nominal| p50 %.0f us, p99 %.0f us, "
              "max %.0f us, "
              "kernel drops %llu\n",
              rate_hz, cycles, mean_period, static_cast<long long>(period_us), p50, p99, max,
              static_cast<unsigned long long>(receiver.stats().rx_kernel_dropped));
  ::testing::Test::RecordProperty("mean_period_us_" + std::to_string(rate_hz), std::to_string(mean_period));
  ::testing::Test::RecordProperty("jitter_p99_us_" + std::to_string(rate_hz), std::to_string(p99));
  ::testing::Test::RecordProperty("jitter_max_us_" + std::to_string(rate_hz), std::to_string(max));
  EXPECT_NEAR(mean_period, static_cast<double>(period_us), 0.02 * static_cast<double>(period_us));
}

TEST_F(Vcan, Timing25Hz) { run_timing(25, 3.0); }
TEST_F(Vcan, Timing100Hz) { run_timing(100, 3.0); }

// Verifies: REQ-HAL-003
TEST_F(Vcan, InterfaceDownAndUpWhileSending) {
  SocketCanConfig tx_config;
  tx_config.reopen_interval_us = 20000;
  SocketCanBus sender;
  ASSERT_TRUE(sender.open(iface(), tx_config).ok());
  SocketCanBus receiver;
  SocketCanConfig rx_config;
  ASSERT_TRUE(rx_config.rx_ids.push_back(0x190));
  ASSERT_TRUE(receiver.open(iface(), rx_config).ok());

  int ok_before = 0;
  int failed_down = 0;
  int ok_after = 0;
  Frame f;
  f.id = 0x190;
  f.length = 8;
  for (int i = 0; i < 20; ++i) {
    f.data[0] = static_cast<std::uint8_t>(i);
    ok_before += sender.send(f).ok() ? 1 : 0;
    sleep_ms(5);
  }
  ASSERT_EQ(run({"ip", "link", "set", iface(), "down"}), 0);
  for (int i = 0; i < 20; ++i) {
    const auto sent = sender.send(f);
    if (!sent.ok()) {
      EXPECT_EQ(sent.error(), hal::CanBusError::kInterfaceDown) << hal::to_string(sent.error());
      ++failed_down;
    }
    sleep_ms(5);
  }
  EXPECT_EQ(sender.state(), hal::BusState::kDown);
  ASSERT_EQ(run({"ip", "link", "set", iface(), "up"}), 0);
  const std::int64_t deadline = monotonic_us() + 3000000;
  while (ok_after < 20 && monotonic_us() < deadline) {
    f.data[0] = static_cast<std::uint8_t>(100 + ok_after);
    ok_after += sender.send(f).ok() ? 1 : 0;
    sleep_ms(5);
  }
  std::printf("down/up: %d sent before, %d refused while down, %d sent after; down events %llu, recoveries %llu, "
              "dropped %llu\n",
              ok_before, failed_down, ok_after, static_cast<unsigned long long>(sender.stats().down_events),
              static_cast<unsigned long long>(sender.stats().recoveries),
              static_cast<unsigned long long>(sender.stats().tx_dropped));
  EXPECT_EQ(ok_before, 20);
  EXPECT_EQ(failed_down, 20);
  EXPECT_EQ(ok_after, 20);
  EXPECT_GE(sender.stats().down_events, 1U);
  EXPECT_GE(sender.stats().recoveries, 1U);
  EXPECT_EQ(sender.stats().tx_dropped, 20U);
  EXPECT_EQ(sender.state(), hal::BusState::kUp);
  // The receiver got the frames sent after the interface came back.
  std::vector<ReceivedFrame> got;
  ReceivedFrame rx[64];
  const std::int64_t rx_deadline = monotonic_us() + 2000000;
  int after_seen = 0;
  while (after_seen < 20 && monotonic_us() < rx_deadline) {
    const auto n = receiver.receive(rx, 64);
    if (n.ok()) {
      for (std::size_t i = 0; i < n.value(); ++i) {
        after_seen += rx[i].frame.data[0] >= 100 ? 1 : 0;
      }
    }
    sleep_ms(5);
  }
  EXPECT_EQ(after_seen, 20);
}

// Verifies: REQ-HAL-003
TEST_F(Vcan, InterfaceDeletedAndRecreatedIsReopened) {
  struct Recreate {
    ~Recreate() {
      if (if_nametoindex(iface()) == 0) {
        static_cast<void>(run({"ip", "link", "add", "dev", iface(), "type", "vcan"}));
      }
      static_cast<void>(run({"ip", "link", "set", "up", iface()}));
    }
  } recreate;
  SocketCanConfig config;
  config.reopen_interval_us = 20000;
  SocketCanBus sender;
  ASSERT_TRUE(sender.open(iface(), config).ok());
  Frame f;
  f.id = 0x390;
  f.length = 2;
  ASSERT_TRUE(sender.send(f).ok());
  ASSERT_EQ(run({"ip", "link", "delete", iface()}), 0);
  const auto gone = sender.send(f);
  ASSERT_FALSE(gone.ok());
  EXPECT_TRUE(gone.error() == hal::CanBusError::kNoSuchInterface || gone.error() == hal::CanBusError::kInterfaceDown)
      << hal::to_string(gone.error());
  EXPECT_EQ(sender.state(), hal::BusState::kDown);
  sleep_ms(30);
  EXPECT_FALSE(sender.send(f).ok()) << "no interface, no send";
  ASSERT_EQ(run({"ip", "link", "add", "dev", iface(), "type", "vcan"}), 0);
  ASSERT_EQ(run({"ip", "link", "set", "up", iface()}), 0);
  SocketCanBus receiver;
  SocketCanConfig rx_config;
  ASSERT_TRUE(rx_config.rx_ids.push_back(0x390));
  ASSERT_TRUE(receiver.open(iface(), rx_config).ok());
  const std::int64_t deadline = monotonic_us() + 2000000;
  bool sent_again = false;
  while (!sent_again && monotonic_us() < deadline) {
    sent_again = sender.send(f).ok();
    sleep_ms(5);
  }
  EXPECT_TRUE(sent_again);
  EXPECT_EQ(sender.state(), hal::BusState::kUp);
  EXPECT_GE(sender.stats().recoveries, 1U);
  ReceivedFrame rx[4];
  std::size_t got = 0;
  const std::int64_t rx_deadline = monotonic_us() + 1000000;
  while (got == 0 && monotonic_us() < rx_deadline) {
    const auto n = receiver.receive(rx, 4);
    got = n.ok() ? n.value() : 0U;
    sleep_ms(5);
  }
  EXPECT_EQ(got, 1U) << "the reopened socket is bound to the new interface";
}

// Verifies: REQ-HAL-003
TEST_F(Vcan, FullTxQueueIsRetriedCountedAndRecovered) {
  // A plug qdisc holds frames until released: the TX queue fills (ENOBUFS).
  if (run({"tc", "qdisc", "add", "dev", iface(), "root", "plug", "limit", "160"}) != 0) {
    GTEST_SKIP() << "tc plug qdisc not available (sch_plug)";
  }
  struct Cleanup {
    ~Cleanup() { static_cast<void>(run({"tc", "qdisc", "del", "dev", iface(), "root"})); }
  } cleanup;
  ASSERT_EQ(run({"tc", "qdisc", "change", "dev", iface(), "root", "plug", "block"}), 0);
  SocketCanConfig config;
  config.tx_retry_count = 3;
  config.tx_retry_wait_us = 200;
  SocketCanBus sender;
  ASSERT_TRUE(sender.open(iface(), config).ok());
  SocketCanBus receiver;
  SocketCanConfig rx_config;
  ASSERT_TRUE(rx_config.rx_ids.push_back(0x290));
  ASSERT_TRUE(receiver.open(iface(), rx_config).ok());

  Frame f;
  f.id = 0x290;
  f.length = 8;
  int accepted = 0;
  int full = 0;
  for (int i = 0; i < 30; ++i) {
    f.data[0] = static_cast<std::uint8_t>(i);
    const auto sent = sender.send(f);
    if (sent.ok()) {
      ++accepted;
    } else {
      EXPECT_EQ(sent.error(), hal::CanBusError::kTxQueueFull) << hal::to_string(sent.error());
      ++full;
    }
  }
  std::printf("queue full: %d accepted, %d dropped after retries; retries %llu, dropped %llu\n", accepted, full,
              static_cast<unsigned long long>(sender.stats().tx_retries),
              static_cast<unsigned long long>(sender.stats().tx_dropped));
  EXPECT_GT(accepted, 0);
  EXPECT_GT(full, 0);
  EXPECT_EQ(sender.stats().tx_dropped, static_cast<std::uint64_t>(full));
  EXPECT_EQ(sender.stats().tx_retries, static_cast<std::uint64_t>(full) * 3U);
  EXPECT_EQ(sender.state(), hal::BusState::kUp);

  ASSERT_EQ(run({"tc", "qdisc", "change", "dev", iface(), "root", "plug", "release_indefinite"}), 0);
  f.data[0] = 200;
  EXPECT_TRUE(sender.send(f).ok());
  ReceivedFrame rx[64];
  std::vector<int> seen;
  const std::int64_t deadline = monotonic_us() + 2000000;
  while (static_cast<int>(seen.size()) < accepted + 1 && monotonic_us() < deadline) {
    const auto n = receiver.receive(rx, 64);
    if (n.ok()) {
      for (std::size_t i = 0; i < n.value(); ++i) {
        seen.push_back(rx[i].frame.data[0]);
      }
    }
    sleep_ms(5);
  }
  ASSERT_EQ(static_cast<int>(seen.size()), accepted + 1);
  for (int i = 0; i < accepted; ++i) {
    EXPECT_EQ(seen[i], i) << "the queued frames come out in order";
  }
  EXPECT_EQ(seen.back(), 200);
}

// Verifies: REQ-HAL-003
TEST_F(Vcan, ErrorFramesChangeTheBusState) {
  SocketCanBus bus;
  ASSERT_TRUE(bus.open(iface(), SocketCanConfig{}).ok());
  const int raw = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  ASSERT_GE(raw, 0);
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(if_nametoindex(iface()));
  ASSERT_EQ(bind(raw, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  const auto inject = [&](canid_t id, std::uint8_t data1) {
    can_frame frame{};
    frame.can_id = CAN_ERR_FLAG | id;
    frame.len = CAN_ERR_DLC;
    frame.data[1] = data1;
    ASSERT_EQ(write(raw, &frame, sizeof frame), static_cast<ssize_t>(sizeof frame));
  };
  const auto drain = [&] {
    ReceivedFrame rx[8];
    const std::int64_t until = monotonic_us() + 200000;
    while (monotonic_us() < until) {
      const auto n = bus.receive(rx, 8);
      ASSERT_TRUE(n.ok());
      EXPECT_EQ(n.value(), 0U) << "error frames are not data";
      sleep_ms(5);
    }
  };
  inject(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE);
  drain();
  EXPECT_EQ(bus.state(), hal::BusState::kErrorPassive);
  inject(CAN_ERR_BUSOFF, 0);
  drain();
  EXPECT_EQ(bus.state(), hal::BusState::kBusOff);
  Frame f;
  f.id = 0x190;
  EXPECT_EQ(bus.send(f).error(), hal::CanBusError::kBusOff);
  inject(CAN_ERR_RESTARTED, 0);
  drain();
  EXPECT_EQ(bus.state(), hal::BusState::kUp);
  EXPECT_TRUE(bus.send(f).ok());
  EXPECT_EQ(bus.stats().bus_off, 1U);
  EXPECT_EQ(bus.stats().controller_problems, 1U);
  EXPECT_EQ(bus.stats().restarts, 1U);
  close(raw);
}

// Verifies: REQ-HAL-003
TEST_F(Vcan, FloodIsBoundedPerCycleAndKernelDropsCounted) {
  // A small receive buffer so that the kernel has to drop part of the flood.
  SocketCanConfig config = node_rx_config();
  config.receive_buffer_bytes = 4096;
  SocketCanBus bus;
  ASSERT_TRUE(bus.open(iface(), config).ok());
  SocketCanBus flooder;
  ASSERT_TRUE(flooder.open(iface(), SocketCanConfig{}).ok());
  Frame sync;
  ASSERT_TRUE(can::encode_sync(sync).ok());
  Frame other;
  other.id = 0x555;
  other.length = 8;
  constexpr int kFlood = 5000;
  int sent = 0;
  for (int i = 0; i < kFlood; ++i) {
    sent += flooder.send(i % 2 == 0 ? sync : other).ok() ? 1 : 0;  // half of it filtered by the kernel
  }
  can::NodeConfig node_config;
  node_config.start_operational = true;
  node_config.sync_mode = true;
  can::Node node;
  ASSERT_TRUE(node.configure(node_config).ok());
  can::TxBatch boot;
  ASSERT_TRUE(node.collect(0, boot).ok());  // boot-up: the node listens from now on
  std::uint64_t received = 0;
  std::size_t largest_batch = 0;
  bool probe_sent = false;
  for (int cycle = 1; cycle < 400; ++cycle) {
    ReceivedFrame rx[can::kMaxRxPerCycle];
    const auto n = bus.receive(rx, can::kMaxRxPerCycle);
    ASSERT_TRUE(n.ok());
    largest_batch = std::max(largest_batch, n.value());
    received += n.value();
    Frame frames[can::kMaxRxPerCycle];
    for (std::size_t i = 0; i < n.value(); ++i) {
      frames[i] = rx[i].frame;
    }
    static_cast<void>(node.receive(frames, n.value(), cycle * 1000));
    can::TxBatch batch;
    ASSERT_TRUE(node.collect(cycle * 1000, batch).ok());
    EXPECT_LE(batch.size(), can::kMaxTxPerCycle);
    if (n.value() == 0) {
      if (probe_sent) {
        break;
      }
      // The kernel reports its drop count with the next frame it queues.
      ASSERT_TRUE(flooder.send(sync).ok());
      probe_sent = true;
      sleep_ms(20);
    }
  }
  std::printf("flood: %d sent, %llu SYNC received (at most %zu per cycle), %llu dropped by the kernel\n", sent,
              static_cast<unsigned long long>(received), largest_batch,
              static_cast<unsigned long long>(bus.stats().rx_kernel_dropped));
  EXPECT_EQ(sent, kFlood);
  EXPECT_LE(largest_batch, can::kMaxRxPerCycle);
  EXPECT_GT(bus.stats().rx_kernel_dropped, 0U) << "SO_RXQ_OVFL should report the overflow";
  EXPECT_EQ(received + bus.stats().rx_kernel_dropped, static_cast<std::uint64_t>(kFlood / 2 + 1));
  EXPECT_EQ(node.counters().rx_unknown_id, 0U) << "0x555 is filtered in the kernel";
  EXPECT_EQ(node.counters().sync_received, received);
}

// Verifies: REQ-HAL-005
TEST_F(Vcan, CandumpLogReplaysWithCanplayer) {
  const std::string path = temp_path("replay") + ".log";
  hal::CandumpLogWriter writer;
  ASSERT_TRUE(writer.open(path.c_str(), iface()).ok());
  std::vector<Frame> written;
  for (int i = 0; i < 10; ++i) {
    Frame f;
    f.id = 0x480 + static_cast<std::uint32_t>(i);
    f.length = static_cast<std::uint8_t>(i % 9);
    for (int b = 0; b < f.length; ++b) {
      f.data[b] = static_cast<std::uint8_t>(i * 16 + b);
    }
    ASSERT_TRUE(writer.write(f, 1700000000000000LL + i * 1000).ok());
    written.push_back(f);
  }
  ASSERT_TRUE(writer.close().ok());
  SocketCanBus receiver;
  ASSERT_TRUE(receiver.open(iface(), SocketCanConfig{}).ok());
  ASSERT_EQ(run({"canplayer", "-t", "-I", path}), 0);
  std::vector<Frame> got;
  ReceivedFrame rx[16];
  const std::int64_t deadline = monotonic_us() + 2000000;
  while (got.size() < written.size() && monotonic_us() < deadline) {
    const auto n = receiver.receive(rx, 16);
    ASSERT_TRUE(n.ok());
    for (std::size_t i = 0; i < n.value(); ++i) {
      got.push_back(rx[i].frame);
    }
    sleep_ms(5);
  }
  ASSERT_EQ(got.size(), written.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i], written[i]) << i;
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace tcpest
