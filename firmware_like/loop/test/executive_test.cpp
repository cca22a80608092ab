#include "tcpest/loop/executive.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "tcpest/hal/camera/file_sources.hpp"
#include "tcpest/loop/memory_node.hpp"
#include "tcpest/loop/motion.hpp"
#include "oracle_pipeline.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace loop {
namespace {

solver::CameraModel pal_camera() {
  const auto camera = solver::CameraModel::create(solver::default_pal_camera());
  EXPECT_TRUE(camera.ok());
  return camera.value();
}

solver::InstrumentModel default_model() {
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{});
  EXPECT_TRUE(model.ok());
  return model.value();
}

// The loop on the truth-only scene, a simulated clock and the in-memory node.
struct Rig {
  solver::CameraModel camera = pal_camera();
  solver::InstrumentModel model = default_model();
  MotionSequence motion;
  std::unique_ptr<ModelScene> scene;
  std::unique_ptr<hal::SimCamera> source;
  hal::SimulatedClock clock{1000000000};
  OraclePipeline pipeline{camera, model};
  MemoryNode node{clock, true, 100 * hal::kNsPerMs, 100 * hal::kNsPerMs};
  LoopConfig config;
  std::unique_ptr<Executive> loop;

  explicit Rig(std::uint32_t frames = 250U, hal::FrameSource* other_source = nullptr) {
    motion.frames = frames;
    scene = std::make_unique<ModelScene>(camera, model, motion);
    source = std::make_unique<hal::SimCamera>(*scene, 25.0, false);
    // The truth beside the loop: the simulated camera's (none for another source).
    pipeline.set_truth_source(other_source != nullptr ? nullptr : source.get());
    build(other_source != nullptr ? other_source : source.get());
  }
  // The rig's parts with another pipeline (or source).
  LoopParts parts_with(FeaturePipeline& p, hal::FrameSource* s) {
    LoopParts parts;
    parts.source = s;
    parts.clock = &clock;
    parts.pipeline = &p;
    parts.node = &node;
    parts.camera = &camera;
    parts.instrument = &model;
    return parts;
  }
  void build(hal::FrameSource* s) {
    auto created = Executive::create(config, parts_with(pipeline, s));
    ASSERT_TRUE(created.ok());
    loop = std::move(created.value());
    loop->start();
  }
};

// Runs `cycles` cycles of `loop`; false (with the failure reported) at the
// first that does not go on.
bool run_cycles(Executive& loop, int cycles) {
  for (int i = 0; i < cycles; ++i) {
    const CycleOutcome outcome = loop.run_cycle();
    if (outcome != CycleOutcome::kContinue) {
      ADD_FAILURE() << "cycle " << i << " of " << cycles << " did not go on";
      return false;
    }
  }
  return true;
}

// Verifies: REQ-LOOP-001
TEST(Executive, TracksTheSimulatedMotionAndPublishesEveryFrame) {
  Rig rig(50U);
  ASSERT_EQ(rig.loop->run(nullptr), CycleOutcome::kFinished);
  const LoopStats& s = rig.loop->stats();
  EXPECT_EQ(s.frames, 50U);
  EXPECT_EQ(s.published, 50U);
  EXPECT_EQ(s.status[static_cast<std::size_t>(EstimateStatus::kValid)], 50U);
  EXPECT_EQ(s.prior[static_cast<std::size_t>(PriorSource::kGeneric)], 1U);
  EXPECT_EQ(s.prior[static_cast<std::size_t>(PriorSource::kTemporal)], 49U);
  // The last estimate is the truth of the last frame.
  const Publication& p = rig.node.publication(0);
  const auto truth_r = rig.motion.pose(rig.model.geometry(), 49U);
  const auto tcp = rig.model.tcp(truth_r);
  EXPECT_NEAR(p.tcp_mm[0], tcp.x(), 1e-3);
  EXPECT_NEAR(p.tcp_mm[1], tcp.y(), 1e-3);
  EXPECT_NEAR(p.tcp_mm[2], tcp.z(), 1e-3);
  EXPECT_EQ(p.frame_counter, 49U);
  EXPECT_GT(rig.node.heartbeats(), 0U);
}

// A new sequence (the soak's next pass over its dataset) starts from the
// generic prior with the pipeline's temporal priors and learned appearance
// forgotten, as the first frame did; it is not a lost track: nothing
// counted, no EMCY.
// Verifies: REQ-LOOP-018
TEST(Executive, ANewSequenceStartsFromTheGenericPriorWithoutDroppingTheTrack) {
  Rig rig(50U);
  ASSERT_TRUE(run_cycles(*rig.loop, 10));
  rig.loop->reset_sequence();
  EXPECT_EQ(rig.pipeline.drops(), 1);
  EXPECT_EQ(rig.pipeline.appearance_resets(), 1);
  ASSERT_TRUE(run_cycles(*rig.loop, 10));
  const LoopStats& s = rig.loop->stats();
  EXPECT_EQ(s.prior[static_cast<std::size_t>(PriorSource::kGeneric)], 2U);
  EXPECT_EQ(s.prior[static_cast<std::size_t>(PriorSource::kTemporal)], 18U);
  EXPECT_EQ(s.track_drops, 0U);
  EXPECT_EQ(s.status[static_cast<std::size_t>(EstimateStatus::kValid)], 20U);
  EXPECT_FALSE(rig.node.fault_active(Fault::kTrackingLost));
}

// Verifies: REQ-LOOP-006
TEST(Executive, NoHeapAllocationPerCycleWithTheSimulatedCamera) {
  Rig rig(3000U);
  ASSERT_TRUE(run_cycles(*rig.loop, 10));
  test::AllocationScope scope;
  ASSERT_TRUE(run_cycles(*rig.loop, 2990));
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(rig.loop->stats().status[0], 3000U);
}

// Verifies: REQ-LOOP-006
TEST(Executive, NoHeapAllocationPerCycleWithRawY4mFrames) {
  // A PAL clip of raw frames, replayed in a loop through the real decoder path.
  std::string dir = std::string(::testing::TempDir()) + "tcpest_loop_y4m_XXXXXX";
  ASSERT_NE(::mkdtemp(&dir[0]), nullptr);
  const std::string path = dir + "/clip.y4m";
  {
    hal::Y4mWriter writer;
    ASSERT_TRUE(writer.open(path.c_str(), 720, 576, 25, 1).ok());
    std::vector<std::uint8_t> rgb(720U * 576U * 3U);
    for (int f = 0; f < 8; ++f) {
      for (std::size_t i = 0; i < rgb.size(); ++i) {
        rgb[i] = static_cast<std::uint8_t>((i * 7U + static_cast<std::size_t>(f) * 13U) & 0xFFU);
      }
      ASSERT_TRUE(writer.write(ImageView{rgb.data(), 720, 576, 720U * 3U}).ok());
    }
    ASSERT_TRUE(writer.close().ok());
  }
  hal::ReplayOptions options;
  options.loop = true;
  auto source = hal::Y4mSource::open(path.c_str(), options);
  ASSERT_TRUE(source.ok());
  Rig rig(1U, source.value().get());
  ASSERT_TRUE(run_cycles(*rig.loop, 10));
  test::AllocationScope scope;
  ASSERT_TRUE(run_cycles(*rig.loop, 2000));
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(rig.loop->stats().frames, 2010U);
  // No truth on raw frames: the oracle finds nothing, so never a valid estimate.
  EXPECT_EQ(rig.loop->stats().status[static_cast<std::size_t>(EstimateStatus::kInvalid)], 2010U);
}

// Verifies: REQ-LOOP-011
TEST(Executive, TrackIsHeldThenDroppedThenReacquiredFromTheGenericPrior) {
  Rig rig(60U);
  rig.scene->blind(20U, 30U);  // ten frames without corners
  ASSERT_EQ(rig.loop->run(nullptr), CycleOutcome::kFinished);
  const LoopStats& s = rig.loop->stats();
  const int drop_after = rig.config.loop.track_drop_after;  // 5
  EXPECT_EQ(s.track_drops, 1U);
  EXPECT_EQ(s.status[static_cast<std::size_t>(EstimateStatus::kHeld)], static_cast<std::uint64_t>(drop_after - 1));
  EXPECT_EQ(s.status[static_cast<std::size_t>(EstimateStatus::kInvalid)], static_cast<std::uint64_t>(10 - drop_after + 1));
  EXPECT_EQ(s.status[static_cast<std::size_t>(EstimateStatus::kValid)], 50U);
  // Generic at the first frame and again after the drop (frames 20+drop_after .. 30).
  EXPECT_EQ(s.prior[static_cast<std::size_t>(PriorSource::kGeneric)], static_cast<std::uint64_t>(1 + 10 - drop_after + 1));
}

// Verifies: REQ-LOOP-012
TEST(Executive, FreshEncoderPriorIsUsedAndAStaleOneIsNot) {
  Rig rig(10U);
  const auto r = rig.motion.pose(rig.model.geometry(), 0U);
  rig.node.inject_prior(JointPrior{r[solver::kLambda], r[solver::kPhi], r[solver::kTheta]}, rig.clock.now_ns());
  ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
  EXPECT_EQ(rig.loop->last().prior, PriorSource::kEncoder);
  // The replay is paced at 25 Hz on the simulated clock: after 3 frames the prior is 120 ms old.
  ASSERT_TRUE(run_cycles(*rig.loop, 3));
  EXPECT_EQ(rig.loop->last().prior, PriorSource::kTemporal);
}

// Encoders that disagree with the image beyond their accuracy (loop.
// encoder_check_*): the estimate loses one level, and publishes degraded
// instead of valid; with the check off it stays valid.
// Verifies: REQ-SOLVER-010
TEST(Executive, AnEstimateFarFromTheEncodersIsPublishedOneLevelLower) {
  for (const bool check_on : {true, false}) {
    Rig rig(10U);
    if (!check_on) {
      rig.pipeline.set_encoder_check(solver::EncoderCheck{0.0, 0.0});
    }
    const auto r = rig.motion.pose(rig.model.geometry(), 0U);
    rig.node.inject_prior(JointPrior{r[solver::kLambda] + 9.0, r[solver::kPhi], r[solver::kTheta]},
                          rig.clock.now_ns());
    ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
    const CycleRecord& last = rig.loop->last();
    ASSERT_EQ(last.prior, PriorSource::kEncoder);
    ASSERT_TRUE(last.solved);
    EXPECT_NEAR(last.publication.r[solver::kLambda], r[solver::kLambda], 0.5);  // the image's, not the encoders'
    EXPECT_EQ(last.encoder_disagrees, check_on);
    EXPECT_EQ(last.publication.status, check_on ? EstimateStatus::kDegraded : EstimateStatus::kValid);
  }
}

// Verifies: REQ-LOOP-007
TEST(Executive, NmtStopAndPreOperationalSilenceThePdos) {
  Rig rig(40U);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  EXPECT_EQ(rig.node.published(), 5U);
  rig.node.inject_stop();
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  EXPECT_EQ(rig.node.published(), 5U);
  EXPECT_EQ(rig.loop->stats().frames, 5U);  // stopped: no processing either
  rig.node.inject_pre_operational();
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  EXPECT_EQ(rig.node.published(), 5U);
  EXPECT_EQ(rig.loop->stats().frames, 10U);  // pre-operational: processing goes on
  rig.node.inject_start();
  ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
  EXPECT_EQ(rig.node.published(), 6U);
  EXPECT_EQ(rig.node.publication(0).status, EstimateStatus::kValid);
  EXPECT_EQ(rig.pipeline.appearance_resets(), 0);
  rig.node.inject_reset();
  ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
  EXPECT_EQ(rig.loop->stats().resets, 1U);
  EXPECT_EQ(rig.loop->last().prior, PriorSource::kGeneric);
  EXPECT_EQ(rig.pipeline.appearance_resets(), 1);  // a reset node forgets what it learned of the scene
}

// A source serving the simulated camera's frames at 25 Hz, for the tests
// that make it fail in their own ways.
class WrappedSource : public hal::FrameSource {
 public:
  explicit WrappedSource(hal::SimCamera& inner) : inner_(inner) {}
  int width() const noexcept override { return inner_.width(); }
  int height() const noexcept override { return inner_.height(); }
  double rate_hz() const noexcept override { return 25.0; }

 protected:
  hal::SimCamera& inner_;
};

// A replay whose files are sometimes unreadable: `bad` gives, per acquire
// call (from 0), the error to return instead of the next frame.
class GlitchyReplay final : public WrappedSource {
 public:
  GlitchyReplay(hal::SimCamera& inner, const std::vector<std::pair<int, hal::CameraError>>& bad)
      : WrappedSource(inner), bad_(bad) {}
  const char* kind() const noexcept override { return "glitchy"; }
  bool live() const noexcept override { return false; }
  Status<hal::CameraError> acquire(const MutableImageView& out, hal::FrameInfo& info) noexcept override {
    const int call = calls_++;
    for (const auto& b : bad_) {
      if (b.first == call) {
        return Status<hal::CameraError>::failure(b.second);
      }
    }
    return inner_.acquire(out, info);
  }
  Status<hal::CameraError> reopen() noexcept override { return ok_status<hal::CameraError>(); }

 private:
  std::vector<std::pair<int, hal::CameraError>> bad_;
  int calls_ = 0;
};

// A corrupt, truncated or wrongly sized frame is one dropped frame: counted,
// said once on the bus (the frame-errors EMCY, cleared by the next good
// frame), and the loop goes on with the next frame; the camera is not
// declared lost.
// Verifies: REQ-LOOP-010
TEST(Executive, AnUnreadableFrameIsDroppedCountedAndTheLoopGoesOn) {
  Rig rig(100U);
  GlitchyReplay glitchy(*rig.source, {{5, hal::CameraError::kCorrupt},
                                      {6, hal::CameraError::kTruncated},
                                      {12, hal::CameraError::kWrongSize},
                                      {15, hal::CameraError::kUnsupported}});
  rig.build(&glitchy);
  std::uint64_t emcy = rig.node.emcy_count();
  for (int i = 0; i < 30; ++i) {
    ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue) << "cycle " << i;
    const bool dropped = i == 5 || i == 6 || i == 12 || i == 15;
    EXPECT_EQ(rig.loop->last().have_frame, !dropped) << "cycle " << i;
    // Raised by the first frame of a run of errors, cleared by the next good one.
    EXPECT_EQ(rig.node.fault_active(Fault::kImageCorrupt), dropped) << "cycle " << i;
    if (i == 5 || i == 12 || i == 15) {
      // The EMCY's detail: the frame counter this cycle's QUALITY carries.
      EXPECT_EQ(rig.node.fault_detail(Fault::kImageCorrupt), rig.node.publication(0).frame_counter) << "cycle " << i;
    }
    const bool changed = i == 5 || i == 7 || i == 12 || i == 13 || i == 15 || i == 16;
    EXPECT_EQ(rig.node.emcy_count() - emcy, changed ? 1U : 0U) << "cycle " << i;
    emcy = rig.node.emcy_count();
    EXPECT_FALSE(rig.loop->last().camera_lost) << "cycle " << i;
  }
  EXPECT_EQ(rig.loop->last().frame_error, hal::CameraError::kNone);
  EXPECT_EQ(rig.loop->stats().frames, 26U);
  EXPECT_EQ(rig.loop->stats().frame_errors, 4U);
  EXPECT_EQ(rig.loop->stats().camera_lost_events, 0U);
  EXPECT_EQ(rig.node.published(), 30U);  // the robot hears from the node every cycle
  EXPECT_EQ(rig.node.publication(0).status, EstimateStatus::kValid);
}

// Consecutive dropped frames are a lost camera, as consecutive cycles
// without a frame are (loop.camera_lost_after): said on the bus; a replay
// then ends (reopen() would replay the same damage), a live camera is
// retried. A shorter run of drops is not.
// Verifies: REQ-LOOP-008
TEST(Executive, ConsecutiveDroppedFramesAreALostCamera) {
  Rig rig(100U);
  std::vector<std::pair<int, hal::CameraError>> bad;
  for (int i = 10; i < 200; ++i) {
    bad.emplace_back(i, i < 12 ? hal::CameraError::kTruncated : hal::CameraError::kCorrupt);
  }
  bad.emplace_back(5, hal::CameraError::kCorrupt);
  GlitchyReplay glitchy(*rig.source, bad);
  rig.build(&glitchy);
  const int lost_after = rig.config.loop.camera_lost_after;
  ASSERT_TRUE(run_cycles(*rig.loop, 10));
  constexpr std::int64_t kPeriodMs = 40;
  for (int i = 0; i < lost_after - 1; ++i) {
    rig.clock.advance_ns(kPeriodMs * hal::kNsPerMs);
    ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
  }
  EXPECT_FALSE(rig.loop->last().camera_lost);
  rig.clock.advance_ns(kPeriodMs * hal::kNsPerMs);
  ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
  EXPECT_TRUE(rig.loop->last().camera_lost);
  EXPECT_TRUE(rig.node.fault_active(Fault::kCameraTimeout));
  // The EMCY's detail: milliseconds since the last frame acquired.
  EXPECT_GE(rig.node.fault_detail(Fault::kCameraTimeout), static_cast<std::uint32_t>(lost_after * kPeriodMs));
  EXPECT_LT(rig.node.fault_detail(Fault::kCameraTimeout), static_cast<std::uint32_t>((lost_after + 1) * kPeriodMs));
  EXPECT_EQ(rig.loop->stats().camera_lost_events, 1U);
  EXPECT_EQ(rig.loop->stats().frame_errors, static_cast<std::uint64_t>(lost_after) + 1U);
  EXPECT_EQ(rig.loop->run_cycle(), CycleOutcome::kFinished);
}

// A live camera that gives only damaged frames is lost and retried.
class DamagedCamera final : public WrappedSource {
 public:
  explicit DamagedCamera(hal::SimCamera& inner) : WrappedSource(inner) {}
  const char* kind() const noexcept override { return "damaged"; }
  bool live() const noexcept override { return true; }
  Status<hal::CameraError> acquire(const MutableImageView& out, hal::FrameInfo& info) noexcept override {
    return damaged ? Status<hal::CameraError>::failure(hal::CameraError::kCorrupt) : inner_.acquire(out, info);
  }
  Status<hal::CameraError> reopen() noexcept override {
    ++reopen_attempts;
    return ok_status<hal::CameraError>();
  }
  bool damaged = false;
  int reopen_attempts = 0;
};

// Verifies: REQ-LOOP-008
TEST(Executive, ALiveCameraGivingOnlyDamagedFramesIsLostAndRetried) {
  Rig rig(100U);
  DamagedCamera camera(*rig.source);
  rig.build(&camera);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  camera.damaged = true;
  ASSERT_TRUE(run_cycles(*rig.loop, rig.config.loop.camera_lost_after));
  EXPECT_TRUE(rig.loop->last().camera_lost);
  camera.damaged = false;
  ASSERT_TRUE(run_cycles(*rig.loop, 40));  // 40 ms fallback period: past retry_ms
  EXPECT_GE(camera.reopen_attempts, 1);
  EXPECT_FALSE(rig.loop->last().camera_lost);
  EXPECT_EQ(rig.loop->stats().camera_recoveries, 1U);
}


// A live camera that disappears and comes back.
class FlakyCamera final : public WrappedSource {
 public:
  explicit FlakyCamera(hal::SimCamera& inner) : WrappedSource(inner) {}
  const char* kind() const noexcept override { return "flaky"; }
  bool live() const noexcept override { return true; }
  Status<hal::CameraError> acquire(const MutableImageView& out, hal::FrameInfo& info) noexcept override {
    if (!present) {
      return Status<hal::CameraError>::failure(hal::CameraError::kDeviceLost);
    }
    return inner_.acquire(out, info);
  }
  Status<hal::CameraError> reopen() noexcept override {
    ++reopen_attempts;
    return present ? ok_status<hal::CameraError>() : Status<hal::CameraError>::failure(hal::CameraError::kNotFound);
  }
  bool present = true;
  int reopen_attempts = 0;
};

// Verifies: REQ-LOOP-008
TEST(Executive, LostCameraDegradesAndRecoversByItself) {
  Rig rig(100U);
  FlakyCamera flaky(*rig.source);
  rig.build(&flaky);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  flaky.present = false;
  ASSERT_TRUE(run_cycles(*rig.loop, 60));  // 60 cycles at the 40 ms fallback period: 2.4 s
  EXPECT_TRUE(rig.loop->last().camera_lost);
  EXPECT_TRUE(rig.node.fault_active(Fault::kCameraTimeout));
  EXPECT_EQ(rig.node.publication(0).status, EstimateStatus::kInvalid);
  EXPECT_GE(flaky.reopen_attempts, 2);
  EXPECT_LE(flaky.reopen_attempts, 3);  // once per retry_ms (1 s)
  flaky.present = true;
  ASSERT_TRUE(run_cycles(*rig.loop, 40));
  EXPECT_FALSE(rig.loop->last().camera_lost);
  EXPECT_FALSE(rig.node.fault_active(Fault::kCameraTimeout));
  EXPECT_EQ(rig.loop->stats().camera_lost_events, 1U);
  EXPECT_EQ(rig.loop->stats().camera_recoveries, 1U);
  EXPECT_EQ(rig.node.publication(0).status, EstimateStatus::kValid);
}

// A node reset forgets its faults (CiA 301 reset node): those that still
// hold are said again at once.
// Verifies: REQ-LOOP-007
TEST(Executive, AResetNodeIsToldAgainOfTheFaultsThatStillHold) {
  Rig rig(100U);
  FlakyCamera flaky(*rig.source);
  rig.build(&flaky);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  flaky.present = false;
  rig.node.set_bus_up(false);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  ASSERT_TRUE(rig.node.fault_active(Fault::kCameraTimeout));
  ASSERT_TRUE(rig.node.fault_active(Fault::kCanTxDropped));
  rig.node.inject_reset();
  ASSERT_FALSE(rig.node.fault_active(Fault::kCameraTimeout));  // the node forgot them
  ASSERT_EQ(rig.loop->run_cycle(), CycleOutcome::kContinue);
  EXPECT_EQ(rig.loop->stats().resets, 1U);
  EXPECT_TRUE(rig.node.fault_active(Fault::kCameraTimeout));
  EXPECT_TRUE(rig.node.fault_active(Fault::kCanTxDropped));
}

// Verifies: REQ-LOOP-009
TEST(Executive, LostBusDegradesAndRecoversByItself) {
  Rig rig(200U);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  rig.node.set_bus_up(false);
  ASSERT_TRUE(run_cycles(*rig.loop, 10));
  EXPECT_TRUE(rig.loop->last().bus_lost);
  EXPECT_EQ(rig.loop->stats().frames, 15U);  // processing goes on
  rig.node.set_bus_up(true);
  ASSERT_TRUE(run_cycles(*rig.loop, 40));  // retry_ms = 1 s = 25 frames
  EXPECT_FALSE(rig.loop->last().bus_lost);
  EXPECT_EQ(rig.loop->stats().bus_recoveries, 1U);
  EXPECT_FALSE(rig.node.fault_active(Fault::kCanTxDropped));
}

// Frames dropped on a full transmit queue: fault 12 in the cycles that
// dropped some, its detail how many; not a lost bus; reset by the first
// cycle that dropped none.
// Verifies: REQ-LOOP-019
TEST(Executive, FramesDroppedOnAFullQueueAreFault12ForTheCyclesThatDroppedThem) {
  Rig rig(100U);
  ASSERT_TRUE(run_cycles(*rig.loop, 5));
  rig.node.set_tx_full(true);
  ASSERT_TRUE(run_cycles(*rig.loop, 1));
  EXPECT_TRUE(rig.node.fault_active(Fault::kCanTxDropped));
  EXPECT_GE(rig.node.fault_detail(Fault::kCanTxDropped), 4U);  // the cycle's four PDOs at least
  EXPECT_FALSE(rig.loop->last().bus_lost);
  ASSERT_TRUE(run_cycles(*rig.loop, 3));
  EXPECT_TRUE(rig.node.fault_active(Fault::kCanTxDropped));
  rig.node.set_tx_full(false);
  ASSERT_TRUE(run_cycles(*rig.loop, 1));
  EXPECT_FALSE(rig.node.fault_active(Fault::kCanTxDropped));
  EXPECT_EQ(rig.loop->stats().bus_lost_events, 0U);
  EXPECT_EQ(rig.loop->stats().publish_errors, 4U);
}

// A pipeline whose model-guided rounds degrade the valid solve, as
// vision's do when its image fit contradicts it at the TCP
// (loop.max_valid_tcp_disagreement_mm).
class FitDegradingOracle final : public FeaturePipeline {
 public:
  explicit FitDegradingOracle(OraclePipeline& inner) : inner_(inner) {}
  const char* name() const noexcept override { return "fit-degrading"; }
  vision::FrameEstimate estimate(const ImageView& image, const vision::FramePrior& prior,
                                 vision::StepObserver& observer) noexcept override {
    vision::FrameEstimate e = inner_.estimate(image, prior, observer);
    e.guided.rounds_kept = 1;  // a round kept
    e.guided.disagreement_demoted = degrade && e.estimate.quality == solver::EstimateQuality::Valid;
    if (e.guided.disagreement_demoted) {
      e.estimate.quality = solver::EstimateQuality::Degraded;
    }
    return e;
  }
  void drop_track() noexcept override { inner_.drop_track(); }
  bool degrade = false;

 private:
  OraclePipeline& inner_;
};

// The cycle's record says why a valid solve was published degraded by the
// model-guided rounds (CycleRecord::fit_disagrees), and only then.
// Verifies: REQ-VISION-010
TEST(Executive, TheRecordSaysWhenTheImageFitDegradedTheSolve) {
  for (const bool degrade : {true, false}) {
    Rig rig(3U);
    FitDegradingOracle pipeline(rig.pipeline);
    pipeline.degrade = degrade;
    auto created = Executive::create(rig.config, rig.parts_with(pipeline, rig.source.get()));
    ASSERT_TRUE(created.ok());
    Executive& loop = *created.value();
    loop.start();
    ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
    const CycleRecord& last = loop.last();
    ASSERT_TRUE(last.solved);
    EXPECT_TRUE(last.refined);
    EXPECT_EQ(last.fit_disagrees, degrade);
    EXPECT_EQ(last.quality, degrade ? solver::EstimateQuality::Degraded : solver::EstimateQuality::Valid);
    EXPECT_EQ(last.publication.status, degrade ? EstimateStatus::kDegraded : EstimateStatus::kValid);
  }
}

// Verifies: REQ-LOOP-002, REQ-LOOP-003
TEST(Executive, PeriodTriggerPublishesAtTheTickAndCountsOverrunsAndSlips) {
  Rig rig(100U);
  rig.config.loop.trigger = Trigger::kPeriod;
  rig.config.loop.period_us = 10000;
  SlowOracle slow(rig.clock, rig.pipeline);
  auto created = Executive::create(rig.config, rig.parts_with(slow, rig.source.get()));
  ASSERT_TRUE(created.ok());
  Executive& loop = *created.value();
  EXPECT_TRUE(loop.publishes_first());
  loop.start();
  slow.next_ns = 500 * hal::kNsPerUs;  // within the classify budget
  for (int i = 0; i < 10; ++i) {
    ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
    // Sent exactly at the tick (simulated clock); nothing in the first cycle (boot-up).
    EXPECT_EQ(loop.last().send_offset_ns, i == 0 ? -1 : 0);
    EXPECT_FALSE(loop.last().overrun);
  }
  // The previous cycle's frame is sent: latency = one period.
  EXPECT_EQ(loop.last().latency_ns, 10 * hal::kNsPerMs);
  slow.next_ns = 25 * hal::kNsPerMs;  // 2.5 periods
  ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
  EXPECT_TRUE(loop.last().overrun);
  EXPECT_EQ(loop.stats().step_overruns[static_cast<std::size_t>(index_of(Step::kClassify))], 1U);
  slow.next_ns = 0;
  ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
  EXPECT_EQ(loop.last().slipped, 2U);
  EXPECT_EQ(loop.stats().slips, 2U);
  EXPECT_EQ(loop.stats().cycle_overruns, 1U);
  EXPECT_TRUE(rig.node.fault_active(Fault::kCycleOverrun) == false);  // reset after a good cycle
  EXPECT_EQ(rig.node.emcy_count(), 2U);                              // raised once, reset once
}

// Verifies: REQ-LOOP-015
TEST(Executive, FrameLimitAndMismatchedCameraSize) {
  Rig rig(100U);
  rig.config.loop.frames = 7U;
  rig.build(rig.source.get());
  ASSERT_EQ(rig.loop->run(nullptr), CycleOutcome::kFinished);
  EXPECT_EQ(rig.loop->stats().cycles, 7U);
  // A camera calibrated for another size than the source's frames is refused.
  auto other = solver::default_pal_camera();
  other.width = 640;
  const auto camera = solver::CameraModel::create(other);
  ASSERT_TRUE(camera.ok());
  LoopParts parts = rig.parts_with(rig.pipeline, rig.source.get());
  parts.camera = &camera.value();
  EXPECT_EQ(Executive::create(rig.config, parts).error(), LoopError::kBadConfig);
}

// Verifies: REQ-LOOP-015
TEST(Executive, StopFlagEndsTheRun) {
  Rig rig(100U);
  std::atomic<bool> stop{true};
  EXPECT_EQ(rig.loop->run(&stop), CycleOutcome::kInterrupted);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest
