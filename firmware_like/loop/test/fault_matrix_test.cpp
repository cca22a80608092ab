// The fault matrix: every fault the loop must live through, in one table,
// each injected into the shipped loop (Executive, CanNodePort, can::Node on
// the simulated bus, a candump log) while a robot on the other end of the
// bus reads what the node sends with the reference receiver (can::Receiver).
// A row says how the fault is made and ended, the state the loop must be in
// while it holds, the EMCY the node must raise and the robot must (or cannot)
// see, and how soon everything must be back after it ends. The SocketCAN
// side of the same faults (the kernel's ENOBUFS, an interface set down and
// up, error frames) is tested against the vcan driver (tests/vcan).
#include <gtest/gtest.h>

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "tcpest/can_iface/messages.hpp"
#include "tcpest/can_iface/receiver.hpp"
#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/hal/can/sim_bus.hpp"
#include "tcpest/loop/can_node_port.hpp"
#include "tcpest/loop/executive.hpp"
#include "tcpest/loop/motion.hpp"
#include "oracle_pipeline.hpp"

namespace tcpest {
namespace loop {
namespace {

constexpr std::int64_t kFramePeriodNs = 40 * hal::kNsPerMs;  // a 25 Hz camera

// The estimator's end of the bus: the simulated endpoint, with the two
// faults the simulated bus does not make itself, as SocketCanBus reports
// them: a transmit queue that stays full after the retries (ENOBUFS), and
// an interface set down (ENETDOWN) and up again.
class FaultyBus final : public hal::CanBus {
 public:
  explicit FaultyBus(hal::SimEndpoint& inner) noexcept : inner_(inner) {}
  Status<hal::CanBusError> send(const can::Frame& frame) noexcept override {
    if (down) {
      ++dropped_;
      return Status<hal::CanBusError>::failure(hal::CanBusError::kInterfaceDown);
    }
    if (tx_full) {
      ++dropped_;
      return Status<hal::CanBusError>::failure(hal::CanBusError::kTxQueueFull);
    }
    return inner_.send(frame);
  }
  Result<std::size_t, hal::CanBusError> receive(hal::ReceivedFrame* out, std::size_t max_frames) noexcept override {
    if (down) {
      return Result<std::size_t, hal::CanBusError>::failure(hal::CanBusError::kInterfaceDown);
    }
    return inner_.receive(out, max_frames);
  }
  hal::BusState state() const noexcept override { return down ? hal::BusState::kDown : inner_.state(); }
  const hal::CanBusStats& stats() const noexcept override {
    merged_ = inner_.stats();
    merged_.tx_dropped += dropped_;
    return merged_;
  }
  bool tx_full = false;
  bool down = false;

 private:
  hal::SimEndpoint& inner_;
  std::uint64_t dropped_ = 0U;
  mutable hal::CanBusStats merged_{};
};

// A live camera on the simulated clock (the harness lets one frame period
// pass before each cycle), which can go silent or deliver one frame late.
class LiveCamera final : public hal::FrameSource {
 public:
  LiveCamera(hal::SimCamera& inner, hal::SimulatedClock& clock) noexcept : inner_(inner), clock_(clock) {}
  const char* kind() const noexcept override { return "live"; }
  int width() const noexcept override { return inner_.width(); }
  int height() const noexcept override { return inner_.height(); }
  double rate_hz() const noexcept override { return 25.0; }
  bool live() const noexcept override { return true; }
  Status<hal::CameraError> acquire(const MutableImageView& out, hal::FrameInfo& info) noexcept override {
    if (silent) {
      return Status<hal::CameraError>::failure(hal::CameraError::kNotReady);
    }
    const std::int64_t exposed_ns = clock_.now_ns();
    clock_.advance_ns(late_ns);  // delivered late: the cycle waited for it
    late_ns = 0;
    const auto got = inner_.acquire(out, info);
    info.timestamp_ns = exposed_ns;
    return got;
  }
  Status<hal::CameraError> reopen() noexcept override {
    return silent ? Status<hal::CameraError>::failure(hal::CameraError::kNotReady) : ok_status<hal::CameraError>();
  }
  bool silent = false;
  std::int64_t late_ns = 0;

 private:
  hal::SimCamera& inner_;
  hal::SimulatedClock& clock_;
};

// The robot's side: NMT start, an ENCODER_PRIOR every cycle (good, corrupted
// or replayed), and everything the node sends read by the reference receiver.
enum class PriorStream : std::uint8_t { kGood, kCorruptCrc, kReplayed, kNone };

struct Harness {
  solver::CameraModel camera;
  solver::InstrumentModel model;
  MotionSequence motion;
  std::unique_ptr<ModelScene> scene;
  std::unique_ptr<hal::SimCamera> sim_camera;
  hal::SimulatedClock clock{5 * hal::kNsPerS};
  std::unique_ptr<LiveCamera> source;
  std::unique_ptr<OraclePipeline> pipeline;
  hal::SimBus bus;
  FaultyBus estimator_end{bus.endpoint(0)};
  hal::CandumpLogWriter log;
  std::string log_path;
  LoopConfig config;
  std::unique_ptr<CanNodePort> port;
  std::unique_ptr<Executive> loop;
  can::Receiver robot;
  PriorStream priors = PriorStream::kGood;
  can::Frame last_prior{};
  std::uint8_t prior_counter = 0U;
  std::vector<can::EmcyMessage> emcy;  // every EMCY the robot received, in order
  int max_heartbeats_per_cycle = 0;

  explicit Harness(const char* log_to) {
    const auto c = solver::CameraModel::create(solver::default_pal_camera());
    const auto m = solver::InstrumentModel::create(solver::InstrumentGeometry{});
    EXPECT_TRUE(c.ok() && m.ok());
    camera = c.value();
    model = m.value();
    motion.frames = 1000U;
    scene = std::make_unique<ModelScene>(camera, model, motion);
    sim_camera = std::make_unique<hal::SimCamera>(*scene, 25.0, true);
    source = std::make_unique<LiveCamera>(*sim_camera, clock);
    pipeline = std::make_unique<OraclePipeline>(camera, model);
    pipeline->set_truth_source(sim_camera.get());
    log_path = log_to != nullptr ? std::string(log_to)
                                 : ::testing::TempDir() + "fault_matrix_" + std::to_string(::getpid()) + ".log";
    EXPECT_TRUE(log.open(log_path.c_str(), "sim0").ok());
    port = std::make_unique<CanNodePort>(clock, estimator_end, &bus, &log, "sim0");
    EXPECT_TRUE(port->configure(node_config(config)).ok());
    LoopParts parts{source.get(), &clock, pipeline.get(), port.get(), &camera, &model};
    auto created = Executive::create(config, parts);
    EXPECT_TRUE(created.ok());
    loop = std::move(created.value());
    loop->start();
  }
  ~Harness() {
    static_cast<void>(log.close());  // the row checked what it needed of it
    if (log_path != "/dev/full") {
      static_cast<void>(std::remove(log_path.c_str()));  // a test's file: nothing to report
    }
  }
  Harness(const Harness&) = delete;
  Harness& operator=(const Harness&) = delete;
  Harness(Harness&&) = delete;
  Harness& operator=(Harness&&) = delete;

  std::int64_t now_us() const { return clock.now_ns() / hal::kNsPerUs; }

  // A send fails only while the simulated bus is off: the robot's frame is lost too.
  void robot_sends(const can::Frame& frame) { robot_send_failures += bus.endpoint(1).send(frame).ok() ? 0 : 1; }
  int robot_send_failures = 0;

  void robot_sends_prior() {
    if (priors == PriorStream::kNone) {
      return;
    }
    if (priors == PriorStream::kReplayed) {
      robot_sends(last_prior);  // the previous frame again: its counter repeats
      return;
    }
    // The joints of the frame just taken, as the robot's encoders read them.
    const hal::FrameTruth& truth = sim_camera->last_truth();
    can::EncoderPriorMessage m;
    m.lambda_mm = truth.r[solver::kLambda];
    m.phi_rad = truth.r[solver::kPhi];
    m.theta_rad = truth.r[solver::kTheta];
    m.status = can::EstimateStatus::kValid;
    m.counter = prior_counter;
    prior_counter = static_cast<std::uint8_t>((prior_counter + 1U) % 15U);
    can::Frame f;
    ASSERT_TRUE(can::encode_encoder_prior(config.can.node_id, m, f).ok());
    last_prior = f;
    if (priors == PriorStream::kCorruptCrc) {
      f.data[7] = static_cast<std::uint8_t>(f.data[7] ^ 0x5AU);
    }
    robot_sends(f);
  }

  // One cycle of the loop, then the robot reads what came and sends its prior.
  void cycle() {
    clock.advance_ns(kFramePeriodNs);  // the camera's next frame is due
    ASSERT_EQ(loop->run_cycle(), CycleOutcome::kContinue);
    bus.set_time_us(now_us());
    std::array<hal::ReceivedFrame, 64> rx{};
    const auto got = bus.endpoint(1).receive(rx.data(), rx.size());
    ASSERT_TRUE(got.ok());
    int heartbeats = 0;
    for (std::size_t i = 0; i < got.value(); ++i) {
      const auto what = robot.receive(rx[i].frame, now_us());
      if (what.ok() && what.value() == can::Message::kEmcy) {
        emcy.push_back(robot.last_emcy().value().value);
      }
      if (what.ok() && what.value() == can::Message::kHeartbeat) {
        ++heartbeats;
      }
    }
    max_heartbeats_per_cycle = heartbeats > max_heartbeats_per_cycle ? heartbeats : max_heartbeats_per_cycle;
    robot.update(now_us());
    robot_sends_prior();
  }
  void cycles(int n) {
    for (int i = 0; i < n && !::testing::Test::HasFatalFailure(); ++i) {
      cycle();
    }
  }
  // Started by the robot's NMT master, then a second of normal running.
  void start() {
    cycle();  // boot-up
    can::Frame f;
    ASSERT_TRUE(can::encode_nmt(can::NmtMessage{can::NmtCommand::kStart, config.can.node_id}, f).ok());
    robot_sends(f);
    cycles(25);
  }
  bool robot_saw(can::Fault fault, bool raised) const {
    const can::FaultInfo* info = can::fault_info(fault);
    for (const can::EmcyMessage& e : emcy) {
      if (e.fault_id == static_cast<std::uint8_t>(fault) && (e.error_code == info->error_code) == raised &&
          (raised || e.error_code == 0U)) {
        return true;
      }
    }
    return false;
  }
  bool healthy() const {
    return !loop->last().bus_lost && !loop->last().camera_lost &&
           robot.estimate_status(now_us()) == can::EstimateStatus::kValid;
  }
};

enum class Robot : std::uint8_t { kSeesIt, kCannotSeeIt };

// The fault a row makes the node raise, or none.
struct RaisedFault {
  bool any;
  can::Fault fault;
};
constexpr RaisedFault raises(can::Fault fault) { return RaisedFault{true, fault}; }
constexpr RaisedFault kNoFault{false, can::Fault::kCameraTimeout};

struct FaultRow {
  const char* name;
  const char* log_path;  // nullptr: a temporary file
  void (*inject)(Harness&);
  void (*clear)(Harness&);
  int hold_cycles;
  // While the fault holds (at its last cycle):
  bool bus_lost;
  bool camera_lost;
  RaisedFault raised;          // by the node (or none)
  Robot raise_seen;            // the robot received its EMCY while it held
  can::EstimateStatus robot_status;  // what the robot's receiver says of the estimate
  bool (*during)(Harness&);    // a row's own check while it holds (nullptr: none)
  // After it ends: everything back (node fault reset, the robot sees the
  // reset, valid estimates on the bus) within this many cycles.
  int recover_within;
  bool (*extra)(Harness&);     // a row's own check after recovery (nullptr: none)
};

void nothing(Harness& h) { static_cast<void>(h); }

const FaultRow kFaultMatrix[] = {
    // The controller goes bus-off for 2 s: nothing gets out, EMCY included;
    // processing goes on; when it is over the robot hears of it (fault 11
    // for one cycle, fault 12's reset).
    {"bus_off", nullptr, [](Harness& h) { h.bus.set_bus_off(true); },
     [](Harness& h) { h.bus.set_bus_off(false); }, 50, true, false, raises(can::Fault::kCanTxDropped),
     Robot::kCannotSeeIt, can::EstimateStatus::kInvalid,
     [](Harness& h) { return h.loop->stats().frames > 60U; },  // processing went on
     30,
     [](Harness& h) { return h.robot_saw(can::Fault::kCanBusOffRecovered, true) && h.loop->stats().bus_recoveries == 1U; }},
    // The transmit queue stays full after the retries (ENOBUFS) for 5
    // cycles: frames dropped and counted, never sent late; not a lost bus.
    {"tx_queue_full", nullptr, [](Harness& h) { h.estimator_end.tx_full = true; },
     [](Harness& h) { h.estimator_end.tx_full = false; }, 5, false, false, raises(can::Fault::kCanTxDropped),
     Robot::kCannotSeeIt, can::EstimateStatus::kInvalid,
     [](Harness& h) { return h.port->node().fault_active(can::Fault::kCanTxDropped); }, 2,
     [](Harness& h) { return h.port->frames_dropped() > 0U && h.loop->stats().bus_lost_events == 0U; }},
    // The interface is set down for 2 s, then up: reopened by the retries.
    {"interface_down_up", nullptr, [](Harness& h) { h.estimator_end.down = true; },
     [](Harness& h) { h.estimator_end.down = false; }, 50, true, false, raises(can::Fault::kCanTxDropped),
     Robot::kCannotSeeIt, can::EstimateStatus::kInvalid, nullptr, 30,
     [](Harness& h) { return h.loop->stats().bus_recoveries == 1U; }},
    // The camera stops delivering for 2 s: lost after camera_lost_after
    // cycles, status invalid on the bus every period, reopened by the retries.
    {"camera_stops_and_resumes", nullptr, [](Harness& h) { h.source->silent = true; },
     [](Harness& h) { h.source->silent = false; }, 50, false, true, raises(can::Fault::kCameraTimeout), Robot::kSeesIt,
     can::EstimateStatus::kInvalid, nullptr, 30,
     [](Harness& h) { return h.loop->stats().camera_recoveries == 1U; }},
    // One frame delivered 100 ms late: that cycle overruns (EMCY, reset by
    // the next cycle), its estimate goes out with the latency in QUALITY.
    {"late_frame", nullptr, [](Harness& h) { h.source->late_ns = 100 * hal::kNsPerMs; }, nothing, 1, false,
     false, raises(can::Fault::kCycleOverrun), Robot::kSeesIt, can::EstimateStatus::kValid,
     [](Harness& h) { return h.robot.quality().value().value.latency_us == 65535; },  // 100 ms: saturated
     2,
     [](Harness& h) { return h.loop->stats().cycle_overruns == 1U; }},
    // ENCODER_PRIOR with a wrong CRC for 10 cycles: refused, fault 8; the
    // loop goes on from its own track, uses the encoders again once good
    // frames return.
    {"prior_corrupted", nullptr, [](Harness& h) { h.priors = PriorStream::kCorruptCrc; },
     [](Harness& h) { h.priors = PriorStream::kGood; }, 10, false, false, raises(can::Fault::kPriorE2eError), Robot::kSeesIt,
     can::EstimateStatus::kValid, [](Harness& h) { return h.loop->last().prior != PriorSource::kEncoder; }, 3,
     [](Harness& h) { return h.loop->last().prior == PriorSource::kEncoder; }},
    // The same ENCODER_PRIOR frame replayed for 10 cycles: its counter
    // repeats, refused, fault 8; stale after prior_timeout_ms, and not
    // fresh again when the stream restarts (the replayed counter is refused).
    {"prior_replayed", nullptr, [](Harness& h) { h.priors = PriorStream::kReplayed; },
     [](Harness& h) { h.priors = PriorStream::kGood; }, 10, false, false, raises(can::Fault::kPriorE2eError), Robot::kSeesIt,
     can::EstimateStatus::kValid, [](Harness& h) { return h.loop->last().prior != PriorSource::kEncoder; }, 3,
     [](Harness& h) { return h.loop->last().prior == PriorSource::kEncoder; }},
    // The monotonic clock jumps 2 s between two cycles (a stalled process,
    // a paused VM): one heartbeat, not a burst; no overrun (the cycle itself
    // took no longer), no EMCY; the frame is processed as any other.
    {"clock_jump", nullptr, [](Harness& h) { h.clock.advance_ns(2 * hal::kNsPerS); }, nothing, 1, false, false,
     kNoFault, Robot::kCannotSeeIt, can::EstimateStatus::kValid,
     [](Harness& h) { return !h.loop->last().overrun && h.loop->last().have_frame; }, 3,
     [](Harness& h) { return h.loop->stats().cycle_overruns == 0U && h.max_heartbeats_per_cycle <= 1; }},
    // The candump log's disk is full from the start: every line fails and
    // is counted (the command reports it and exits 1), the bus is not touched.
    {"log_disk_full", "/dev/full", nothing, nothing, 25, false, false, kNoFault,
     Robot::kCannotSeeIt, can::EstimateStatus::kValid, nullptr, 1, [](Harness& h) {
       static_cast<void>(h.log.close());  // flushes: the failures are counted, the first errno kept
       return h.log.write_errors() > 0U && h.log.first_errno() == ENOSPC && h.port->frames_dropped() == 0U;
     }},
};

void PrintTo(const FaultRow& row, std::ostream* os) { *os << row.name; }

class FaultMatrix : public ::testing::TestWithParam<FaultRow> {};

// Verifies: REQ-LOOP-008, REQ-LOOP-009, REQ-LOOP-019
TEST_P(FaultMatrix, StateEmcyAndRecovery) {
  const FaultRow& row = GetParam();
  Harness h(row.log_path);
  h.start();
  ASSERT_FALSE(HasFatalFailure());
  ASSERT_TRUE(h.healthy()) << "not running normally before the fault: bus lost " << h.loop->last().bus_lost
                           << ", camera lost " << h.loop->last().camera_lost << ", robot's status "
                           << static_cast<int>(h.robot.estimate_status(h.now_us())) << ", published "
                           << h.loop->stats().published << ", mode " << to_string(h.loop->last().mode);
  const std::uint64_t prior_uses = h.loop->stats().prior[static_cast<std::size_t>(PriorSource::kEncoder)];
  EXPECT_GT(prior_uses, 0U) << "the encoders' prior is used before the fault";
  const std::size_t emcy_before = h.emcy.size();

  row.inject(h);
  h.cycles(row.hold_cycles);
  ASSERT_FALSE(HasFatalFailure());
  EXPECT_EQ(h.loop->last().bus_lost, row.bus_lost);
  EXPECT_EQ(h.loop->last().camera_lost, row.camera_lost);
  if (row.raised.any) {
    const bool node_raised = h.port->node().fault_active(row.raised.fault) || h.robot_saw(row.raised.fault, true);
    EXPECT_TRUE(node_raised) << "fault " << can::to_string(row.raised.fault) << " not raised";
    EXPECT_EQ(h.robot_saw(row.raised.fault, true), row.raise_seen == Robot::kSeesIt);
  } else {
    EXPECT_EQ(h.emcy.size(), emcy_before) << "an EMCY for a fault that is none";
  }
  EXPECT_EQ(h.robot.estimate_status(h.now_us()), row.robot_status);
  if (row.during != nullptr) {
    EXPECT_TRUE(row.during(h)) << "the row's own check while the fault holds";
  }

  row.clear(h);
  int cycles_to_recover = -1;
  for (int i = 1; i <= row.recover_within + 5 && cycles_to_recover < 0; ++i) {
    h.cycle();
    ASSERT_FALSE(HasFatalFailure());
    const bool reset =
        !row.raised.any || (!h.port->node().fault_active(row.raised.fault) && h.robot_saw(row.raised.fault, false));
    if (reset && h.healthy()) {
      cycles_to_recover = i;
    }
  }
  EXPECT_GE(cycles_to_recover, 1) << "not recovered";
  EXPECT_LE(cycles_to_recover, row.recover_within);
  // A second of normal running after it: nothing new is raised.
  h.cycles(25);
  EXPECT_TRUE(h.healthy());
  for (std::uint8_t id = 1U; id <= can::kFaultCount; ++id) {
    EXPECT_FALSE(h.port->node().fault_active(static_cast<can::Fault>(id))) << "fault " << int{id} << " still active";
  }
  if (row.extra != nullptr) {
    EXPECT_TRUE(row.extra(h)) << "the row's own check";
  }
}

INSTANTIATE_TEST_SUITE_P(Loop, FaultMatrix, ::testing::ValuesIn(kFaultMatrix),
                         [](const ::testing::TestParamInfo<FaultRow>& row_info) { return std::string(row_info.param.name); });

}  // namespace
}  // namespace loop
}  // namespace tcpest
