// tcpest run: the loop as deployed. Frames in (simulated camera, JPEG files,
// Y4M, V4L2), TCP estimates out on CAN (SocketCAN, or the simulated bus
// writing a candump log). A status line every second; SIGINT/SIGTERM stop
// cleanly with a summary. Exit codes: commands.hpp (0 the source ended or
// --frames was reached, 2 usage, 3 configuration or input, 1 failure,
// 4 stopped by a signal).
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
    {"config", "CFG.yaml", "configuration: instrument and the loop:/can:/rt: sections (default: built-in defaults)"},
    kCalibOption,
    {"source", "SRC", "sim | DIR | LIST.txt | FILE.y4m | /dev/videoN (overrides loop.source; default sim)"},
    {"bus", "BUS", "IFACE (SocketCAN) | log:FILE (simulated bus, candump log) | sim (overrides can.bus)"},
    {"frames", "N", "stop after N cycles (overrides loop.frames; 0 = until the source ends)"},
    {"no-pacing", nullptr, "replay as fast as possible instead of at the source's rate"},
    {"quiet", nullptr, "no status line"},
};
constexpr std::size_t kOptionCount = sizeof kOptions / sizeof kOptions[0];

// The status line, once per status period, from the loop's own statistics.
class StatusLine final : public loop::CycleObserver {
 public:
  StatusLine(const loop::Executive& executive, hal::Clock& clock, std::int64_t period_ns) noexcept
      : executive_(executive), clock_(clock), period_ns_(period_ns), next_ns_(clock.now_ns() + period_ns) {}
  void on_cycle(const loop::CycleRecord& record, const ImageView& /*frame*/) noexcept override {
    const std::int64_t now = clock_.now_ns();
    if (now < next_ns_) {
      return;
    }
    next_ns_ = now + period_ns_;
    const loop::LoopStats& s = executive_.stats();
    const std::uint64_t camera_cycles = s.status[0] + s.status[1] + s.status[2] + s.status[3];
    std::printf("[%s] frames %llu, valid %.1f %%, latency p50 %.2f ms p99 %.2f ms, overruns %llu, slips %llu%s%s\n",
                loop::to_string(record.mode), static_cast<unsigned long long>(s.frames),
                camera_cycles > 0U ? 100.0 * static_cast<double>(s.status[0]) / static_cast<double>(camera_cycles) : 0.0,
                ms(s.latency.quantile_ns(0.5)), ms(s.latency.quantile_ns(0.99)),
                static_cast<unsigned long long>(s.cycle_overruns), static_cast<unsigned long long>(s.slips),
                record.camera_lost ? ", CAMERA LOST" : "", record.bus_lost ? ", BUS LOST" : "");
    static_cast<void>(std::fflush(stdout));  // a status line is for now, not for later
  }

 private:
  const loop::Executive& executive_;
  hal::Clock& clock_;
  std::int64_t period_ns_;
  std::int64_t next_ns_;
};

// How a run that was not interrupted ended: 0, or (reported) 3 when the
// recording was too damaged to go on, 1 when the camera was lost and not
// recovered (a live camera; a replay's input is at fault: 3).
int end_of_run_code(const LoopRig& rig) noexcept {
  const char* stopped = rig.source->stop_reason();
  if (stopped != nullptr) {
    std::fprintf(stderr, "tcpest run: source %s: %s: stopped\n", rig.config.loop.source, stopped);
    return kExitConfig;
  }
  const loop::LoopStats& s = rig.executive->stats();
  if (s.camera_lost_events > s.camera_recoveries) {
    std::fprintf(stderr, "tcpest run: source %s: lost (no usable frame in %d consecutive cycles) and not recovered\n",
                 rig.config.loop.source, rig.config.loop.camera_lost_after);
    return rig.source->live() ? kExitFailure : kExitConfig;
  }
  return kExitOk;
}

}  // namespace

int cmd_run(int argc, char** argv) {
  auto args_owner = std::make_unique<Args>();  // large (positional table): not on the stack
  Args& args = *args_owner;
  char error[256];
  if (!args.parse(argc, argv, 1, kOptions, kOptionCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest run: %s (see --help)\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest run [--config CFG] [--calib CAM.yaml] [--source SRC] [--bus BUS] [--frames N] [--no-pacing]",
                "The estimation loop as deployed: frames in, TCP estimates out on CAN, every cycle timed.\n"
                "Without a config file the documented defaults apply (docs/loop.md): the simulated camera,\n"
                "the simulated bus logging to can.log, the frame trigger at 25 Hz.\n"
                "Exit codes: 0 done, 1 failure, 2 usage, 3 configuration/input, 4 stopped by SIGINT/SIGTERM.",
                kOptions, kOptionCount);
    return kExitOk;
  }
  if (args.positional_count() != 0U) {
    std::fprintf(stderr, "tcpest run: unexpected argument '%s' (see --help)\n", args.positional(0));
    return kExitUsage;
  }
  RigRequest request;
  request.command = "run";
  request.config_path = args.value("config");
  request.calib_path = args.value("calib");
  request.source = args.value("source");
  request.bus = args.value("bus");
  request.no_pacing = args.flag("no-pacing");
  request.quiet = args.flag("quiet");
  if (args.value("frames") != nullptr) {
    unsigned long long frames = 0U;
    if (!unsigned_option(args, "run", "frames", 0U, 1000000000000ULL, frames)) {  // loop.frames' range
      return kExitUsage;
    }
    request.frames = static_cast<long long>(frames);
  }
  const std::atomic<bool>* stop = install_stop_signals();
  auto rig_owner = std::make_unique<LoopRig>();  // the loop's buffers: allocated once, here
  LoopRig& rig = *rig_owner;
  const int code = rig.open_all(request);
  if (code != kExitOk) {
    return code;
  }
  const loop::RtReport rt = loop::apply_rt_settings(rig.config.rt);  // its latency request lasts until the return
  for (std::size_t i = 0; i < rt.message_count; ++i) {
    std::fprintf(stderr, "tcpest run: %s\n", rt.messages[i]);
  }
  std::printf("tcpest run: source %s (%dx%d, %s), %s, node 0x%02X, trigger %s%s\n", rig.config.loop.source,
              rig.source->width(), rig.source->height(), rig.source->kind(), rig.bus_label,
              static_cast<unsigned>(rig.config.can.node_id), loop::to_string(rig.config.loop.trigger),
              rig.config.loop.pacing ? "" : " (no pacing)");
  StatusLine status(*rig.executive, rig.clock, static_cast<std::int64_t>(rig.config.loop.status_period_ms) * hal::kNsPerMs);
  if (!request.quiet) {
    rig.executive->set_observer(&status);
  }
  const loop::CycleOutcome outcome = rig.executive->run(stop);
  std::printf("tcpest run: %s\n", outcome == loop::CycleOutcome::kInterrupted ? "stopped by signal" : "finished");
  print_summary(stdout, *rig.executive);
  const bool log_complete = rig.finish_log(stdout);
  int exit_code = outcome == loop::CycleOutcome::kInterrupted ? kExitInterrupted : end_of_run_code(rig);
  if (!log_complete) {
    exit_code = kExitFailure;  // a write failed (docs/cli.md)
  }
  return exit_code;
}

}  // namespace cli
}  // namespace tcpest
