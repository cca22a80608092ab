// tcpest demo: the whole product on a synthetic scene, no hardware needed.
// Renders a motion sequence with the built-in camera (hal/render), runs the
// real loop on it at 25 Hz (vision, solver, CAN node), publishing on vcan0 if
// it exists, else on the in-process simulated bus; a simulated robot sends
// NMT start and its encoder readings (ENCODER_PRIOR). At the end: accuracy
// against the ground truth and timing, and in DIR: can.log (candump format),
// cycles.csv, overlays/*.png, tcp.svg (estimate vs truth), latency.svg.
#include <net/if.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#include "cli/args.hpp"
#include "cli/cycle_overlay.hpp"
#include "cli/cycles_csv.hpp"
#include "cli/commands.hpp"
#include "cli/joint_errors.hpp"
#include "cli/loop_rig.hpp"
#include "cli/setup.hpp"
#include "tcpest/can_iface/e2e.hpp"
#include "tcpest/can_iface/messages.hpp"
#include "tcpest/can_iface/receiver.hpp"
#include "tcpest/render/image_io.hpp"

namespace tcpest {
namespace cli {

namespace {

constexpr OptionSpec kOptions[] = {
    {"out", "DIR", "output directory (default ./tcpest-demo)"},
    {"config", "CFG.yaml", "configuration (instrument and loop:/can:/rt: sections); default: built-in"},
    kCalibOption,
    {"frames", "N", "frames of the sequence (default 250: 10 s at 25 Hz)"},
    {"seed", "S", "seed of the motion sequence and the rendering (default 7)"},
    {"bus", "BUS", "vcan0 | IFACE | sim (default: vcan0 if it exists, else the simulated bus)"},
    {"overlay-every", "N", "write an overlay every N frames (default 25; 0 = none)"},
};
constexpr std::size_t kOptionCount = sizeof kOptions / sizeof kOptions[0];

struct Sample {
  double t_s = 0.0;
  int status = 3;
  bool solved = false;
  double est[3] = {0.0, 0.0, 0.0};
  double truth[3] = {0.0, 0.0, 0.0};
  bool truth_valid = false;
  solver::PoseVector est_r = solver::PoseVector::Zero();    // what MECHANICAL and JOINTS carried
  solver::PoseVector truth_r = solver::PoseVector::Zero();
  double latency_ms = -1.0;
  double total_ms = 0.0;
};

// The robot's side of the bus: NMT start, then an ENCODER_PRIOR per frame;
// what the estimator sends goes through the controllers' reference receiver.
class Robot {
 public:
  Robot(hal::CanBus& bus, std::uint8_t node_id) noexcept : bus_(bus), node_id_(node_id) {
    can::ReceiverConfig config;
    config.node_id = node_id;
    static_cast<void>(rx_.configure(config));  // the loop's node ID, already validated
  }
  void start_node() noexcept {
    can::Frame f;
    if (can::encode_nmt(can::NmtMessage{can::NmtCommand::kStart, node_id_}, f).ok()) {
      count(bus_.send(f).ok());
    }
  }
  void send_prior(const loop::JointPrior& j) noexcept {
    can::EncoderPriorMessage m;
    m.lambda_mm = j.lambda_mm;
    m.phi_rad = j.phi_rad;
    m.theta_rad = j.theta_rad;
    m.status = can::EstimateStatus::kValid;
    m.counter = counter_.take();
    can::Frame f;
    if (can::encode_encoder_prior(node_id_, m, f).ok()) {
      count(bus_.send(f).ok());
    }
  }
  // Reads what the estimator sent (the simulated bus's queue must not overflow).
  void drain() noexcept {
    std::array<hal::ReceivedFrame, 64> rx{};
    for (int i = 0; i < 8; ++i) {
      const auto got = bus_.receive(rx.data(), rx.size());
      if (!got.ok() || got.value() == 0U) {
        break;
      }
      received_ += got.value();
      for (std::size_t k = 0U; k < got.value(); ++k) {
        static_cast<void>(rx_.receive(rx[k].frame, rx[k].timestamp_us));  // refusals are counted in rx_
      }
    }
  }
  std::uint64_t received() const noexcept { return received_; }
  const can::Receiver& receiver() const noexcept { return rx_; }
  std::uint64_t send_failures() const noexcept { return failures_; }

 private:
  void count(bool ok) noexcept { failures_ += ok ? 0U : 1U; }
  hal::CanBus& bus_;
  std::uint8_t node_id_;
  can::AliveCounter counter_{};
  can::Receiver rx_{};
  std::uint64_t received_ = 0U;
  std::uint64_t failures_ = 0U;
};

class DemoObserver final : public loop::CycleObserver {
 public:
  DemoObserver(LoopRig& rig, Robot& robot, std::FILE* csv, const char* overlay_dir, int overlay_every,
               std::vector<Sample>& samples) noexcept
      : rig_(rig), robot_(robot), csv_(csv), overlay_dir_(overlay_dir), overlay_every_(overlay_every),
        samples_(samples) {}

  bool csv_failed() const noexcept { return csv_failed_; }

  bool init() noexcept {
    const int w = rig_.models.camera.width();
    const int h = rig_.models.camera.height();
    overlay_.reset(new (std::nothrow) std::uint8_t[static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3U]);
    auto encoder = render::JpegEncoder::create(w, h);
    if (!overlay_ || !encoder.ok()) {
      return false;
    }
    encoder_ = std::move(encoder.value());
    return write_cycles_csv_header(csv_, true);
  }

  void on_cycle(const loop::CycleRecord& r, const ImageView& frame) noexcept override {
    robot_.drain();
    if (rig_.sim != nullptr && rig_.sim->next_index() < rig_.sim->frame_count()) {
      robot_.send_prior(rig_.sim->encoder_reading(rig_.sim->next_index()));
    }
    if (!r.have_frame && r.frame_error == hal::CameraError::kNone) {
      return;
    }
    if (t0_ns_ < 0) {
      t0_ns_ = r.trigger_ns;
    }
    const loop::Publication& p = r.publication;
    // The frame's truth, beside the loop: the simulated source's.
    const hal::FrameTruth truth =
        r.have_frame && rig_.sim != nullptr ? rig_.sim->last_truth() : hal::FrameTruth{};
    // A refused row is reported once, with the outputs, at the end.
    csv_failed_ = !write_cycles_csv_row(csv_, r, &truth, true, t0_ns_) || csv_failed_;
    // The cycle that finds the sequence ended has its row, but it is not a
    // frame: the accuracy counts frames (a dropped frame is one, without an
    // estimate).
    if (!r.have_frame && r.frame_error == hal::CameraError::kEndOfStream) {
      return;
    }
    if (samples_.size() < samples_.capacity()) {
      Sample s;
      s.t_s = ms(r.trigger_ns - t0_ns_) / 1000.0;
      s.status = static_cast<int>(p.status);
      s.solved = r.solved;
      for (std::size_t i = 0; i < 3U; ++i) {
        s.est[i] = p.tcp_mm[i];
        s.truth[i] = truth.tcp_mm[i];
      }
      s.truth_valid = truth.valid;
      s.est_r = p.r;
      for (std::size_t i = 0; i < truth.r.size(); ++i) {
        s.truth_r[static_cast<Eigen::Index>(i)] = truth.r[i];
      }
      s.latency_ms = r.latency_ns >= 0 ? ms(r.latency_ns) : -1.0;
      s.total_ms = ms(r.total_ns);
      samples_.push_back(s);
    }
    if (r.have_frame && overlay_every_ > 0 && r.frame_sequence % static_cast<std::uint32_t>(overlay_every_) == 0U) {
      write_overlay(r, truth, frame);
    }
  }

 private:
  void write_overlay(const loop::CycleRecord& r, const hal::FrameTruth& truth, const ImageView& frame) noexcept {
    const MutableImageView out{overlay_.get(), frame.width, frame.height, static_cast<std::size_t>(frame.width) * 3U};
    draw_cycle_overlay(out, frame, rig_.vision != nullptr ? &rig_.vision->extractor().result() : nullptr, rig_.models,
                       r, &truth);
    char path[512];
    static_cast<void>(std::snprintf(path, sizeof path, "%s/frame_%04u.png", overlay_dir_, r.frame_sequence));  // short paths
    if (!render::write_png_file(out.view(), path).ok()) {
      std::fprintf(stderr, "tcpest demo: could not write %s\n", path);
    }
  }

  LoopRig& rig_;
  Robot& robot_;
  std::FILE* csv_;
  const char* overlay_dir_;
  int overlay_every_;
  std::vector<Sample>& samples_;
  std::unique_ptr<std::uint8_t[]> overlay_;
  std::unique_ptr<render::JpegEncoder> encoder_;
  std::int64_t t0_ns_ = -1;
  bool csv_failed_ = false;  // a row the stream refused
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) {
    return 0.0;
  }
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1U)));
  return v[std::min(i, v.size() - 1U)];
}

// TCP estimate against truth, one panel per axis.
bool write_tcp_svg(const char* path, const std::vector<Sample>& samples) {
  std::FILE* f = std::fopen(path, "w");
  if (f == nullptr) {
    return false;
  }
  const double width = 900.0;
  const double panel_h = 200.0;
  const double left = 70.0;
  const double right = 20.0;
  const double top = 40.0;
  const double gap = 40.0;
  const double height = top + 3.0 * (panel_h + gap) + 20.0;
  double t_max = 0.0;
  for (const Sample& s : samples) {
    t_max = std::max(t_max, s.t_s);
  }
  t_max = std::max(t_max, 1e-3);
  std::fprintf(f, "<svg xmlns='http://www.w3.org/2000/svg' width='%.0f' height='%.0f' font-family='sans-serif' font-size='12'>\n",
               width, height);
  std::fprintf(f, "<rect width='100%%' height='100%%' fill='white'/>\n");
  std::fprintf(f, "<text x='%.0f' y='22' font-size='15'>TCP estimate (dots: blue valid, orange degraded) vs ground truth (black line), camera frame</text>\n", left);
  const char* axis_name[3] = {"x (mm)", "y (mm)", "z (mm)"};
  for (int a = 0; a < 3; ++a) {
    double lo = 1e300;
    double hi = -1e300;
    for (const Sample& s : samples) {
      if (s.truth_valid) {
        lo = std::min(lo, s.truth[a]);
        hi = std::max(hi, s.truth[a]);
      }
      if (s.status <= 1) {
        lo = std::min(lo, s.est[a]);
        hi = std::max(hi, s.est[a]);
      }
    }
    if (lo > hi) {
      lo = -1.0;
      hi = 1.0;
    }
    const double pad = std::max(0.5, 0.08 * (hi - lo));
    lo -= pad;
    hi += pad;
    const double y0 = top + a * (panel_h + gap);
    auto px = [&](double t) { return left + (width - left - right) * t / t_max; };
    auto py = [&](double v) { return y0 + panel_h * (1.0 - (v - lo) / (hi - lo)); };
    std::fprintf(f, "<rect x='%.1f' y='%.1f' width='%.1f' height='%.1f' fill='none' stroke='#888'/>\n", left, y0,
                 width - left - right, panel_h);
    std::fprintf(f, "<text x='8' y='%.1f'>%s</text>\n", y0 + panel_h / 2.0, axis_name[a]);
    for (int second = 0; second <= static_cast<int>(t_max); ++second) {
      const double x = px(static_cast<double>(second));
      std::fprintf(f, "<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='#ddd'/>\n", x, y0, x, y0 + panel_h);
      std::fprintf(f, "<text x='%.1f' y='%.1f' text-anchor='middle' fill='#666'>%d</text>\n", x, y0 + panel_h + 14.0,
                   second);
    }
    std::fprintf(f, "<text x='%.1f' y='%.1f' text-anchor='end'>%.1f</text>\n", left - 4.0, y0 + 12.0, hi);
    std::fprintf(f, "<text x='%.1f' y='%.1f' text-anchor='end'>%.1f</text>\n", left - 4.0, y0 + panel_h, lo);
    std::fprintf(f, "<polyline fill='none' stroke='black' stroke-width='1.5' points='");
    for (const Sample& s : samples) {
      if (s.truth_valid) {
        std::fprintf(f, "%.1f,%.1f ", px(s.t_s), py(s.truth[a]));
      }
    }
    std::fprintf(f, "'/>\n");
    for (const Sample& s : samples) {
      if (s.status <= 1) {
        std::fprintf(f, "<circle cx='%.1f' cy='%.1f' r='2.2' fill='%s'/>\n", px(s.t_s), py(s.est[a]),
                     s.status == 0 ? "#1f5fd0" : "#f08a00");
      }
    }
  }
  std::fprintf(f, "<text x='%.1f' y='%.1f' text-anchor='middle'>time (s)</text>\n", width / 2.0, height - 6.0);
  std::fprintf(f, "</svg>\n");
  return std::fclose(f) == 0;
}

// Latency (frame timestamp to CAN send) histogram, 0.25 ms bins.
bool write_latency_svg(const char* path, const std::vector<Sample>& samples) {
  std::vector<double> lat;
  for (const Sample& s : samples) {
    if (s.latency_ms >= 0.0) {
      lat.push_back(s.latency_ms);
    }
  }
  std::FILE* f = std::fopen(path, "w");
  if (f == nullptr) {
    return false;
  }
  const double bin = 0.25;
  const double max_ms = lat.empty() ? 10.0 : std::max(2.0, std::ceil(percentile(lat, 1.0) / bin + 1.0) * bin);
  const std::size_t bins = static_cast<std::size_t>(max_ms / bin) + 1U;
  std::vector<int> counts(bins, 0);
  for (const double v : lat) {
    counts[std::min(bins - 1U, static_cast<std::size_t>(v / bin))] += 1;
  }
  int peak = 1;
  for (const int c : counts) {
    peak = c > peak ? c : peak;
  }
  const double width = 900.0;
  const double height = 360.0;
  const double left = 60.0;
  const double bottom = 50.0;
  const double top = 40.0;
  const double plot_w = width - left - 20.0;
  const double plot_h = height - top - bottom;
  std::fprintf(f, "<svg xmlns='http://www.w3.org/2000/svg' width='%.0f' height='%.0f' font-family='sans-serif' font-size='12'>\n",
               width, height);
  std::fprintf(f, "<rect width='100%%' height='100%%' fill='white'/>\n");
  std::fprintf(f, "<text x='%.0f' y='22' font-size='15'>Latency, frame timestamp to CAN send: %zu cycles, p50 %.2f ms, p99 %.2f ms, max %.2f ms</text>\n",
               left, lat.size(), percentile(lat, 0.5), percentile(lat, 0.99), percentile(lat, 1.0));
  for (std::size_t b = 0; b < bins; ++b) {
    const double h = plot_h * counts[b] / peak;
    std::fprintf(f, "<rect x='%.1f' y='%.1f' width='%.1f' height='%.1f' fill='#1f5fd0'/>\n",
                 left + plot_w * static_cast<double>(b) / static_cast<double>(bins), top + plot_h - h,
                 std::max(1.0, plot_w / static_cast<double>(bins) - 1.0), h);
  }
  std::fprintf(f, "<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='black'/>\n", left, top + plot_h, left + plot_w,
               top + plot_h);
  for (int tick = 0; tick <= 10; ++tick) {
    const double v = max_ms * tick / 10.0;
    std::fprintf(f, "<text x='%.1f' y='%.1f' text-anchor='middle'>%.1f</text>\n", left + plot_w * tick / 10.0,
                 top + plot_h + 16.0, v);
  }
  std::fprintf(f, "<text x='%.1f' y='%.1f' text-anchor='middle'>latency (ms)</text>\n", left + plot_w / 2.0, height - 10.0);
  std::fprintf(f, "<text x='12' y='%.1f'>cycles (max %d)</text>\n", top + 12.0, peak);
  std::fprintf(f, "</svg>\n");
  return std::fclose(f) == 0;
}

// The longest sequence the demo renders (and so the largest overlay period).
constexpr unsigned long long kMaxDemoFrames = 100000U;

// The demo's options.
struct DemoOptions {
  const char* out_dir = "tcpest-demo";
  unsigned long long frames = 250U;
  unsigned long long seed = 7U;
  unsigned long long overlay_every = 25U;
};

// --out, --frames, --seed and --overlay-every. Returns kExitOk or kExitUsage
// (reported).
int parse_demo_options(const Args& args, DemoOptions& o) noexcept {
  o.out_dir = args.value("out") != nullptr ? args.value("out") : "tcpest-demo";
  if (!unsigned_option(args, "demo", "frames", 1U, kMaxDemoFrames, o.frames) ||
      !unsigned_option(args, "demo", "seed", 0U, ~0ULL, o.seed) ||
      !unsigned_option(args, "demo", "overlay-every", 0U, kMaxDemoFrames, o.overlay_every)) {
    return kExitUsage;
  }
  return kExitOk;
}

// The files the demo writes into its output directory.
struct DemoPaths {
  char overlay_dir[512] = {};
  char log_path[512] = {};
  char csv_path[512] = {};
  char tcp_svg[512] = {};
  char latency_svg[512] = {};
};

// The output paths under `out_dir`, and the directories (out_dir and its
// overlays/). Returns kExitOk or kExitConfig (reported).
int make_demo_paths(const char* out_dir, DemoPaths& p) noexcept {
  static_cast<void>(std::snprintf(p.overlay_dir, sizeof p.overlay_dir, "%s/overlays", out_dir));  // paths under 512 bytes
  static_cast<void>(std::snprintf(p.log_path, sizeof p.log_path, "%s/can.log", out_dir));
  static_cast<void>(std::snprintf(p.csv_path, sizeof p.csv_path, "%s/cycles.csv", out_dir));
  static_cast<void>(std::snprintf(p.tcp_svg, sizeof p.tcp_svg, "%s/tcp.svg", out_dir));
  static_cast<void>(std::snprintf(p.latency_svg, sizeof p.latency_svg, "%s/latency.svg", out_dir));
  if (!make_directory(out_dir) || !make_directory(p.overlay_dir)) {
    std::fprintf(stderr, "tcpest demo: cannot create %s: %s\n", out_dir, std::strerror(errno));
    return kExitConfig;
  }
  return kExitOk;
}

// Loads the rig for the demo: configuration and models, the loop's settings
// for a frame-triggered paced run, the simulated camera with this seed, the
// bus (logged to `log_path`) and the loop. Returns kExitOk, else the exit
// code (reported).
int load_demo_rig(const RigRequest& request, const DemoOptions& o, const char* log_path, LoopRig& rig) noexcept {
  int code = rig.load(request);
  if (code != kExitOk) {
    return code;
  }
  rig.config.loop.trigger = loop::Trigger::kFrame;
  rig.config.loop.pacing = true;
  rig.config.loop.replay_loop = false;
  rig.config.loop.frames = 0U;
  rig.config.can.start_operational = false;  // the simulated robot starts the node, as the real one would
  std::printf("tcpest demo: rendering %llu frames of a motion sequence (seed %llu) ...\n", o.frames, o.seed);
  // The simulated camera, with this seed.
  {
    loop::PrerenderOptions options;
    options.frames = static_cast<std::uint32_t>(o.frames);
    options.seed = o.seed;
    options.loop = false;
    auto created = loop::PrerenderedSource::create(rig.models.camera, rig.models.instrument, options);
    if (!created.ok()) {
      std::fprintf(stderr, "tcpest demo: simulated camera: %s\n", hal::to_string(created.error()));
      return kExitFailure;
    }
    rig.sim = created.value().get();
    rig.source = std::move(created.value());
  }
  code = rig.open_bus(log_path);
  if (code == kExitOk) {
    code = rig.build();
  }
  return code;
}

// The robot's bus: the other endpoint of the simulated bus, or `socket`
// opened on the interface `bus`. nullptr (reported) if it cannot be opened.
hal::CanBus* open_robot_bus(LoopRig& rig, const char* bus, hal::SocketCanBus& socket) noexcept {
  if (rig.sim_bus) {
    return &rig.sim_bus->endpoint(1);
  }
  hal::SocketCanConfig sc;
  const std::uint32_t ids[] = {can::tcp_id(rig.config.can.node_id), can::heartbeat_id(rig.config.can.node_id)};
  for (const std::uint32_t id : ids) {
    static_cast<void>(sc.rx_ids.push_back(id));  // 2 of 16
  }
  if (!socket.open(bus, sc).ok()) {
    std::fprintf(stderr, "tcpest demo: cannot open %s for the simulated robot\n", bus);
    return nullptr;
  }
  return &socket;
}

// Prints the accuracy of the estimates (valid or degraded) against the
// ground truth: share of frames, 3-D error and per-axis error (mm).
void print_accuracy(const std::vector<Sample>& samples) {
  std::vector<double> err3;
  std::vector<double> err_axis[3];
  std::size_t estimated = 0U;
  JointErrors joints;
  for (const Sample& s : samples) {
    if (s.status <= 1 && s.truth_valid) {
      ++estimated;
      joints.add(s.est_r, s.truth_r);
      double e2 = 0.0;
      for (int a = 0; a < 3; ++a) {
        const double d = s.est[a] - s.truth[a];
        err_axis[a].push_back(std::fabs(d));
        e2 += d * d;
      }
      err3.push_back(std::sqrt(e2));
    }
  }
  std::printf("\n== accuracy (TCP, camera frame, against the renderer's ground truth)\n");
  std::printf("frames %zu, with an estimate (valid or degraded) %zu (%.1f %%)\n", samples.size(), estimated,
              samples.empty() ? 0.0 : 100.0 * static_cast<double>(estimated) / static_cast<double>(samples.size()));
  if (!err3.empty()) {
    std::printf("3-D error (mm): median %.2f, p95 %.2f, max %.2f\n", percentile(err3, 0.5), percentile(err3, 0.95),
                percentile(err3, 1.0));
    std::printf("per axis, median |error| (mm): x %.2f, y %.2f, z %.2f\n", percentile(err_axis[0], 0.5),
                percentile(err_axis[1], 0.5), percentile(err_axis[2], 0.5));
    char line[320];
    joints.format("joints sent (JOINTS): ", line, sizeof line);
    std::printf("%s\n", line);
  }
}

// The report after the run: accuracy, timing, what the robot received, the
// plots (tcp.svg, latency.svg) and the list of outputs. False if a plot could
// not be written.
bool report_run(const LoopRig& rig, const Robot& robot, const std::vector<Sample>& samples,
                const DemoPaths& paths) {
  // Accuracy against the ground truth.
  print_accuracy(samples);
  std::printf("\n== timing\n");
  print_summary(stdout, *rig.executive);
  const can::ReceiverCounters& rx = robot.receiver().counters();
  std::printf("robot side: %llu frames received from the estimator, decoded %u, E2E failures %u, counter jumps %u, "
              "stale events %u\n",
              static_cast<unsigned long long>(robot.received()), rx.decoded, rx.e2e_failures, rx.counter_jumps,
              rx.stale_events);
  const bool svg_ok = write_tcp_svg(paths.tcp_svg, samples) && write_latency_svg(paths.latency_svg, samples);
  std::printf("\nwritten: %s, %s, %s, %s, %s/\n", paths.log_path, paths.csv_path, paths.tcp_svg, paths.latency_svg,
              paths.overlay_dir);
  return svg_ok;
}

}  // namespace

int cmd_demo(int argc, char** argv) {
  auto args_owner = std::make_unique<Args>();  // large (positional table): not on the stack
  Args& args = *args_owner;
  char error[256];
  if (!args.parse(argc, argv, 1, kOptions, kOptionCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest demo: %s (see --help)\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest demo [--out DIR]",
                "Renders a synthetic motion sequence with the built-in camera and runs the real loop on it at 25 Hz\n"
                "(about 10 s), on vcan0 if it exists, else on the in-process simulated bus. Prints the accuracy\n"
                "against the ground truth and the timing; writes can.log, cycles.csv, overlays/, tcp.svg and\n"
                "latency.svg into DIR.",
                kOptions, kOptionCount);
    return kExitOk;
  }
  if (args.positional_count() != 0U) {
    std::fprintf(stderr, "tcpest demo: unexpected argument '%s' (see --help)\n", args.positional(0));
    return kExitUsage;
  }
  DemoOptions options;
  int code = parse_demo_options(args, options);
  if (code != kExitOk) {
    return code;
  }
  DemoPaths paths;
  code = make_demo_paths(options.out_dir, paths);
  if (code != kExitOk) {
    return code;
  }

  const bool have_vcan = ::if_nametoindex("vcan0") != 0U;
  const char* bus = args.value("bus") != nullptr ? args.value("bus") : (have_vcan ? "vcan0" : "sim");
  RigRequest request;
  request.command = "demo";
  request.config_path = args.value("config");
  request.calib_path = args.value("calib");
  request.source = "sim";
  request.bus = bus;
  request.sim_frames = static_cast<std::uint32_t>(options.frames);
  const std::atomic<bool>* stop = install_stop_signals();
  auto rig_owner = std::make_unique<LoopRig>();  // the loop's buffers: allocated once, here
  LoopRig& rig = *rig_owner;
  code = load_demo_rig(request, options, paths.log_path, rig);
  if (code != kExitOk) {
    return code;
  }
  // The robot: the other endpoint of the simulated bus, or its own socket on the interface.
  hal::SocketCanBus robot_socket;
  hal::CanBus* robot_bus = open_robot_bus(rig, bus, robot_socket);
  if (robot_bus == nullptr) {
    return kExitFailure;
  }
  Robot robot(*robot_bus, rig.config.can.node_id);
  std::FILE* csv = std::fopen(paths.csv_path, "w");
  if (csv == nullptr) {
    std::fprintf(stderr, "tcpest demo: cannot write %s: %s\n", paths.csv_path, std::strerror(errno));
    return kExitConfig;
  }
  std::vector<Sample> samples;
  samples.reserve(static_cast<std::size_t>(options.frames) + 16U);
  DemoObserver observer(rig, robot, csv, paths.overlay_dir, static_cast<int>(options.overlay_every), samples);
  if (!observer.init()) {
    std::fclose(csv);
    return kExitFailure;
  }
  rig.executive->set_observer(&observer);
  std::printf("tcpest demo: running the loop at 25 Hz on %s (vision, solver, CAN node 0x%02X) ...\n", rig.bus_label,
              static_cast<unsigned>(rig.config.can.node_id));
  // The node boots (boot-up message), the robot starts it, the first prior goes out.
  static_cast<void>(rig.node->receive(rig.clock.now_ns()));  // a bus fault here shows in the first cycle again
  robot.start_node();
  robot.send_prior(rig.sim->encoder_reading(0U));
  const loop::CycleOutcome outcome = rig.executive->run(stop);
  robot.drain();
  const bool csv_ok = std::fclose(csv) == 0 && !observer.csv_failed();
  const bool svg_ok = report_run(rig, robot, samples, paths);
  const bool log_ok = rig.finish_log(stdout);
  if (!csv_ok || !svg_ok || !log_ok) {
    std::fprintf(stderr, "tcpest demo: some outputs could not be written\n");
    return kExitFailure;
  }
  return outcome == loop::CycleOutcome::kInterrupted ? kExitInterrupted : kExitOk;
}

}  // namespace cli
}  // namespace tcpest
