#include "cli/loop_rig.hpp"

#include <signal.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <new>

#include "cli/commands.hpp"
#include "tcpest/common/yaml_lite.hpp"
#include "tcpest/hal/camera/file_sources.hpp"
#include "tcpest/hal/camera/v4l2_source.hpp"
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace cli {

namespace {

std::atomic<bool> g_stop{false};  // NOLINT(cppcoreguidelines-avoid-non-const-global-variables): a signal handler can only reach a global

extern "C" void on_stop_signal(int /*signal*/) { g_stop.store(true, std::memory_order_relaxed); }

bool ends_with(const char* text, const char* suffix) noexcept {
  const std::size_t n = std::strlen(text);
  const std::size_t s = std::strlen(suffix);
  return n >= s && std::strcmp(text + n - s, suffix) == 0;
}

int camera_exit_code(hal::CameraError e) noexcept {
  switch (e) {
    case hal::CameraError::kNotFound:
    case hal::CameraError::kCorrupt:
    case hal::CameraError::kTruncated:
    case hal::CameraError::kWrongSize:
    case hal::CameraError::kUnsupported:
    case hal::CameraError::kEndOfStream:  // an empty recording
      return kExitConfig;
    default:
      return kExitFailure;
  }
}

void progress_line(std::uint32_t done, std::uint32_t total) {
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  if (done == total || (tty && done % 10U == 0U)) {
    std::fprintf(stderr, "%srendering the simulated camera's sequence: %u/%u frames%s", tty ? "\r" : "", done, total,
                 done == total ? "\n" : "");
  }
}

}  // namespace

double ms(std::int64_t ns) noexcept { return static_cast<double>(ns) / 1e6; }

LoopRig::~LoopRig() {
  executive.reset();
  if (logging) {
    static_cast<void>(log.close());  // the summary has been printed; a close error cannot be acted on here
  }
}

const std::atomic<bool>* install_stop_signals() noexcept {
  struct sigaction action {};
  action.sa_handler = on_stop_signal;  // NOLINT(cppcoreguidelines-pro-type-union-access): the POSIX struct
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: clock_nanosleep and poll return EINTR
  static_cast<void>(sigaction(SIGINT, &action, nullptr));   // valid signal numbers: cannot fail
  static_cast<void>(sigaction(SIGTERM, &action, nullptr));  // idem
  return &g_stop;
}

int LoopRig::load(const RigRequest& r) noexcept {
  request = r;
  if (!load_model_setup(r.command, r.calib_path, r.config_path, models)) {
    return kExitConfig;
  }
  static yaml::Document scratch;  // large: static storage, start-up only
  const auto loaded = loop::load_loop_config(r.config_path, scratch, config);
  if (!loaded.ok()) {
    char message[768];
    loaded.error().format(message, sizeof message);
    std::fprintf(stderr, "tcpest %s: config: %s\n", r.command, message);
    return kExitConfig;
  }
  if (r.source != nullptr) {
    static_cast<void>(std::snprintf(config.loop.source, sizeof config.loop.source, "%s", r.source));  // checked by open_source
  }
  if (r.bus != nullptr) {
    static_cast<void>(std::snprintf(config.can.bus, sizeof config.can.bus, "%s", r.bus));  // checked by open_bus
  }
  if (r.frames >= 0) {
    config.loop.frames = static_cast<std::uint64_t>(r.frames);
  }
  if (r.no_pacing) {
    config.loop.pacing = false;
  }
  if (r.start_operational) {
    config.can.start_operational = true;
  }
  return kExitOk;
}

int LoopRig::open_source() noexcept {
  const char* spec = config.loop.source;
  const int w = models.camera.width();
  const int h = models.camera.height();
  if (std::strcmp(spec, "sim") == 0) {
    loop::PrerenderOptions options;
    options.frames = request.sim_frames;
    options.rate_hz = config.loop.trigger == loop::Trigger::kPeriod ? 1e6 / static_cast<double>(config.loop.period_us)
                                                                   : 25.0;
    options.loop = config.loop.replay_loop || config.loop.frames > request.sim_frames || config.loop.frames == 0U;
    options.progress = request.quiet ? nullptr : progress_line;
    auto created = loop::PrerenderedSource::create(models.camera, models.instrument, options);
    if (!created.ok()) {
      std::fprintf(stderr, "tcpest %s: simulated camera: %s\n", request.command, hal::to_string(created.error()));
      return kExitFailure;
    }
    sim = created.value().get();
    source = std::move(created.value());
    return kExitOk;
  }
  hal::CameraError error = hal::CameraError::kNone;
  char detail[192] = {};  // why a file is refused, when the source says
  if (std::strncmp(spec, "/dev/video", 10) == 0) {
    hal::V4l2Options options;
    options.width = w;
    options.height = h;
    options.timeout_ms = config.loop.camera_timeout_ms;
    if (!hal::parse_v4l2_pixel_format(config.loop.v4l2_format, options.format)) {
      std::fprintf(stderr, "tcpest %s: loop.v4l2_format '%s': expected yuyv, mjpeg or rgb24\n", request.command,
                   config.loop.v4l2_format);
      return kExitConfig;
    }
    auto opened = hal::V4l2Source::open(spec, options);
    if (opened.ok()) {
      source = std::move(opened.value());
    } else {
      error = opened.error();
    }
  } else {
    hal::ReplayOptions options;
    options.width = w;
    options.height = h;
    options.loop = config.loop.replay_loop;
    if (ends_with(spec, ".y4m")) {
      auto opened = hal::Y4mSource::open(spec, options, detail, sizeof detail);
      if (opened.ok()) {
        source = std::move(opened.value());
      } else {
        error = opened.error();
      }
    } else {
      auto opened = hal::JpegFileSource::open(spec, options);
      if (opened.ok()) {
        source = std::move(opened.value());
      } else {
        error = opened.error();
      }
    }
  }
  if (!source) {
    if (error == hal::CameraError::kWrongSize) {
      std::fprintf(stderr, "tcpest %s: source %s: frames are not %dx%d, the calibrated camera's size\n",
                   request.command, spec, w, h);
    } else if (detail[0] != '\0') {
      std::fprintf(stderr, "tcpest %s: source %s: %s: %s\n", request.command, spec, hal::to_string(error), detail);
    } else {
      std::fprintf(stderr, "tcpest %s: source %s: %s\n", request.command, spec, hal::to_string(error));
    }
    return camera_exit_code(error);
  }
  return kExitOk;
}

int LoopRig::open_bus(const char* log_path) noexcept {
  const char* spec = config.can.bus;
  hal::CanBus* bus = nullptr;
  const char* log_interface = "sim0";
  if (std::strncmp(spec, "log:", 4) == 0 || std::strcmp(spec, "sim") == 0) {
    sim_bus.reset(new (std::nothrow) hal::SimBus());
    if (!sim_bus) {
      return kExitFailure;
    }
    bus = &sim_bus->endpoint(0);
    if (spec[0] == 'l' && log_path == nullptr) {
      log_path = spec + 4;
    }
    static_cast<void>(std::snprintf(bus_label, sizeof bus_label, "simulated bus%s%s", log_path ? ", log " : "",
                                    log_path ? log_path : ""));  // a label: truncation is harmless
  } else {
    socket_bus.reset(new (std::nothrow) hal::SocketCanBus());
    if (!socket_bus) {
      return kExitFailure;
    }
    hal::SocketCanConfig sc;
    const std::uint32_t ids[] = {can::kNmtId, can::kSyncId, can::encoder_prior_id(config.can.node_id)};
    for (const std::uint32_t id : ids) {
      static_cast<void>(sc.rx_ids.push_back(id));  // 3 of 16: cannot be full
    }
    const auto opened = socket_bus->open(spec, sc);
    if (!opened.ok() && opened.error() != hal::CanBusError::kInterfaceDown) {
      std::fprintf(stderr, "tcpest %s: CAN interface %s: %s\n", request.command, spec, hal::to_string(opened.error()));
      return kExitFailure;
    }
    bus = socket_bus.get();
    log_interface = spec;
    static_cast<void>(std::snprintf(bus_label, sizeof bus_label, "SocketCAN %s", spec));  // a label
  }
  if (log_path != nullptr) {
    const auto opened = log.open(log_path, log_interface);
    if (!opened.ok()) {
      std::fprintf(stderr, "tcpest %s: candump log %s: %s\n", request.command, log_path, hal::to_string(opened.error()));
      return kExitConfig;
    }
    logging = true;
    static_cast<void>(std::snprintf(log_file, sizeof log_file, "%s", log_path));  // for messages: truncation is harmless
  }
  node.reset(new (std::nothrow) loop::CanNodePort(clock, *bus, sim_bus.get(), logging ? &log : nullptr, log_interface));
  if (!node) {
    return kExitFailure;
  }
  node->set_socket(socket_bus.get());
  const auto configured = node->configure(loop::node_config(config));
  if (!configured.ok()) {
    std::fprintf(stderr, "tcpest %s: CAN node configuration: %s\n", request.command, can::to_string(configured.error()));
    return kExitConfig;
  }
  return kExitOk;
}

int LoopRig::build() noexcept {
  auto vision_pipeline = loop::VisionPipeline::create(models.camera, models.instrument, vision::default_color_model(),
                                                      config.loop.estimator);
  if (!vision_pipeline.ok()) {
    std::fprintf(stderr, "tcpest %s: frame estimator: %s\n", request.command,
                 vision::to_string(vision_pipeline.error()));
    return kExitFailure;
  }
  vision = vision_pipeline.value().get();
  pipeline = std::move(vision_pipeline.value());
  if (source->width() != models.camera.width() || source->height() != models.camera.height()) {
    std::fprintf(stderr, "tcpest %s: the source's frames are %dx%d, the camera calibration is %dx%d\n",
                 request.command, source->width(), source->height(), models.camera.width(), models.camera.height());
    return kExitConfig;
  }
  loop::LoopParts parts{source.get(), &clock, pipeline.get(), node.get(), &models.camera, &models.instrument};
  auto created = loop::Executive::create(config, parts);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest %s: loop: %s\n", request.command, loop::to_string(created.error()));
    return kExitConfig;
  }
  executive = std::move(created.value());
  return kExitOk;
}

int LoopRig::open_all(const RigRequest& r) noexcept {
  int code = load(r);
  if (code == kExitOk) {
    code = open_source();
  }
  if (code == kExitOk) {
    code = open_bus();
  }
  if (code == kExitOk) {
    code = build();
  }
  return code;
}

bool LoopRig::finish_log(std::FILE* out) noexcept {
  if (!logging) {
    return true;
  }
  static_cast<void>(log.close());  // its failure is in the counts below
  logging = false;
  const std::uint64_t errors = log.write_errors();
  std::fprintf(out, "candump log %s: %llu lines, lost %llu, write errors %llu\n", log_file,
               static_cast<unsigned long long>(log.lines_written()), static_cast<unsigned long long>(log.lines_lost()),
               static_cast<unsigned long long>(errors));
  if (errors == 0U) {
    return true;
  }
  std::fprintf(stderr, "tcpest %s: candump log %s: %llu write error(s), the first: %s; the log is incomplete\n",
               request.command, log_file, static_cast<unsigned long long>(errors), std::strerror(log.first_errno()));
  return false;
}

void print_steps(std::FILE* out, const loop::Executive& executive) noexcept {
  const loop::LoopStats& s = executive.stats();
  std::fprintf(out, "%-13s %9s %9s %9s %9s %9s %9s %9s\n", "step (ms)", "budget", "p50", "p99", "p99.9", "max",
               "mean", "overruns");
  for (int i = 0; i < loop::kNumSteps; ++i) {
    const auto& h = s.step[static_cast<std::size_t>(i)];
    std::fprintf(out, "%-13s %9.3f %9.3f %9.3f %9.3f %9.3f %9.3f %9llu\n", loop::kSchedule[static_cast<std::size_t>(i)].name,
                 static_cast<double>(loop::kSchedule[static_cast<std::size_t>(i)].budget_us) / 1000.0,
                 ms(h.quantile_ns(0.5)), ms(h.quantile_ns(0.99)), ms(h.quantile_ns(0.999)), ms(h.max_ns()),
                 h.mean_ns() / 1e6, static_cast<unsigned long long>(s.step_overruns[static_cast<std::size_t>(i)]));
  }
  std::fprintf(out, "%-13s %9.3f %9.3f %9.3f %9.3f %9.3f %9.3f %9llu\n", "total", ms(executive.cycle_budget_ns()),
               ms(s.total.quantile_ns(0.5)), ms(s.total.quantile_ns(0.99)), ms(s.total.quantile_ns(0.999)),
               ms(s.total.max_ns()), s.total.mean_ns() / 1e6, static_cast<unsigned long long>(s.cycle_overruns));
}

void print_summary(std::FILE* out, const loop::Executive& executive) noexcept {
  const loop::LoopStats& s = executive.stats();
  const std::uint64_t camera_cycles = s.status[0] + s.status[1] + s.status[2] + s.status[3];
  std::fprintf(out, "cycles %llu, frames %llu, dropped frames %llu, not ready %llu\n",
               static_cast<unsigned long long>(s.cycles), static_cast<unsigned long long>(s.frames),
               static_cast<unsigned long long>(s.frame_errors), static_cast<unsigned long long>(s.not_ready));
  std::fprintf(out, "estimates: valid %llu, degraded %llu, held %llu, invalid %llu (valid share %.1f %%)\n",
               static_cast<unsigned long long>(s.status[0]), static_cast<unsigned long long>(s.status[1]),
               static_cast<unsigned long long>(s.status[2]), static_cast<unsigned long long>(s.status[3]),
               camera_cycles > 0U ? 100.0 * static_cast<double>(s.status[0]) / static_cast<double>(camera_cycles) : 0.0);
  std::fprintf(out, "priors: encoder %llu, temporal %llu, generic %llu; track drops %llu\n",
               static_cast<unsigned long long>(s.prior[2]), static_cast<unsigned long long>(s.prior[1]),
               static_cast<unsigned long long>(s.prior[0]), static_cast<unsigned long long>(s.track_drops));
  std::fprintf(out, "published %llu (errors %llu); camera lost %llu / recovered %llu; bus lost %llu / recovered %llu\n",
               static_cast<unsigned long long>(s.published), static_cast<unsigned long long>(s.publish_errors),
               static_cast<unsigned long long>(s.camera_lost_events), static_cast<unsigned long long>(s.camera_recoveries),
               static_cast<unsigned long long>(s.bus_lost_events), static_cast<unsigned long long>(s.bus_recoveries));
  std::fprintf(out, "overruns %llu (cycle budget %.2f ms), slips %llu\n",
               static_cast<unsigned long long>(s.cycle_overruns), ms(executive.cycle_budget_ns()),
               static_cast<unsigned long long>(s.slips));
  print_steps(out, executive);
  if (s.latency.count() > 0U) {
    std::fprintf(out, "latency frame -> CAN send (ms): p50 %.3f, p99 %.3f, p99.9 %.3f, max %.3f\n",
                 ms(s.latency.quantile_ns(0.5)), ms(s.latency.quantile_ns(0.99)), ms(s.latency.quantile_ns(0.999)),
                 ms(s.latency.max_ns()));
  }
  if (s.send_offset.count() > 0U) {
    // Period and SYNC triggers publish at the tick: this is the send jitter
    // (docs/loop.md "Measured"); with the frame trigger it includes the cycle.
    std::fprintf(out, "CAN send - trigger (us): p50 %.1f, p99 %.1f, p99.9 %.1f, max %.1f (n %llu)\n",
                 static_cast<double>(s.send_offset.quantile_ns(0.5)) / 1e3,
                 static_cast<double>(s.send_offset.quantile_ns(0.99)) / 1e3,
                 static_cast<double>(s.send_offset.quantile_ns(0.999)) / 1e3,
                 static_cast<double>(s.send_offset.max_ns()) / 1e3,
                 static_cast<unsigned long long>(s.send_offset.count()));
  }
}

}  // namespace cli
}  // namespace tcpest
