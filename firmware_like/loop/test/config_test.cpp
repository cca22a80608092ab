#include "tcpest/loop/config.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <utility>

#include "tcpest/test/mutate.hpp"

namespace tcpest {
namespace loop {
namespace {

Status<Diagnostic> parse(const char* text, LoopConfig& config) {
  static yaml::Document doc;
  const auto parsed = doc.parse(text, std::strlen(text), "test.yaml");
  if (!parsed.ok()) {
    return parsed;
  }
  return read_loop_config(doc, config);
}

// Verifies: REQ-LOOP-013
TEST(LoopConfig, DefaultsWithoutSections) {
  LoopConfig config;
  ASSERT_TRUE(parse("instrument:\n  radius_mm: 1.81\n", config).ok());
  EXPECT_EQ(config.loop.trigger, Trigger::kFrame);
  EXPECT_EQ(config.loop.period_us, 40000);
  EXPECT_STREQ(config.loop.source, "sim");
  EXPECT_EQ(config.can.node_id, 0x10U);
  EXPECT_EQ(config.can.heartbeat_ms, 100);
  EXPECT_FALSE(config.rt.lock_memory);
  EXPECT_EQ(config.rt.cpu_latency_us, -1);  // no request unless asked
}

// A configuration that sets every section (and the damage tests' valid input).
const char* const kEverySection =
    "loop:\n  trigger: period\n  period_us: 20000\n  pacing: false\n  frames: 100\n  source: /dev/video0\n"
    "  solve_mode: fixed\n  classify_step: 1\n  track_drop_after: 3\n  min_corners_valid: 8\n  max_rms_valid_px: 1.5\n"
    "  outlier_rounds: 0\n  guided_rounds: 0\n  base_rim_seed: false\n  max_valid_tcp_disagreement_mm: 3.5\n"
    "  encoder_check_lambda_mm: 4.5\n  encoder_check_bend_rad: 0\n"
    "can:\n  bus: vcan0\n  node_id: 33\n  heartbeat_ms: 50\n  start_operational: true\n"
    "rt:\n  lock_memory: true\n  fifo_priority: 80\n  cpu: 1\n  prefault_stack_kb: 512\n"
    "  cpu_latency_us: 0\n";

// Verifies: REQ-LOOP-013
TEST(LoopConfig, ReadsEverySection) {
  LoopConfig config;
  const char* text = kEverySection;
  const auto s = parse(text, config);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(config.loop.trigger, Trigger::kPeriod);
  EXPECT_EQ(config.loop.period_us, 20000);
  EXPECT_FALSE(config.loop.pacing);
  EXPECT_EQ(config.loop.frames, 100U);
  EXPECT_STREQ(config.loop.source, "/dev/video0");
  EXPECT_EQ(config.loop.estimator.solve_mode, solver::SolveMode::FixedModel);
  EXPECT_EQ(config.loop.estimator.classify_step, 1);
  EXPECT_EQ(config.loop.track_drop_after, 3);
  EXPECT_EQ(config.loop.estimator.solve.min_corners_valid, 8);
  EXPECT_DOUBLE_EQ(config.loop.estimator.solve.max_rms_valid_px, 1.5);
  EXPECT_EQ(config.loop.estimator.solve.outlier_rounds, 0);
  EXPECT_EQ(config.loop.estimator.guided.rounds, 0);
  EXPECT_FALSE(config.loop.estimator.guided.base_rim_seed);
  EXPECT_DOUBLE_EQ(config.loop.estimator.guided.max_valid_tcp_disagreement_mm, 3.5);
  EXPECT_DOUBLE_EQ(config.loop.estimator.encoder_check.lambda_tolerance_mm, 4.5);
  EXPECT_DOUBLE_EQ(config.loop.estimator.encoder_check.bend_tolerance_rad, 0.0);
  EXPECT_STREQ(config.can.bus, "vcan0");
  EXPECT_EQ(config.can.node_id, 33U);
  EXPECT_TRUE(config.can.start_operational);
  EXPECT_TRUE(config.rt.lock_memory);
  EXPECT_EQ(config.rt.fifo_priority, 80);
  EXPECT_EQ(config.rt.cpu, 1);
  EXPECT_EQ(config.rt.prefault_stack_kb, 512);
  EXPECT_EQ(config.rt.cpu_latency_us, 0);
}

// Verifies: REQ-LOOP-013
TEST(LoopConfig, UnknownKeysAndBadValuesNameTheLine) {
  LoopConfig config;
  auto s = parse("loop:\n  trigger: frame\n  peroid_us: 100\n", config);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().line, 3U);
  s = parse("can:\n  node_id: 300\n", config);
  ASSERT_FALSE(s.ok());
  EXPECT_STREQ(s.error().field, "can.node_id");
  s = parse("loop:\n  trigger: sometimes\n", config);
  ASSERT_FALSE(s.ok());
  s = parse("rt:\n  lock_memory: maybe\n", config);
  ASSERT_FALSE(s.ok());
  // Out-of-range values name their field.
  const struct {
    const char* text;
    const char* field;
  } bad[] = {
      {"loop:\n  classify_step: 3\n", "loop.classify_step"},
      {"loop:\n  guided_rounds: 5\n", "loop.guided_rounds"},
      {"loop:\n  encoder_check_bend_rad: -0.1\n", "loop.encoder_check_bend_rad"},
      {"loop:\n  encoder_check_lambda_mm: nan\n", "loop.encoder_check_lambda_mm"},
      {"loop:\n  max_valid_tcp_disagreement_mm: -1\n", "loop.max_valid_tcp_disagreement_mm"},
      {"rt:\n  cpu_latency_us: -2\n", "rt.cpu_latency_us"},
      {"rt:\n  cpu_latency_us: 2000000\n", "rt.cpu_latency_us"},
  };
  for (const auto& b : bad) {
    s = parse(b.text, config);
    ASSERT_FALSE(s.ok()) << b.text;
    EXPECT_STREQ(s.error().field, b.field);
  }
  ASSERT_TRUE(parse("loop:\n  classify_step: auto\n", config).ok());
  EXPECT_EQ(config.loop.estimator.classify_step, 0);
}

// config/deploy.yaml, the deployment example the package ships: it loads,
// it lists every key of the three sections, and each key not marked
// "deployed" there holds its default.
TEST(LoopConfig, DeploymentExampleLoadsWithTheDefaultsItClaims) {
  const std::string path = std::string(TCPEST_TEST_DATA_DIR) + "/../../config/deploy.yaml";
  static yaml::Document doc;
  LoopConfig config;
  const auto loaded = load_loop_config(path.c_str(), doc, config);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const char* const every_key[] = {
      "loop.trigger", "loop.period_us", "loop.pacing", "loop.frames", "loop.source", "loop.replay_loop",
      "loop.v4l2_format", "loop.solve_mode", "loop.classify_step", "loop.track_drop_after",
      "loop.min_corners_valid", "loop.max_rms_valid_px", "loop.encoder_check_lambda_mm",
      "loop.encoder_check_bend_rad", "loop.outlier_rounds", "loop.guided_rounds", "loop.base_rim_seed",
      "loop.max_valid_tcp_disagreement_mm", "loop.camera_timeout_ms", "loop.camera_lost_after", "loop.retry_ms",
      "loop.status_period_ms", "can.bus", "can.node_id", "can.heartbeat_ms", "can.prior_timeout_ms",
      "can.prior_max_counter_gap", "can.start_operational", "can.sync_timeout_ms", "rt.lock_memory", "rt.fifo_priority",
      "rt.cpu", "rt.prefault_stack_kb", "rt.cpu_latency_us"};
  for (const char* key : every_key) {
    EXPECT_TRUE(doc.has(key)) << key;
  }
  // Deployed: a V4L2 camera, SocketCAN, the loop alone on an isolated core.
  EXPECT_STREQ(config.loop.source, "/dev/video0");
  EXPECT_STREQ(config.can.bus, "can0");
  EXPECT_TRUE(config.rt.lock_memory);
  EXPECT_EQ(config.rt.fifo_priority, 80);
  EXPECT_EQ(config.rt.cpu, 3);
  EXPECT_EQ(config.rt.cpu_latency_us, 0);
  // Everything else: the defaults.
  const LoopConfig d;
  const LoopSettings& l = config.loop;
  EXPECT_EQ(l.trigger, d.loop.trigger);
  EXPECT_EQ(l.period_us, d.loop.period_us);
  EXPECT_EQ(l.pacing, d.loop.pacing);
  EXPECT_EQ(l.frames, d.loop.frames);
  EXPECT_EQ(l.replay_loop, d.loop.replay_loop);
  EXPECT_STREQ(l.v4l2_format, d.loop.v4l2_format);
  EXPECT_EQ(l.track_drop_after, d.loop.track_drop_after);
  EXPECT_EQ(l.camera_timeout_ms, d.loop.camera_timeout_ms);
  EXPECT_EQ(l.camera_lost_after, d.loop.camera_lost_after);
  EXPECT_EQ(l.retry_ms, d.loop.retry_ms);
  EXPECT_EQ(l.status_period_ms, d.loop.status_period_ms);
  const vision::EstimatorConfig& e = l.estimator;
  const vision::EstimatorConfig& de = d.loop.estimator;
  EXPECT_EQ(e.solve_mode, de.solve_mode);
  EXPECT_EQ(e.classify_step, de.classify_step);
  EXPECT_EQ(e.solve.min_corners_valid, de.solve.min_corners_valid);
  EXPECT_EQ(e.solve.max_rms_valid_px, de.solve.max_rms_valid_px);
  EXPECT_EQ(e.solve.outlier_rounds, de.solve.outlier_rounds);
  EXPECT_EQ(e.encoder_check.lambda_tolerance_mm, de.encoder_check.lambda_tolerance_mm);
  EXPECT_EQ(e.encoder_check.bend_tolerance_rad, de.encoder_check.bend_tolerance_rad);
  EXPECT_EQ(e.guided.rounds, de.guided.rounds);
  EXPECT_EQ(e.guided.base_rim_seed, de.guided.base_rim_seed);
  EXPECT_EQ(e.guided.max_valid_tcp_disagreement_mm, de.guided.max_valid_tcp_disagreement_mm);
  const CanSettings& c = config.can;
  EXPECT_EQ(c.node_id, d.can.node_id);
  EXPECT_EQ(c.heartbeat_ms, d.can.heartbeat_ms);
  EXPECT_EQ(c.prior_timeout_ms, d.can.prior_timeout_ms);
  EXPECT_EQ(c.prior_max_counter_gap, d.can.prior_max_counter_gap);
  EXPECT_EQ(c.start_operational, d.can.start_operational);
  EXPECT_EQ(c.sync_timeout_ms, d.can.sync_timeout_ms);
  EXPECT_EQ(config.rt.prefault_stack_kb, d.rt.prefault_stack_kb);
}

// The keys of estimation steps that were removed (docs/decisions/0053) are
// unknown keys now: a file that still names one is refused, naming it.
TEST(LoopConfig, TheRemovedEstimationStepsKeysAreUnknownKeys) {
  LoopConfig config;
  const char* const removed[] = {"fallback_seeds", "shaft_recheck", "alias_check", "valid_start_check"};
  for (const char* key : removed) {
    const std::string text = std::string("loop:\n  ") + key + ": 1\n";
    const auto s = parse(text.c_str(), config);
    ASSERT_FALSE(s.ok()) << key;
    EXPECT_EQ(std::string(s.error().field), std::string("loop.") + key);
    EXPECT_NE(std::strstr(s.error().message, "unknown key"), nullptr) << key;
  }
}

}  // namespace
}  // namespace loop
}  // namespace tcpest

#include "tcpest/loop/rt_setup.hpp"

namespace tcpest {
namespace loop {
namespace {

// Seeded damage to a configuration with every section: refused with the
// line or field named, or read. Never a crash or an overrun.
// Verifies: REQ-LOOP-013
TEST(LoopConfig, DamagedFilesAreRefusedWithAPlace) {
  const std::string valid = kEverySection;
  test::Mutator mutator(13U);
  static yaml::Document doc;
  int refused = 0;
  for (int i = 0; i < 20000; ++i) {
    const std::string text = mutator.damage(valid);
    LoopConfig config;
    const auto parsed = doc.parse(text.data(), text.size(), "damaged.yaml");
    const auto read = parsed.ok() ? read_loop_config(doc, config) : parsed;
    if (!read.ok()) {
      EXPECT_TRUE(read.error().line > 0U || read.error().field[0] != '\0') << text;
      EXPECT_NE(read.error().message[0], '\0') << text;
      ++refused;
      continue;
    }
    EXPECT_GT(config.loop.period_us, 0) << text;
    EXPECT_GE(config.rt.cpu_latency_us, -1) << text;
  }
  EXPECT_GT(refused, 2000);
  EXPECT_GT(20000 - refused, 400);
}

// Verifies: REQ-LOOP-014
TEST(RtSetup, FailuresAreReportedNotFatal) {
  RtSettings settings;
  settings.cpu = 1023;           // no such CPU here
  settings.prefault_stack_kb = 64;
  const RtReport report = apply_rt_settings(settings);
  EXPECT_FALSE(report.pinned);
  EXPECT_TRUE(report.stack_prefaulted);
  ASSERT_EQ(report.message_count, 1U);
  EXPECT_NE(std::strstr(report.messages[0], "rt.cpu"), nullptr);
  const RtReport nothing = apply_rt_settings(RtSettings{0 != 0, 0, -1, 0});
  EXPECT_EQ(nothing.message_count, 0U);
  EXPECT_FALSE(nothing.cpu_latency.held());
}

// Reads the kernel's aggregate CPU latency request (us), -1 if unreadable.
std::int32_t current_cpu_latency_us() {
  const int fd = ::open("/dev/cpu_dma_latency", O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    return -1;
  }
  std::int32_t value = -1;
  const ssize_t got = ::read(fd, &value, sizeof value);
  static_cast<void>(::close(fd));  // read-only probe
  return got == static_cast<ssize_t>(sizeof value) ? value : -1;
}

// Verifies: REQ-LOOP-014
TEST(RtSetup, CpuLatencyIsHeldUntilReleasedOrReported) {
  const std::int32_t before_us = current_cpu_latency_us();
  RtSettings settings{0 != 0, 0, -1, 0};
  settings.cpu_latency_us = 0;
  RtReport report = apply_rt_settings(settings);
  if (!report.cpu_latency.held()) {
    // No device or no privilege here: reported once, not fatal.
    ASSERT_EQ(report.message_count, 1U);
    EXPECT_NE(std::strstr(report.messages[0], "rt.cpu_latency_us"), nullptr);
    return;
  }
  EXPECT_EQ(report.message_count, 0U);
  EXPECT_EQ(current_cpu_latency_us(), 0);  // the request is in force while held
  report.cpu_latency.release();
  EXPECT_FALSE(report.cpu_latency.held());
  EXPECT_EQ(current_cpu_latency_us(), before_us);  // withdrawn: back to what it was
  report.cpu_latency.release();                    // a second release is harmless
  // One owner: a moved report carries the request, and its end withdraws it.
  {
    RtReport first = apply_rt_settings(settings);
    ASSERT_TRUE(first.cpu_latency.held());
    const RtReport second = std::move(first);
    EXPECT_FALSE(first.cpu_latency.held());  // NOLINT(bugprone-use-after-move): the moved-from state is the point
    EXPECT_TRUE(second.cpu_latency.held());
    EXPECT_EQ(current_cpu_latency_us(), 0);
  }
  EXPECT_EQ(current_cpu_latency_us(), before_us);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest
