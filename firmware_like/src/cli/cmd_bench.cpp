// tcpest bench: the loop's timing on a fixed dataset, printed, never asserted
// (the machine is shared: compare within one run).
//   1. throughput: the full cycle (JPEG decode, vision stages 1-4, solve,
//      CAN publish on the simulated bus) with --no-pacing over a fixed
//      rendered sequence (seed 11), per-step and total percentiles;
//      with --hd also at 1920x1080 and the HD/PAL ratio of the medians.
//   2. period jitter: the loop on the period trigger side by side with a bare
//      clock_nanosleep(TIMER_ABSTIME) loop at the same period, in alternating
//      blocks, |send - deadline| against |wake - deadline|.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/loop_rig.hpp"
#include "cli/setup.hpp"
#include "tcpest/loop/rt_setup.hpp"

namespace tcpest {
namespace cli {

namespace {

constexpr OptionSpec kOptions[] = {
    {"config", "CFG.yaml", "configuration (instrument and the rt: section apply)"},
    kCalibOption,
    {"frames", "N", "cycles of the throughput run (default 2000)"},
    {"dataset", "N", "rendered frames in the fixed dataset, replayed in a loop (default 40)"},
    {"hd", nullptr, "also time 1920x1080 frames (same scene, scaled camera) and print the HD/PAL ratio"},
    {"jitter-seconds", "S", "seconds of each side of the jitter comparison (default 20; 0 = skip)"},
    {"period-us", "P", "period of the jitter comparison (default 40000)"},
};
constexpr std::size_t kOptionCount = sizeof kOptions / sizeof kOptions[0];

solver::CameraIntrinsics hd_camera(const solver::CameraIntrinsics& pal) noexcept {
  solver::CameraIntrinsics hd = pal;
  const double sx = 1920.0 / static_cast<double>(pal.width);
  const double sy = 1080.0 / static_cast<double>(pal.height);
  hd.width = 1920;
  hd.height = 1080;
  hd.fx = pal.fx * sx;
  hd.cx = (pal.cx + 0.5) * sx - 0.5;
  hd.fy = pal.fy * sy;
  hd.cy = (pal.cy + 0.5) * sy - 0.5;
  return hd;
}

// One throughput run; returns the median total cycle time (ns), -1 on error.
std::int64_t throughput(const char* label, const RigRequest& request, const solver::CameraIntrinsics* camera,
                        std::uint32_t dataset, std::uint64_t cycles, const std::atomic<bool>* stop, int& code) {
  auto rig = std::make_unique<LoopRig>();
  code = rig->load(request);
  if (code != kExitOk) {
    return -1;
  }
  if (camera != nullptr) {
    const auto model = solver::CameraModel::create(*camera);
    if (!model.ok()) {
      code = kExitFailure;
      return -1;
    }
    rig->models.camera = model.value();
  }
  rig->config.loop.trigger = loop::Trigger::kFrame;
  rig->config.loop.pacing = false;
  rig->config.loop.frames = cycles;
  rig->config.can.start_operational = true;  // no NMT master on the bench's bus
  std::snprintf(rig->config.can.bus, sizeof rig->config.can.bus, "sim");
  loop::PrerenderOptions options;
  options.frames = dataset;
  options.seed = 11U;
  options.loop = true;
  std::printf("rendering the %s dataset (%u frames, %dx%d) ...\n", label, dataset, rig->models.camera.width(),
              rig->models.camera.height());
  static_cast<void>(std::fflush(stdout));  // progress before a long step
  auto created = loop::PrerenderedSource::create(rig->models.camera, rig->models.instrument, options);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest bench: dataset: %s\n", hal::to_string(created.error()));
    code = kExitFailure;
    return -1;
  }
  rig->sim = created.value().get();
  rig->source = std::move(created.value());
  code = rig->open_bus();
  if (code == kExitOk) {
    code = rig->build();
  }
  if (code != kExitOk) {
    return -1;
  }
  std::printf("\n== throughput, %s %dx%d: %llu cycles, --no-pacing, JPEG decode + vision + solve + CAN publish\n",
              label, rig->models.camera.width(), rig->models.camera.height(), static_cast<unsigned long long>(cycles));
  const loop::CycleOutcome outcome = rig->executive->run(stop);
  print_summary(stdout, *rig->executive);
  if (outcome == loop::CycleOutcome::kInterrupted) {
    code = kExitInterrupted;
  }
  return rig->executive->stats().total.quantile_ns(0.5);
}

void print_jitter_row(const char* label, const loop::DurationHistogram& h) {
  std::printf("%-34s %8llu %9.1f %9.1f %9.1f %9.1f\n", label, static_cast<unsigned long long>(h.count()),
              static_cast<double>(h.quantile_ns(0.5)) / 1e3, static_cast<double>(h.quantile_ns(0.99)) / 1e3,
              static_cast<double>(h.quantile_ns(0.999)) / 1e3, static_cast<double>(h.max_ns()) / 1e3);
}

int jitter(const RigRequest& request, std::int64_t period_us, double seconds, const std::atomic<bool>* stop) {
  auto rig = std::make_unique<LoopRig>();
  int code = rig->load(request);
  if (code != kExitOk) {
    return code;
  }
  rig->config.loop.trigger = loop::Trigger::kPeriod;
  rig->config.loop.period_us = period_us;
  rig->config.loop.frames = 0U;
  rig->config.can.start_operational = true;  // no NMT master on the bench's bus
  std::snprintf(rig->config.can.bus, sizeof rig->config.can.bus, "sim");
  loop::PrerenderOptions options;
  options.frames = 20U;
  options.seed = 11U;
  options.rate_hz = 1e6 / static_cast<double>(period_us);
  std::printf("\nrendering the jitter dataset (20 frames) ...\n");
  static_cast<void>(std::fflush(stdout));  // progress before a long step
  auto created = loop::PrerenderedSource::create(rig->models.camera, rig->models.instrument, options);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest bench: dataset: %s\n", hal::to_string(created.error()));
    return kExitFailure;
  }
  rig->sim = created.value().get();
  rig->source = std::move(created.value());
  code = rig->open_bus();
  if (code == kExitOk) {
    code = rig->build();
  }
  if (code != kExitOk) {
    return code;
  }
  const std::int64_t period_ns = period_us * hal::kNsPerUs;
  const auto total_periods = static_cast<std::uint64_t>(seconds * 1e9 / static_cast<double>(period_ns));
  constexpr std::uint64_t kBlock = 25U;  // alternate bare and loop blocks of 25 periods: same machine conditions
  std::printf("== period jitter at %.1f ms, %.0f s each side, alternating blocks of %llu periods\n",
              static_cast<double>(period_ns) / 1e6, seconds, static_cast<unsigned long long>(kBlock));
  static_cast<void>(std::fflush(stdout));  // progress before a long step
  auto bare = std::make_unique<loop::DurationHistogram>();
  hal::MonotonicClock clock;
  std::uint64_t done = 0U;
  bool interrupted = false;
  while (done < total_periods && !interrupted) {
    // Bare: clock_nanosleep to absolute deadlines, nothing else.
    std::int64_t deadline = clock.now_ns() + period_ns;
    for (std::uint64_t i = 0; i < kBlock; ++i) {
      if (!clock.sleep_until_ns(deadline).ok()) {
        interrupted = true;
        break;
      }
      const std::int64_t late = clock.now_ns() - deadline;
      bare->add(late < 0 ? -late : late);
      deadline += period_ns;
    }
    // The loop on its period trigger (publish at the tick).
    rig->executive->start();
    for (std::uint64_t i = 0; i < kBlock && !interrupted; ++i) {
      if (rig->executive->run_cycle() != loop::CycleOutcome::kContinue || stop->load()) {
        interrupted = true;
      }
    }
    done += kBlock;
  }
  const loop::LoopStats& s = rig->executive->stats();
  // The loop's steps: which one took the time when a cycle overran. (Not
  // its latency: a bare block pauses the loop, so the first send after it
  // carries a frame acquired a block earlier.)
  print_steps(stdout, *rig->executive);
  std::printf("%-34s %8s %9s %9s %9s %9s\n", "|actual - nominal| (us)", "n", "p50", "p99", "p99.9", "max");
  print_jitter_row("bare clock_nanosleep wake-up", *bare);
  print_jitter_row("tcpest loop CAN send (TCP frame)", s.send_offset);
  const double floor = static_cast<double>(bare->quantile_ns(0.999));
  std::printf("ratio p99.9 loop / bare: %.2f (target <= 1.2); loop overruns %llu, slips %llu, cycle p99.9 %.2f ms\n",
              floor > 0.0 ? static_cast<double>(s.send_offset.quantile_ns(0.999)) / floor : 0.0,
              static_cast<unsigned long long>(s.cycle_overruns), static_cast<unsigned long long>(s.slips),
              ms(s.total.quantile_ns(0.999)));
  return interrupted ? kExitInterrupted : kExitOk;
}

}  // namespace

int cmd_bench(int argc, char** argv) {
  auto args_owner = std::make_unique<Args>();  // large (positional table): not on the stack
  Args& args = *args_owner;
  char error[256];
  if (!args.parse(argc, argv, 1, kOptions, kOptionCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest bench: %s (see --help)\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest bench [--frames N] [--dataset N] [--hd] [--jitter-seconds S] [--period-us P]",
                "Times the loop on a fixed rendered dataset with --no-pacing (per-step and total percentiles),\n"
                "and compares the period jitter of its CAN sends with a bare clock_nanosleep loop, side by side.",
                kOptions, kOptionCount);
    return kExitOk;
  }
  if (args.positional_count() != 0U) {
    std::fprintf(stderr, "tcpest bench: unexpected argument '%s' (see --help)\n", args.positional(0));
    return kExitUsage;
  }
  unsigned long long frames = 2000U;
  unsigned long long dataset = 40U;
  unsigned long long period_us = 40000U;
  double seconds = 20.0;
  // The ranges of loop.frames and loop.period_us (docs/loop.md); a day of jitter at most.
  if (!unsigned_option(args, "bench", "frames", 1U, 1000000000000ULL, frames) ||
      !unsigned_option(args, "bench", "dataset", 1U, 10000U, dataset) ||
      !unsigned_option(args, "bench", "period-us", 1000U, 10000000U, period_us) ||
      !number_option(args, "bench", "jitter-seconds", 0.0, 86400.0, seconds)) {
    return kExitUsage;
  }
  const std::atomic<bool>* stop = install_stop_signals();
  RigRequest request;
  request.command = "bench";
  request.config_path = args.value("config");
  request.calib_path = args.value("calib");
  request.quiet = true;
  // The rt: section applies to the benchmark too (report, not fatal). A
  // CPU latency request stays in force until the command returns: both the
  // loop and the bare timer loop are measured under it.
  loop::RtReport rt;
  {
    static yaml::Document scratch;
    loop::LoopConfig config;
    if (loop::load_loop_config(request.config_path, scratch, config).ok()) {
      rt = loop::apply_rt_settings(config.rt);
      for (std::size_t i = 0; i < rt.message_count; ++i) {
        std::fprintf(stderr, "tcpest bench: %s\n", rt.messages[i]);
      }
    }
  }
  int code = kExitOk;
  const std::int64_t pal = throughput("PAL", request, nullptr, static_cast<std::uint32_t>(dataset), frames, stop, code);
  if (code != kExitOk) {
    return code;
  }
  if (args.flag("hd")) {
    static ModelSetup base;
    if (!load_model_setup("bench", request.calib_path, request.config_path, base)) {
      return kExitConfig;
    }
    const solver::CameraIntrinsics hd = hd_camera(base.camera.intrinsics());
    const std::int64_t hd_median = throughput("HD", request, &hd, static_cast<std::uint32_t>(dataset), frames, stop, code);
    if (code != kExitOk) {
      return code;
    }
    std::printf("\nmedian cycle: PAL %.3f ms, HD %.3f ms, ratio %.2f (target <= 3)\n", ms(pal), ms(hd_median),
                pal > 0 ? static_cast<double>(hd_median) / static_cast<double>(pal) : 0.0);
  }
  if (seconds > 0.0) {
    code = jitter(request, static_cast<std::int64_t>(period_us), seconds, stop);
  }
  return code;
}

}  // namespace cli
}  // namespace tcpest
