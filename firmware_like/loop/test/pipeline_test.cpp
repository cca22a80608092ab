// The loop with the real units: rendered frames, vision, solver, the CAN node
// on the simulated bus.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "tcpest/can_iface/messages.hpp"
#include "tcpest/hal/camera/file_sources.hpp"
#include "tcpest/hal/can/sim_bus.hpp"
#include "tcpest/loop/can_node_port.hpp"
#include "tcpest/loop/executive.hpp"
#include "tcpest/loop/motion.hpp"
#include "oracle_pipeline.hpp"
#include "tcpest/loop/rendered_scene.hpp"
#include "tcpest/loop/vision_pipeline.hpp"
#include "tcpest/test/alloc_counter.hpp"
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace loop {
namespace {

struct Models {
  solver::CameraModel camera;
  solver::InstrumentModel model;
  Models() {
    const auto c = solver::CameraModel::create(solver::default_pal_camera());
    const auto m = solver::InstrumentModel::create(solver::InstrumentGeometry{});
    EXPECT_TRUE(c.ok() && m.ok());
    camera = c.value();
    model = m.value();
  }
};

struct Run {
  std::vector<can::Frame> frames;  // everything the estimator sent, in order
  LoopStats stats;
  double max_tcp_error_mm = 0.0;
};

// One run over `frames` rendered frames; the "robot" endpoint records the traffic.
std::unique_ptr<Run> run_rendered(const Models& m, std::uint32_t frames) {
  auto out = std::make_unique<Run>();
  auto scene = RenderedScene::create(m.camera, m.model, 7U, 25.0, frames);
  EXPECT_TRUE(scene.ok());
  hal::SimCamera source(*scene.value(), 25.0, false);
  auto pipeline = VisionPipeline::create(m.camera, m.model, vision::default_color_model());
  EXPECT_TRUE(pipeline.ok());
  hal::SimulatedClock clock(5 * hal::kNsPerS);
  auto bus = std::make_unique<hal::SimBus>();
  LoopConfig config;
  config.can.start_operational = true;  // no NMT master on this simulated bus
  CanNodePort node(clock, bus->endpoint(0), bus.get(), nullptr, "sim0");
  EXPECT_TRUE(node.configure(node_config(config)).ok());
  LoopParts parts{&source, &clock, pipeline.value().get(), &node, &m.camera, &m.model};
  auto loop = Executive::create(config, parts);
  EXPECT_TRUE(loop.ok());
  loop.value()->start();
  std::array<hal::ReceivedFrame, 64> rx{};
  while (loop.value()->run_cycle() == CycleOutcome::kContinue) {
    const auto got = bus->endpoint(1).receive(rx.data(), rx.size());
    EXPECT_TRUE(got.ok());
    for (std::size_t i = 0; i < got.value(); ++i) {
      out->frames.push_back(rx[i].frame);
    }
    const CycleRecord& r = loop.value()->last();
    const hal::FrameTruth& truth = source.last_truth();  // beside the loop
    if (r.solved && r.have_frame && truth.valid) {
      const double e = std::sqrt(std::pow(r.publication.tcp_mm[0] - truth.tcp_mm[0], 2) +
                                 std::pow(r.publication.tcp_mm[1] - truth.tcp_mm[1], 2) +
                                 std::pow(r.publication.tcp_mm[2] - truth.tcp_mm[2], 2));
      out->max_tcp_error_mm = std::max(out->max_tcp_error_mm, e);
    }
  }
  out->stats = loop.value()->stats();
  return out;
}

// The loop's start-up, its vision pipeline and its executive, with memory
// running out at each of their allocations in turn: an out-of-memory error
// from the part that ran out, everything taken before freed.
// Verifies: REQ-ERR-007
TEST(LoopWithUnits, StartUpReportsOutOfMemoryAtAnyOfItsAllocations) {
  if (!test::malloc_hook_active()) {
    GTEST_SKIP() << "malloc belongs to the sanitizer's runtime in this build";
  }
  const Models m;
  auto scene = RenderedScene::create(m.camera, m.model, 7U, 25.0, 2U);
  ASSERT_TRUE(scene.ok());
  hal::SimCamera source(*scene.value(), 25.0, false);
  hal::SimulatedClock clock(5 * hal::kNsPerS);
  hal::SimBus bus;
  const LoopConfig config;
  CanNodePort node(clock, bus.endpoint(0), &bus, nullptr, "sim0");
  ASSERT_TRUE(node.configure(node_config(config)).ok());
  bool pipeline_out_of_memory = false;
  bool loop_out_of_memory = false;
  const auto start_up = [&]() {
    pipeline_out_of_memory = false;
    loop_out_of_memory = false;
    const auto pipeline = VisionPipeline::create(m.camera, m.model, vision::default_color_model());
    if (!pipeline.ok()) {
      pipeline_out_of_memory = pipeline.error() == vision::VisionError::OutOfMemory;
      return false;
    }
    const LoopParts parts{&source, &clock, pipeline.value().get(), &node, &m.camera, &m.model};
    const auto loop = Executive::create(config, parts);
    loop_out_of_memory = !loop.ok() && loop.error() == LoopError::kOutOfMemory;
    return loop.ok();  // both released here: only the count matters
  };
  const std::size_t allocations = test::run_out_of_memory_at_each_allocation(start_up, [&](const test::OutOfMemoryOutcome& o) {
    ASSERT_FALSE(o.succeeded) << "allocation " << o.nth;
    EXPECT_TRUE(pipeline_out_of_memory || loop_out_of_memory) << "allocation " << o.nth;
    EXPECT_EQ(o.leaked, 0U) << "out of memory at allocation " << o.nth;
  });
  EXPECT_GE(allocations, 14U);
}

// Verifies: REQ-LOOP-001
TEST(LoopWithUnits, RenderedSequenceThroughVisionSolverAndCan) {
  Models m;
  const auto run = run_rendered(m, 40U);
  EXPECT_EQ(run->stats.frames, 40U);
  // How many frames give an estimate, and how good it is, is the vision
  // unit's business (tcpest evaluate, tcpest demo); here: every frame went
  // through all the steps and out on the bus.
  std::printf("estimates: %llu valid, %llu degraded of 40; max TCP error %.2f mm\n",
              static_cast<unsigned long long>(run->stats.status[0]),
              static_cast<unsigned long long>(run->stats.status[1]), run->max_tcp_error_mm);
  // Boot-up, then per frame TCP, JOINTS, MECHANICAL, QUALITY, and heartbeats.
  int tcp = 0;
  int quality = 0;
  int heartbeat = 0;
  for (const can::Frame& f : run->frames) {
    tcp += f.id == can::tcp_id(0x10U) ? 1 : 0;
    quality += f.id == can::quality_id(0x10U) ? 1 : 0;
    heartbeat += f.id == can::heartbeat_id(0x10U) ? 1 : 0;
  }
  EXPECT_EQ(tcp, 40);
  EXPECT_EQ(quality, 40);
  EXPECT_GE(heartbeat, 15);  // 1.6 s at 100 ms (plus boot-up)
  // Every TCP frame passes its E2E check.
  for (const can::Frame& f : run->frames) {
    if (f.id == can::tcp_id(0x10U)) {
      EXPECT_TRUE(can::decode_tcp(0x10U, f).ok());
    }
  }
}

// Verifies: REQ-LOOP-005
TEST(LoopWithUnits, TwoRunsOnTheSameInputGiveBitIdenticalCanPayloads) {
  Models m;
  const auto a = run_rendered(m, 25U);
  const auto b = run_rendered(m, 25U);
  ASSERT_EQ(a->frames.size(), b->frames.size());
  ASSERT_GT(a->frames.size(), 100U);
  for (std::size_t i = 0; i < a->frames.size(); ++i) {
    EXPECT_TRUE(a->frames[i] == b->frames[i]) << "frame " << i;
  }
}

// Verifies: REQ-LOOP-006
TEST(LoopWithUnits, NoHeapAllocationPerCycleWithVisionOnRawFrames) {
  Models m;
  // A few rendered PAL frames as raw video, replayed in a loop.
  std::string dir = std::string(::testing::TempDir()) + "tcpest_loop_vis_XXXXXX";
  ASSERT_NE(::mkdtemp(&dir[0]), nullptr);
  const std::string path = dir + "/rendered.y4m";
  {
    auto scene = RenderedScene::create(m.camera, m.model, 3U, 25.0, 0U);
    ASSERT_TRUE(scene.ok());
    std::vector<std::uint8_t> rgb(720U * 576U * 3U);
    const MutableImageView view{rgb.data(), 720, 576, 720U * 3U};
    hal::Y4mWriter writer;
    ASSERT_TRUE(writer.open(path.c_str(), 720, 576, 25, 1).ok());
    for (std::uint32_t i = 0; i < 6U; ++i) {
      hal::FrameTruth truth;
      ASSERT_TRUE(scene.value()->render(i * 10U, view, truth).ok());
      ASSERT_TRUE(writer.write(view.view()).ok());
    }
    ASSERT_TRUE(writer.close().ok());
  }
  hal::ReplayOptions options;
  options.loop = true;
  auto source = hal::Y4mSource::open(path.c_str(), options);
  ASSERT_TRUE(source.ok());
  auto pipeline = VisionPipeline::create(m.camera, m.model, vision::default_color_model());
  ASSERT_TRUE(pipeline.ok());
  hal::SimulatedClock clock(hal::kNsPerS);
  auto bus = std::make_unique<hal::SimBus>();
  LoopConfig config;
  config.can.start_operational = true;  // no NMT master on this simulated bus
  CanNodePort node(clock, bus->endpoint(0), bus.get(), nullptr, "sim0");
  ASSERT_TRUE(node.configure(node_config(config)).ok());
  LoopParts parts{source.value().get(), &clock, pipeline.value().get(), &node, &m.camera, &m.model};
  auto loop = Executive::create(config, parts);
  ASSERT_TRUE(loop.ok());
  loop.value()->start();
  std::array<hal::ReceivedFrame, 64> rx{};
  for (int i = 0; i < 20; ++i) {
    ASSERT_EQ(loop.value()->run_cycle(), CycleOutcome::kContinue);
    static_cast<void>(bus->endpoint(1).receive(rx.data(), rx.size()));
  }
  test::AllocationScope scope;
  for (int i = 0; i < 2000; ++i) {
    ASSERT_EQ(loop.value()->run_cycle(), CycleOutcome::kContinue);
    static_cast<void>(bus->endpoint(1).receive(rx.data(), rx.size()));  // keep the robot's queue from overflowing
  }
  EXPECT_EQ(scope.count(), 0U);
  const LoopStats& s = loop.value()->stats();
  EXPECT_EQ(s.frames, 2020U);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest

namespace tcpest {
namespace loop {
namespace {

// The SYNC trigger: the PDOs follow each SYNC and carry the latest finished
// cycle's estimate; without SYNC nothing is published.
// Verifies: REQ-LOOP-004
TEST(LoopWithUnits, SyncTriggerAnswersEachSyncWithTheLatestEstimate) {
  Models m;
  MotionSequence motion;
  motion.frames = 100U;
  ModelScene scene(m.camera, m.model, motion);
  hal::SimCamera source(scene, 25.0, false);
  OraclePipeline pipeline(m.camera, m.model);
  pipeline.set_truth_source(&source);
  hal::SimulatedClock clock(hal::kNsPerS);
  auto bus = std::make_unique<hal::SimBus>();
  LoopConfig config;
  config.can.start_operational = true;  // no NMT master on this simulated bus
  config.loop.trigger = Trigger::kSync;
  CanNodePort node(clock, bus->endpoint(0), bus.get(), nullptr, "sim0");
  ASSERT_TRUE(node.configure(node_config(config)).ok());
  LoopParts parts{&source, &clock, &pipeline, &node, &m.camera, &m.model};
  auto created = Executive::create(config, parts);
  ASSERT_TRUE(created.ok());
  Executive& loop = *created.value();
  EXPECT_TRUE(loop.publishes_first());
  loop.start();
  can::Frame sync;
  ASSERT_TRUE(can::encode_sync(sync).ok());
  std::array<hal::ReceivedFrame, 64> rx{};
  int tcp_frames = 0;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(bus->endpoint(1).send(sync).ok());
    ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
    const auto got = bus->endpoint(1).receive(rx.data(), rx.size());
    ASSERT_TRUE(got.ok());
    for (std::size_t k = 0; k < got.value(); ++k) {
      if (rx[k].frame.id == can::tcp_id(0x10U)) {
        ++tcp_frames;
        const auto tcp = can::decode_tcp(0x10U, rx[k].frame);
        ASSERT_TRUE(tcp.ok());
        if (i >= 2) {
          // The previous cycle's estimate (the oracle's is exact).
          const auto r = motion.pose(m.model.geometry(), static_cast<std::uint32_t>(i - 1));
          EXPECT_NEAR(tcp.value().x_mm, m.model.tcp(r).x(), 0.01);
          EXPECT_EQ(tcp.value().status, can::EstimateStatus::kValid);
        }
      }
    }
  }
  EXPECT_EQ(tcp_frames, 9);  // the first SYNC comes before the node is operational (boot-up)
  // No SYNC: the cycle times out (sync_timeout_ms) and publishes nothing.
  ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
  const auto got = bus->endpoint(1).receive(rx.data(), rx.size());
  ASSERT_TRUE(got.ok());
  for (std::size_t k = 0; k < got.value(); ++k) {
    EXPECT_NE(rx[k].frame.id, can::tcp_id(0x10U));
  }
  EXPECT_EQ(loop.last().latency_ns, -1);
}

// Verifies: REQ-LOOP-002, REQ-LOOP-003
TEST(LoopWithUnits, PeriodTriggerSendsTheTcpFrameFirstAtTheTickEvenAfterAnOverrun) {
  // The cycle-overrun EMCY is decided at the end of its cycle: it goes out
  // then, not at the next tick ahead of the TCP frame (which it would delay).
  Models m;
  MotionSequence motion;
  motion.frames = 100U;
  ModelScene scene(m.camera, m.model, motion);
  hal::SimCamera source(scene, 25.0, false);
  OraclePipeline oracle(m.camera, m.model);
  oracle.set_truth_source(&source);
  hal::SimulatedClock clock(hal::kNsPerS);
  SlowOracle slow(clock, oracle);
  auto bus = std::make_unique<hal::SimBus>();
  LoopConfig config;
  config.can.start_operational = true;  // no NMT master on this simulated bus
  config.loop.trigger = Trigger::kPeriod;
  config.loop.period_us = 40000;
  CanNodePort node(clock, bus->endpoint(0), bus.get(), nullptr, "sim0");
  ASSERT_TRUE(node.configure(node_config(config)).ok());
  LoopParts parts{&source, &clock, &slow, &node, &m.camera, &m.model};
  auto created = Executive::create(config, parts);
  ASSERT_TRUE(created.ok());
  Executive& loop = *created.value();
  loop.start();
  std::array<hal::ReceivedFrame, 64> rx{};
  int tcp_frames = 0;
  int emcy_frames = 0;
  for (int i = 0; i < 20; ++i) {
    // Runs of two overrunning cycles (over the cycle budget) start and end.
    slow.next_ns = (i % 4 == 1 || i % 4 == 2) ? (cycle_budget_us() + 2000) * hal::kNsPerUs : 0;
    ASSERT_EQ(loop.run_cycle(), CycleOutcome::kContinue);
    EXPECT_EQ(loop.last().overrun, i % 4 == 1 || i % 4 == 2);
    // This cycle's traffic, in order: the tick's PDOs first, then whatever the cycle raised.
    const auto got = bus->endpoint(1).receive(rx.data(), rx.size());
    ASSERT_TRUE(got.ok());
    bool tcp_seen = false;
    for (std::size_t k = 0; k < got.value(); ++k) {
      const std::uint32_t id = rx[k].frame.id;
      if (id == can::tcp_id(0x10U)) {
        ++tcp_frames;
        tcp_seen = true;
        EXPECT_EQ(k, 0U) << "cycle " << i << ": the TCP frame is not the first frame of the tick";
      } else if (id == can::emcy_id(0x10U)) {
        ++emcy_frames;
        EXPECT_TRUE(tcp_seen || i == 0) << "cycle " << i << ": an EMCY went out before the TCP frame";
      }
    }
  }
  EXPECT_EQ(tcp_frames, 19);   // none in the first cycle (boot-up)
  EXPECT_EQ(emcy_frames, 10);  // five runs of overruns: raised and reset each
  EXPECT_EQ(loop.stats().slips, 0U);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest
