// tcpest bench: the loop's timing on a fixed dataset, printed, never asserted
// (the machine is shared: compare within one run).
//   1. throughput: the full cycle (JPEG decode, vision stages 1-4, solve,
//      CAN publish on the simulated bus) with --no-pacing over a fixed
//      rendered sequence (seed 11), per-step and total percentiles;
//      with --hd also at 1920x1080 and the HD/PAL ratio of the medians.
//   2. period jitter: the loop on the period trigger side by side with a bare
//      clock_nanosleep(TIMER_ABSTIME) loop at the same period, in alternating
//      blocks, |send - deadline| against |wake - deadline|.
// With --soak N, instead of both: N cycles of the throughput run's loop after
// a warm-up pass, checked (exit 1 when a check fails): no heap allocation, no
// growth of the heap, no doubling of the CPU time per cycle, and the same TCP
// and JOINTS payloads on every pass over the dataset.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>
#include <new>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/heap_probe.hpp"
#include "cli/loop_rig.hpp"
#include "cli/setup.hpp"
#include "tcpest/can_iface/messages.hpp"
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
    {"soak", "N", "instead of the two parts above: N cycles (1..10^9) checked for heap allocations, leaks, "
                  "cycle-time drift and payload determinism"},
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

// The loop as the throughput run and the soak run it: the configuration
// `tcpest run` uses, with the frame trigger, --no-pacing, the simulated bus
// (no NMT master: operational from the start), on the fixed rendered dataset
// (seed 11) replayed in a loop. `cycles` 0: until the caller stops. Null on
// error, with `code` set.
std::unique_ptr<LoopRig> bench_rig(const char* label, const RigRequest& request,
                                   const solver::CameraIntrinsics* camera, std::uint32_t dataset,
                                   std::uint64_t cycles, int& code) {
  auto rig = std::make_unique<LoopRig>();
  code = rig->load(request);
  if (code != kExitOk) {
    return nullptr;
  }
  if (camera != nullptr) {
    const auto model = solver::CameraModel::create(*camera);
    if (!model.ok()) {
      code = kExitFailure;
      return nullptr;
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
    return nullptr;
  }
  rig->sim = created.value().get();
  rig->source = std::move(created.value());
  code = rig->open_bus();
  if (code == kExitOk) {
    code = rig->build();
  }
  if (code != kExitOk) {
    return nullptr;
  }
  return rig;
}

// One throughput run; returns the median total cycle time (ns), -1 on error.
std::int64_t throughput(const char* label, const RigRequest& request, const solver::CameraIntrinsics* camera,
                        std::uint32_t dataset, std::uint64_t cycles, const std::atomic<bool>* stop, int& code) {
  const std::unique_ptr<LoopRig> rig = bench_rig(label, request, camera, dataset, cycles, code);
  if (!rig) {
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

// ---- The soak ---------------------------------------------------------------

// The drift check compares the CPU time per cycle of the first and the last
// tenth: a neighbour on a shared machine stretches the wall-clock cycle
// times (reported beside it) but hardly the CPU time the loop itself uses.
// It may double before the check fails; a real drift (a growing queue, a
// histogram scanned from its start) grows past that.
constexpr double kMaxCpuDrift = 2.0;

// CPU time of this process (the soak runs one thread), in seconds.
double process_cpu_s() noexcept {
  timespec t{};
  if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t) != 0) {
    return 0.0;
  }
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// FNV-1a of the TCP and JOINTS frames one cycle sent, without the E2E alive
// counter (byte 6, low nibble) and CRC (byte 7): they change every frame by
// design. The status nibble (byte 6, high) is part of the data.
std::uint64_t hash_frame(std::uint64_t h, const can::Frame& frame) noexcept {
  auto mix = [&h](std::uint32_t byte) noexcept {
    h ^= byte & 0xFFU;
    h *= 1099511628211ULL;
  };
  mix(frame.id);
  mix(frame.id >> 8U);
  mix(frame.length);
  for (std::size_t i = 0U; i < frame.length && i < 6U; ++i) {
    mix(frame.data[i]);
  }
  if (frame.length > 6U) {
    mix(frame.data[6] & 0xF0U);
  }
  return h;
}

constexpr std::uint64_t kFnvOffset = 14695981039346656037ULL;

struct SoakCycle {
  bool ran = false;  // a cycle with a frame
  std::uint64_t sequence = 0U;
  std::uint64_t payload_hash = kFnvOffset;
  std::int64_t total_ns = 0;
};

// One cycle, and what the controllers' side of the bus received from it.
// A cycle whose frame starts a pass over the dataset starts a new sequence:
// the temporal prior carries a pass's last pose into the next pass, and the
// solve depends on its prior below the wire's resolution, so that without
// the reset a pass is never exactly periodic (measured: on the 40-frame
// dataset frames 32-33 of 13 passes in 500 differed from pass 2, by up to
// 0.03 mm and 0.04 rad, the same passes in every run). With it every pass is
// the same computation on the same frames: any difference is state that
// leaked or memory that changed.
SoakCycle soak_cycle(loop::Executive& executive, hal::SimEndpoint& listener, std::uint64_t next_sequence,
                     std::uint32_t dataset) noexcept {
  SoakCycle c;
  if (next_sequence % dataset == 0U) {
    executive.reset_sequence();
  }
  const loop::CycleOutcome outcome = executive.run_cycle();
  const loop::CycleRecord& r = executive.last();
  c.ran = outcome == loop::CycleOutcome::kContinue && r.have_frame;
  c.sequence = r.frame_sequence;
  c.total_ns = r.total_ns;
  hal::ReceivedFrame batch[8];
  for (;;) {  // bounded: the cycle sent a few frames, the queue holds 256
    const auto received = listener.receive(batch, sizeof batch / sizeof batch[0]);
    if (!received.ok() || received.value() == 0U) {
      break;
    }
    for (std::size_t i = 0U; i < received.value(); ++i) {
      c.payload_hash = hash_frame(c.payload_hash, batch[i].frame);
    }
  }
  return c;
}

struct SoakTally {
  std::uint64_t cycles = 0U;            // soak cycles run (the warm-up not included)
  std::uint64_t frameless = 0U;         // cycles without a frame (the replay never lacks one)
  std::uint64_t allocations = 0U;
  std::uint64_t last_pass = 0U;         // 0-based pass of the last cycle (0: the warm-up)
  bool last_pass_partial = false;
  std::uint64_t mismatches = 0U;        // frames whose payloads differ from the reference pass's (the second)
  std::uint64_t first_mismatch_pass = 0U;
  std::uint64_t first_mismatch_frame = 0U;
  double first_tenth_cpu_s = 0.0;       // CPU time of the first tenth of the cycles
  double last_tenth_cpu_s = 0.0;        // and of the last
};

// The soak's cycles: `tally` and the two tenths' histograms filled, the
// allocations counted with `probe` (may be null). False when stopped.
bool soak_cycles(loop::Executive& executive, hal::SimEndpoint& listener, const HeapProbe* probe,
                 std::uint32_t dataset, std::uint64_t cycles, std::uint64_t* reference,
                 loop::DurationHistogram& first_tenth, loop::DurationHistogram& last_tenth, SoakTally& tally,
                 const std::atomic<bool>* stop) noexcept {
  const std::uint64_t tenth = cycles >= 10U ? cycles / 10U : 1U;
  const bool progress = cycles >= 100000U;  // a long run says where it is, every tenth, on stderr
  if (probe != nullptr) {
    probe->arm();
  }
  bool stopped = false;
  std::uint64_t next_sequence = dataset;  // the warm-up took the first pass
  double cpu_s = process_cpu_s();
  for (std::uint64_t j = 0U; j < cycles; ++j) {
    if (stop->load(std::memory_order_relaxed)) {
      stopped = true;
      break;
    }
    if (j == tenth) {
      tally.first_tenth_cpu_s = process_cpu_s() - cpu_s;
    }
    if (j == cycles - tenth) {
      cpu_s = process_cpu_s();
    }
    if (progress && j > 0U && j % tenth == 0U) {
      // The print is not part of a cycle: not counted.
      tally.allocations += probe != nullptr ? probe->disarm() : 0U;
      std::fprintf(stderr, "tcpest bench: soak %llu/%llu cycles\n", static_cast<unsigned long long>(j),
                   static_cast<unsigned long long>(cycles));
      if (probe != nullptr) {
        probe->arm();
      }
    }
    const SoakCycle c = soak_cycle(executive, listener, next_sequence, dataset);
    ++tally.cycles;
    if (!c.ran) {
      ++tally.frameless;
      continue;
    }
    next_sequence = c.sequence + 1U;
    const std::uint64_t pass = c.sequence / dataset;
    const std::uint64_t frame = c.sequence % dataset;
    tally.last_pass = pass;
    tally.last_pass_partial = frame + 1U < dataset;
    if (pass == 1U) {
      reference[frame] = c.payload_hash;
    } else if (pass > 1U && c.payload_hash != reference[frame]) {
      if (tally.mismatches == 0U) {
        tally.first_mismatch_pass = pass;
        tally.first_mismatch_frame = frame;
      }
      ++tally.mismatches;
    }
    if (j < tenth) {
      first_tenth.add(c.total_ns);
    }
    if (j >= cycles - tenth) {
      last_tenth.add(c.total_ns);
    }
  }
  tally.allocations += probe != nullptr ? probe->disarm() : 0U;
  if (!stopped) {
    tally.last_tenth_cpu_s = process_cpu_s() - cpu_s;
  }
  return !stopped;
}

double ratio(std::int64_t later, std::int64_t first) noexcept {
  return first > 0 ? static_cast<double>(later) / static_cast<double>(first) : 0.0;
}

// The drift line; false when the CPU time per cycle more than doubled.
bool print_drift(const SoakTally& tally, const loop::DurationHistogram& first_tenth,
                 const loop::DurationHistogram& last_tenth) noexcept {
  if (last_tenth.count() > 0U && tally.last_tenth_cpu_s > 0.0) {
    const double cpu_ratio = tally.first_tenth_cpu_s > 0.0 ? tally.last_tenth_cpu_s / tally.first_tenth_cpu_s : 0.0;
    const double per_cycle_ms = 1e3 / static_cast<double>(first_tenth.count());
    const bool drift_ok = cpu_ratio <= kMaxCpuDrift;
    std::printf("cycle time drift, first vs last tenth (%llu cycles each): CPU %.3f -> %.3f ms per cycle (x%.2f, limit "
                "x%.0f); wall-clock p50 %.3f -> %.3f ms (x%.2f), p99 %.3f -> %.3f ms (x%.2f) (reported: the machine "
                "may be shared) %s\n",
                static_cast<unsigned long long>(first_tenth.count()), tally.first_tenth_cpu_s * per_cycle_ms,
                tally.last_tenth_cpu_s * per_cycle_ms, cpu_ratio, kMaxCpuDrift, ms(first_tenth.quantile_ns(0.5)),
                ms(last_tenth.quantile_ns(0.5)), ratio(last_tenth.quantile_ns(0.5), first_tenth.quantile_ns(0.5)),
                ms(first_tenth.quantile_ns(0.99)), ms(last_tenth.quantile_ns(0.99)),
                ratio(last_tenth.quantile_ns(0.99), first_tenth.quantile_ns(0.99)), drift_ok ? "ok" : "FAIL");
    return drift_ok;
  }
  std::printf("cycle time drift, first vs last tenth: the last tenth was not reached\n");
  return true;
}

// `cycles` cycles of the throughput run's loop after a warm-up pass over the
// dataset (start-up: the track, the decoder's arena, the first sends), then
// one line per check. Exit 1 when one fails.
int soak(const RigRequest& request, std::uint32_t dataset, std::uint64_t cycles, const std::atomic<bool>* stop) {
  int code = kExitOk;
  const std::unique_ptr<LoopRig> rig = bench_rig("soak", request, nullptr, dataset, 0U, code);
  if (!rig) {
    return code;
  }
  // The controllers' side of the simulated bus: TCP and JOINTS only.
  hal::SimEndpoint& listener = rig->sim_bus->endpoint(1U);
  const std::uint32_t ids[] = {can::tcp_id(rig->config.can.node_id), can::joints_id(rig->config.can.node_id)};
  auto reference = std::unique_ptr<std::uint64_t[]>(new (std::nothrow) std::uint64_t[dataset]());
  auto first_tenth = std::make_unique<loop::DurationHistogram>();
  auto last_tenth = std::make_unique<loop::DurationHistogram>();
  if (!listener.set_rx_ids(ids, 2U).ok() || !reference) {
    std::fprintf(stderr, "tcpest bench: soak: start-up failed\n");
    return kExitFailure;
  }
  std::printf("\n== soak, %dx%d: a warm-up pass over the %u frames, then %llu cycles, --no-pacing, simulated bus\n",
              rig->models.camera.width(), rig->models.camera.height(), dataset,
              static_cast<unsigned long long>(cycles));
  static_cast<void>(std::fflush(stdout));  // progress before a long step
  loop::Executive& executive = *rig->executive;
  executive.start();
  for (std::uint32_t i = 0U; i < dataset; ++i) {
    if (!soak_cycle(executive, listener, i, dataset).ran) {
      std::fprintf(stderr, "tcpest bench: soak: the warm-up cycle %u had no frame\n", i);
      return kExitFailure;
    }
  }
  const HeapProbe* probe = heap_probe();
  SoakTally tally;
  const long long heap_after_warm_up_bytes = heap_bytes_in_use();
  const bool completed =
      soak_cycles(executive, listener, probe, dataset, cycles, reference.get(), *first_tenth, *last_tenth, tally, stop);
  const long long heap_at_end_bytes = heap_bytes_in_use();

  print_summary(stdout, executive);  // the warm-up included
  if (!completed) {
    std::printf("stopped after %llu of %llu cycles: the lines below cover those\n",
                static_cast<unsigned long long>(tally.cycles), static_cast<unsigned long long>(cycles));
  }
  bool passed = tally.frameless == 0U;
  if (tally.frameless != 0U) {
    std::printf("cycles without a frame: %llu (FAIL: the replay always has one)\n",
                static_cast<unsigned long long>(tally.frameless));
  }
  if (probe != nullptr) {
    passed = passed && tally.allocations == 0U;
    std::printf("heap allocations after start-up: %llu in %llu cycles (%s counted) %s\n",
                static_cast<unsigned long long>(tally.allocations), static_cast<unsigned long long>(tally.cycles),
                probe->counts, tally.allocations == 0U ? "ok" : "FAIL");
  } else {
    std::printf("heap allocations after start-up: not counted (no counter in this build)\n");
  }
  if (heap_after_warm_up_bytes >= 0 && heap_at_end_bytes >= 0) {
    const long long growth_bytes = heap_at_end_bytes - heap_after_warm_up_bytes;
    passed = passed && growth_bytes <= 0;
    std::printf("heap in use: %lld bytes after the warm-up, %lld at the end (growth %lld) %s\n",
                heap_after_warm_up_bytes, heap_at_end_bytes, growth_bytes, growth_bytes <= 0 ? "ok" : "FAIL");
  } else {
    std::printf("heap in use: not measured (no mallinfo2 in this C library)\n");
  }
  passed = print_drift(tally, *first_tenth, *last_tenth) && passed;
  // Pass 1 is the warm-up (it starts without a track), pass 2 the reference.
  const std::uint64_t compared = tally.last_pass > 1U ? tally.last_pass - 1U : 0U;
  const std::uint64_t last_pass_number = tally.last_pass + 1U;  // 1-based, as printed
  const std::uint64_t first_mismatch_pass_number = tally.first_mismatch_pass + 1U;
  if (compared == 0U) {
    std::printf("payload determinism: not checked (fewer than 3 passes over the %u frames)\n", dataset);
  } else if (tally.mismatches == 0U) {
    std::printf("payload determinism: passes 3..%llu (%llu%s) equal to pass 2 frame by frame (TCP and JOINTS, E2E "
                "counter and CRC excluded; the track restarted at each pass) ok\n",
                static_cast<unsigned long long>(last_pass_number), static_cast<unsigned long long>(compared),
                tally.last_pass_partial ? ", the last one partial" : "");
  } else {
    passed = false;
    std::printf("payload determinism: %llu frames of passes 3..%llu differ from pass 2, the first frame %llu of pass "
                "%llu (TCP and JOINTS, E2E counter and CRC excluded; the track restarted at each pass) FAIL\n",
                static_cast<unsigned long long>(tally.mismatches), static_cast<unsigned long long>(last_pass_number),
                static_cast<unsigned long long>(tally.first_mismatch_frame),
                static_cast<unsigned long long>(first_mismatch_pass_number));
  }
  std::printf("soak: %s\n", passed ? "passed" : "FAILED");
  if (!passed) {
    return kExitFailure;
  }
  return completed ? kExitOk : kExitInterrupted;
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
    print_usage("tcpest bench [--frames N] [--dataset N] [--hd] [--jitter-seconds S] [--period-us P]\n"
                "       tcpest bench --soak N [--dataset N]",
                "Times the loop on a fixed rendered dataset with --no-pacing (per-step and total percentiles),\n"
                "and compares the period jitter of its CAN sends with a bare clock_nanosleep loop, side by side.\n"
                "With --soak N, instead of both: a warm-up pass over the dataset, then N cycles of the same loop,\n"
                "and one line per check: heap allocations (must be 0), heap growth (must be none), the cycle\n"
                "time of the first vs the last tenth (fails if the CPU time per cycle more than doubles), and the TCP and\n"
                "JOINTS payloads of every pass over the dataset against the second pass's. Exit 1 when a check\n"
                "fails. --frames, --hd, --jitter-seconds and --period-us do not apply.",
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
  unsigned long long soak_count = 0U;
  // The ranges of loop.frames and loop.period_us (docs/loop.md); a day of
  // jitter at most; 10^9 soak cycles are over a month at --no-pacing.
  if (!unsigned_option(args, "bench", "frames", 1U, 1000000000000ULL, frames) ||
      !unsigned_option(args, "bench", "dataset", 1U, 10000U, dataset) ||
      !unsigned_option(args, "bench", "period-us", 1000U, 10000000U, period_us) ||
      !number_option(args, "bench", "jitter-seconds", 0.0, 86400.0, seconds) ||
      !unsigned_option(args, "bench", "soak", 1U, 1000000000ULL, soak_count)) {
    return kExitUsage;
  }
  const bool soaking = args.value("soak") != nullptr;
  if (soaking) {
    for (const char* other : {"frames", "hd", "jitter-seconds", "period-us"}) {
      if (args.flag(other)) {
        std::fprintf(stderr, "tcpest bench: --%s does not apply to --soak (see --help)\n", other);
        return kExitUsage;
      }
    }
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
  if (soaking) {
    return soak(request, static_cast<std::uint32_t>(dataset), soak_count, stop);
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
