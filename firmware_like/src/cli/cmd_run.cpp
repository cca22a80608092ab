// tcpest run: the loop as deployed. Frames in (simulated camera, JPEG files,
// Y4M, V4L2), TCP estimates out on CAN (SocketCAN, or the simulated bus
// writing a candump log). A status line every second; SIGINT/SIGTERM stop
// cleanly with a summary. With --record DIR, cycles.csv, the candump log and
// overlays are written off the cycle (cli/recorder.hpp); with --status-json
// the status line is one JSON object. Exit codes: commands.hpp (0 the source
// ended or --frames was reached, 2 usage, 3 configuration or input, 1 failure
// (a recording's write too), 4 stopped by a signal).
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <utility>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/loop_rig.hpp"
#include "cli/recorder.hpp"
#include "cli/setup.hpp"
#include "tcpest/common/json_escape.hpp"
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
    {"start-operational", nullptr,
     "go operational after boot-up without waiting for an NMT start (sets can.start_operational; for a bus "
     "without an NMT master, e.g. log:FILE)"},
    {"quiet", nullptr, "no status line"},
    {"status-json", nullptr, "the status line as one JSON object per line (docs/cli.md)"},
    {"record", "DIR", "write DIR/cycles.csv, DIR/can.log and DIR/overlays/ off the cycle (docs/loop.md)"},
    {"overlay-every", "N", "with --record: an overlay every N frames (default 25; 0 = none)"},
    {"record-max-mb", "M", "with --record: disk cap of the recording in MiB, files rotated (default 1024; 0 = none)"},
    {"record-keep", "K", "with --record: files kept per stream, the current one included (default 4)"},
    {"record-queue", "N", "with --record: cycles the writer may lag behind before records are dropped (default 256)"},
};
constexpr std::size_t kOptionCount = sizeof kOptions / sizeof kOptions[0];

// The status line, once per status period, from the loop's own statistics:
// text, or one JSON object per line for a supervisor (docs/cli.md).
class StatusLine final : public loop::CycleObserver {
 public:
  StatusLine(const loop::Executive& executive, hal::Clock& clock, std::int64_t period_ns, bool json,
             const Recorder* recorder) noexcept
      : executive_(executive), clock_(clock), period_ns_(period_ns), start_ns_(clock.now_ns()),
        next_ns_(start_ns_ + period_ns), json_(json), recorder_(recorder) {}
  void on_cycle(const loop::CycleRecord& record, const ImageView& /*frame*/) noexcept override {
    const std::int64_t now = clock_.now_ns();
    if (now < next_ns_) {
      return;
    }
    next_ns_ = now + period_ns_;
    if (json_) {
      print_json(record, now);
    } else {
      print_text(record);
    }
    static_cast<void>(std::fflush(stdout));  // a status line is for now, not for later
  }

 private:
  double valid_share() const noexcept {
    const loop::LoopStats& s = executive_.stats();
    const std::uint64_t camera_cycles = s.status[0] + s.status[1] + s.status[2] + s.status[3];
    return camera_cycles > 0U ? static_cast<double>(s.status[0]) / static_cast<double>(camera_cycles) : 0.0;
  }
  unsigned long long drops() const noexcept {
    return recorder_ != nullptr ? static_cast<unsigned long long>(recorder_->dropped()) : 0ULL;
  }
  void print_text(const loop::CycleRecord& record) const noexcept {
    const loop::LoopStats& s = executive_.stats();
    char recording[96] = {};
    if (recorder_ != nullptr) {
      static_cast<void>(std::snprintf(recording, sizeof recording, ", record drops %llu, write errors %llu", drops(),
                                      static_cast<unsigned long long>(recorder_->write_errors())));  // fits
    }
    std::printf("[%s] frames %llu, valid %.1f %%, latency p50 %.2f ms p99 %.2f ms, overruns %llu, slips %llu%s%s%s\n",
                loop::to_string(record.mode), static_cast<unsigned long long>(s.frames), 100.0 * valid_share(),
                ms(s.latency.quantile_ns(0.5)), ms(s.latency.quantile_ns(0.99)),
                static_cast<unsigned long long>(s.cycle_overruns), static_cast<unsigned long long>(s.slips), recording,
                record.camera_lost ? ", CAMERA LOST" : "", record.bus_lost ? ", BUS LOST" : "");
  }
  void print_json(const loop::CycleRecord& record, std::int64_t now_ns) const noexcept {
    const loop::LoopStats& s = executive_.stats();
    char mode[64];
    static_cast<void>(json::escape_string(loop::to_string(record.mode), mode, sizeof mode));  // short names: fit
    std::printf("{\"t_s\":%.3f,\"mode\":\"%s\",\"cycles\":%llu,\"frames\":%llu,\"valid_share\":%.4f,"
                "\"latency_p50_ms\":%.3f,\"latency_p99_ms\":%.3f,\"overruns\":%llu,\"slips\":%llu,"
                "\"drops\":%llu,\"write_errors\":%llu,\"camera_lost\":%s,\"bus_lost\":%s}\n",
                ms(now_ns - start_ns_) / 1000.0, mode, static_cast<unsigned long long>(s.cycles),
                static_cast<unsigned long long>(s.frames), valid_share(), ms(s.latency.quantile_ns(0.5)),
                ms(s.latency.quantile_ns(0.99)), static_cast<unsigned long long>(s.cycle_overruns),
                static_cast<unsigned long long>(s.slips), drops(),
                recorder_ != nullptr ? static_cast<unsigned long long>(recorder_->write_errors()) : 0ULL,
                record.camera_lost ? "true" : "false", record.bus_lost ? "true" : "false");
  }

  const loop::Executive& executive_;
  hal::Clock& clock_;
  std::int64_t period_ns_;
  std::int64_t start_ns_;
  std::int64_t next_ns_;
  bool json_;
  const Recorder* recorder_;
};

// --record and its options into `options` (dir nullptr: no recording).
// False (reported) on a bad value.
bool parse_record_options(const Args& args, RecorderOptions& options) noexcept {
  options.dir = args.value("record");
  unsigned long long overlay_every = 25U;
  unsigned long long keep = 4U;
  unsigned long long queue = 256U;
  double max_mb = 1024.0;
  if (!unsigned_option(args, "run", "overlay-every", 0U, 1000000U, overlay_every) ||
      !unsigned_option(args, "run", "record-keep", 1U, kMaxRecorderKeepFiles, keep) ||
      !unsigned_option(args, "run", "record-queue", 1U, kMaxRecorderQueue, queue) ||
      !number_option(args, "run", "record-max-mb", 0.0, 1e7, max_mb)) {
    return false;
  }
  options.overlay_every = static_cast<std::uint32_t>(overlay_every);
  options.keep_files = static_cast<std::uint32_t>(keep);
  options.queue_capacity = static_cast<std::uint32_t>(queue);
  options.max_bytes = static_cast<std::uint64_t>(max_mb * 1048576.0);
  return true;
}

// The recorder of this rig (its writer thread started), tapping the CAN
// node; nullptr (reported) when it cannot be started, with the exit code in
// `code` (2: a cap too small for the options, 1: anything else).
std::unique_ptr<Recorder> start_recorder(RecorderOptions options, LoopRig& rig, int& code) noexcept {
  options.width = rig.source->width();
  options.height = rig.source->height();
  options.with_truth = rig.sim != nullptr;
  options.can_interface = rig.node->log_interface();
  auto created = Recorder::create(options, rig.models);
  if (!created.ok()) {
    code = created.error() == RecorderError::kBadOptions ? kExitUsage : kExitFailure;
    if (created.error() == RecorderError::kBadOptions) {
      std::fprintf(stderr, "tcpest run: --record %s: --record-max-mb too small for %u file(s) per stream%s\n",
                   options.dir, options.keep_files, options.overlay_every > 0U ? " and one overlay" : "");
    } else {
      std::fprintf(stderr, "tcpest run: --record %s: %s%s%s\n", options.dir, to_string(created.error()),
                   errno != 0 ? ": " : "", errno != 0 ? std::strerror(errno) : "");
    }
    return nullptr;
  }
  std::unique_ptr<Recorder> recorder = std::move(created.value());
  recorder->set_truth_source(rig.sim);
  if (rig.vision != nullptr) {
    recorder->set_extraction(&rig.vision->extractor().result());
  }
  rig.node->set_tap(recorder.get());
  return recorder;
}

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
    print_usage("tcpest run [--config CFG] [--calib CAM.yaml] [--source SRC] [--bus BUS] [--frames N] [--no-pacing]\n"
                "           [--start-operational] [--record DIR [--overlay-every N] [--record-max-mb M] "
                "[--record-keep K]] [--status-json]",
                "The estimation loop as deployed: frames in, TCP estimates out on CAN, every cycle timed.\n"
                "Without a config file the documented defaults apply (docs/loop.md): the simulated camera,\n"
                "the simulated bus logging to can.log, the frame trigger at 25 Hz. The CAN node sends its PDOs\n"
                "once operational: after the robot's NMT start, or at once with --start-operational.\n"
                "Exit codes: 0 done, 1 failure (a recording's or log's write too), 2 usage, 3 configuration/input,\n"
                "4 stopped by SIGINT/SIGTERM.",
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
  request.start_operational = args.flag("start-operational");
  request.quiet = args.flag("quiet");
  if (args.value("frames") != nullptr) {
    unsigned long long frames = 0U;
    if (!unsigned_option(args, "run", "frames", 0U, 1000000000000ULL, frames)) {  // loop.frames' range
      return kExitUsage;
    }
    request.frames = static_cast<long long>(frames);
  }
  RecorderOptions record_options;
  if (!parse_record_options(args, record_options)) {
    return kExitUsage;
  }
  const std::atomic<bool>* stop = install_stop_signals();
  auto rig_owner = std::make_unique<LoopRig>();  // the loop's buffers: allocated once, here
  LoopRig& rig = *rig_owner;
  const int code = rig.open_all(request);
  if (code != kExitOk) {
    return code;
  }
  // The writer thread starts before the real-time settings: it keeps the normal policy.
  std::unique_ptr<Recorder> recorder;
  if (record_options.dir != nullptr) {
    int record_code = kExitOk;
    recorder = start_recorder(record_options, rig, record_code);
    if (!recorder) {
      return record_code;
    }
  }
  const loop::RtReport rt = loop::apply_rt_settings(rig.config.rt);  // its latency request lasts until the return
  for (std::size_t i = 0; i < rt.message_count; ++i) {
    std::fprintf(stderr, "tcpest run: %s\n", rt.messages[i]);
  }
  std::printf("tcpest run: source %s (%dx%d, %s), %s, node 0x%02X, trigger %s%s\n", rig.config.loop.source,
              rig.source->width(), rig.source->height(), rig.source->kind(), rig.bus_label,
              static_cast<unsigned>(rig.config.can.node_id), loop::to_string(rig.config.loop.trigger),
              rig.config.loop.pacing ? "" : " (no pacing)");
  StatusLine status(*rig.executive, rig.clock, static_cast<std::int64_t>(rig.config.loop.status_period_ms) * hal::kNsPerMs,
                    args.flag("status-json"), recorder.get());
  loop::CycleObserver* status_observer = request.quiet ? nullptr : &status;
  if (recorder) {
    recorder->set_next(status_observer);
    rig.executive->set_observer(recorder.get());
  } else {
    rig.executive->set_observer(status_observer);
  }
  const loop::CycleOutcome outcome = rig.executive->run(stop);
  std::printf("tcpest run: %s\n", outcome == loop::CycleOutcome::kInterrupted ? "stopped by signal" : "finished");
  print_summary(stdout, *rig.executive);
  const bool log_complete = rig.finish_log(stdout);
  bool record_complete = true;
  if (recorder) {
    rig.node->set_tap(nullptr);
    record_complete = recorder->finish();
    recorder->print(stdout, "run");
  }
  int exit_code = outcome == loop::CycleOutcome::kInterrupted ? kExitInterrupted : end_of_run_code(rig);
  if (!log_complete || !record_complete) {
    exit_code = kExitFailure;  // a write failed (docs/cli.md)
  }
  return exit_code;
}

}  // namespace cli
}  // namespace tcpest
