// tcpest estimate: feature extraction and the pose solver on image files.
// Consecutive images are a sequence (the temporal priors of stage 2 apply);
// a bad image gets an error line and the run goes on.
#include <cstdio>
#include <cstring>
#include <vector>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/setup.hpp"
#include "cli/vision_run.hpp"
#include "tcpest/can_iface/node.hpp"
#include "tcpest/common/json_escape.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/render/image_io.hpp"

namespace tcpest {
namespace cli {
namespace {

const OptionSpec kSpecs[] = {
    kCalibOption,
    kInstrumentConfigOption,
    {"colors", "MODEL.json", "colour model (tcpest train-colors); default: the built-in model"},
    {"prior", "LAMBDA,PHI,THETA", "encoder joints (mm, rad, rad) for every image: stage-2 priors and solver start"},
    {"fixed-model", nullptr, "estimate lambda, phi, theta only (channel pose held at its nominal value)"},
    kGuidedRoundsOption,
    kDenseOption,
    {"overlay", "DIR", "write DIR/<image name>.overlay.jpg: borders, corners, model at the estimate, TCP"},
    {"json", nullptr, "one JSON object per image and line"},
    {"can-log", "FILE",
     "write the TCP and JOINTS frames the loop's CAN node sends for each image (candump log, 40 ms apart; "
     "an image without an estimate: status invalid)"},
};
constexpr std::size_t kSpecCount = sizeof kSpecs / sizeof kSpecs[0];

const char* base_name(const char* path) noexcept {
  const char* slash = std::strrchr(path, '/');
  return slash == nullptr ? path : slash + 1;
}

// The readable line of one estimate (without --json).
void print_estimate_line(const char* path, const EstimateResult& result, const vision::Extraction& e) {
  std::printf("%s: %s, %d corners%s%s", path, to_string(result.status), e.corner_count,
              result.extraction_ok ? "" : " (", result.extraction_ok ? "" : result.extraction_error);
  if (!result.extraction_ok) {
    std::printf(")");
  }
  if (result.status != solver::EstimateQuality::None) {
    std::printf(", TCP [%.2f, %.2f, %.2f] mm, rms %.3f px, %d iterations", result.tcp.x(), result.tcp.y(),
                result.tcp.z(), result.summary.rms_px, result.summary.iterations);
  }
  std::printf(", %.0f us\n", result.total_us);
}

// The overlay directory (--overlay) created, and an encoder for frames of
// the extractor's largest size; false after printing an error.
bool open_overlay(const char* overlay_dir, const EstimatePipeline& pipeline,
                  std::unique_ptr<render::JpegEncoder>& encoder) {
  if (!make_directory(overlay_dir)) {
    std::fprintf(stderr, "tcpest estimate: cannot create the overlay directory %s\n", overlay_dir);
    return false;
  }
  const vision::RegionsConfig& frames = pipeline.extractor().config().regions;
  auto created = render::JpegEncoder::create(frames.max_width, frames.max_height);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest estimate: JPEG encoder: %s\n", render::to_string(created.error()));
    return false;
  }
  encoder = std::move(created.value());
  return true;
}

// What the images of one run share.
struct EstimateRun {
  const ModelSetup& setup;
  EstimatePipeline& pipeline;
  ImageReader& reader;
  std::vector<std::uint8_t>& pixels;
  render::JpegEncoder* encoder;  // nullptr: no overlay
  const char* overlay_dir;
  const double* prior;  // the encoders' joints for every image (nullptr: none)
  bool json;
  hal::CandumpLogWriter* can_log;  // nullptr: no --can-log
  can::Node* node;                 // the node behind --can-log (operational, no heartbeat)
  std::uint32_t index;             // of the image in the sequence
  int can_log_errors;
};

// The estimate's TCP and JOINTS frames from the CAN node the loop runs
// (encoding, status and alive counter its own): what `tcpest run` sends for
// the same frame with the same prior.
void log_can_frames(EstimateRun& run, const EstimateResult& result) {
  can::Estimate estimate;
  if (result.status == solver::EstimateQuality::Valid || result.status == solver::EstimateQuality::Degraded) {
    estimate.status = result.status == solver::EstimateQuality::Valid ? can::EstimateStatus::kValid
                                                                      : can::EstimateStatus::kDegraded;
    estimate.tcp_x_mm = result.tcp.x();
    estimate.tcp_y_mm = result.tcp.y();
    estimate.tcp_z_mm = result.tcp.z();
    estimate.lambda_mm = result.r[solver::kLambda];
    estimate.phi_rad = result.r[solver::kPhi];
    estimate.theta_rad = result.r[solver::kTheta];
  }
  const std::int64_t t_us = static_cast<std::int64_t>(run.index) * 40000;  // 25 Hz
  can::TxBatch batch;
  if (!run.node->publish(estimate).ok() || !run.node->collect(t_us, batch).ok()) {
    ++run.can_log_errors;
    return;
  }
  const std::uint8_t node_id = run.node->config().node_id;
  for (const can::Frame& frame : batch) {
    const bool pdo = frame.id == can::tcp_id(node_id) || frame.id == can::joints_id(node_id);
    if (pdo && !run.can_log->write(frame, t_us).ok()) {
      ++run.can_log_errors;
    }
  }
}

// An image that gives no estimate: its JSON line (the name escaped, a
// longer one cut at a character, never mid-escape), and for the sequence a
// failed frame, as the loop counts a dropped one.
void refuse_image(EstimateRun& run, const char* path, const char* reason) {
  run.pipeline.frame_failed();
  if (run.can_log != nullptr) {
    log_can_frames(run, EstimateResult{});
  }
  if (run.json) {
    char image[4096];
    static_cast<void>(json::escape_string(path, image, sizeof image));  // cut when longer: still valid JSON
    std::printf("{\"image\": \"%s\", \"status\": \"none\", \"error\": \"%s\"}\n", image, reason);
  }
}

// One image: read, estimated and reported (a line, or a JSON object), its
// overlay written. False when the image cannot be read or its size is not
// the calibration's (reported; the run goes on).
bool estimate_image(EstimateRun& run, const char* path) {
  char error[256];
  ImageView view;
  if (!run.reader.read(path, run.pixels, view, error, sizeof error)) {
    std::fprintf(stderr, "tcpest estimate: %s: %s\n", path, error);
    refuse_image(run, path, "unreadable image");
    return false;
  }
  if (view.width != run.setup.camera.width() || view.height != run.setup.camera.height()) {
    std::fprintf(stderr, "tcpest estimate: %s: image is %dx%d, the calibration %dx%d\n", path, view.width,
                 view.height, run.setup.camera.width(), run.setup.camera.height());
    refuse_image(run, path, "image size differs from calibration");
    return false;
  }
  const EstimateResult result = run.pipeline.process(view, run.prior);
  if (run.can_log != nullptr) {
    log_can_frames(run, result);
  }
  const vision::Extraction& e = run.pipeline.extractor().result();
  if (run.json) {
    char line[4096];
    format_estimate_json(path, result, e, line, sizeof line);
    std::printf("%s\n", line);
  } else {
    print_estimate_line(path, result, e);
  }
  if (run.encoder != nullptr) {
    run.pipeline.draw_overlay(result, MutableImageView{run.pixels.data(), view.width, view.height, view.stride_bytes});
    char out_path[1024];
    static_cast<void>(std::snprintf(out_path, sizeof out_path, "%s/%s.overlay.jpg", run.overlay_dir,  // checked below
                                    base_name(path)));
    const auto written = run.encoder->write_file(view, 90, out_path);
    if (!written.ok()) {
      std::fprintf(stderr, "tcpest estimate: %s: %s\n", out_path, render::to_string(written.error()));
    }
  }
  return true;
}

}  // namespace

int cmd_estimate(int argc, char** argv) {
  Args args;
  char error[256];
  if (!args.parse(argc, argv, 1, kSpecs, kSpecCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest estimate: %s\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest estimate --calib CAM.yaml [--config CFG] [--colors MODEL] [--prior LAMBDA,PHI,THETA] "
                "[--fixed-model] [--guided-rounds N] [--dense] [--overlay DIR] [--json] "
                "[--can-log FILE] IMAGE...",
                "Extracts the labelled apparent corners of each image (JPEG or PPM) and solves the pose.",
                kSpecs, kSpecCount);
    return kExitOk;
  }
  if (args.positional_count() == 0U) {
    std::fprintf(stderr, "tcpest estimate: no image given (see --help)\n");
    return kExitUsage;
  }
  double prior[3] = {0.0, 0.0, 0.0};
  const bool has_prior = args.value("prior") != nullptr;
  if (has_prior && !parse_number_list(args.value("prior"), prior, 3U)) {
    std::fprintf(stderr, "tcpest estimate: --prior needs three numbers LAMBDA,PHI,THETA\n");
    return kExitUsage;
  }
  ModelSetup setup;
  static EstimatePipeline pipeline;  // large: static storage
  int exit_code = kExitOk;
  if (!init_pipeline_from_args("estimate", args, setup, pipeline, exit_code)) {
    return exit_code;
  }
  ImageReader reader;
  const vision::RegionsConfig& frames = pipeline.extractor().config().regions;
  if (!reader.init(frames.max_width, frames.max_height)) {
    std::fprintf(stderr, "tcpest estimate: JPEG decoder initialisation failed\n");
    return kExitFailure;
  }
  const char* overlay_dir = args.value("overlay");
  std::unique_ptr<render::JpegEncoder> encoder;
  if (overlay_dir != nullptr && !open_overlay(overlay_dir, pipeline, encoder)) {
    return kExitFailure;
  }
  static hal::CandumpLogWriter can_log;  // large buffer: static storage
  can::Node node;
  const char* can_log_path = args.value("can-log");
  if (can_log_path != nullptr) {
    can::NodeConfig node_config;
    node_config.node_id = pipeline.config().can.node_id;
    node_config.heartbeat_period_us = 0;
    node_config.start_operational = true;
    can::TxBatch boot;
    if (!node.configure(node_config).ok() || !node.collect(0, boot).ok()) {  // the boot-up is not logged
      std::fprintf(stderr, "tcpest estimate: --can-log: can.node_id %u refused\n", node_config.node_id);
      return kExitConfig;
    }
    const auto opened = can_log.open(can_log_path, "est");
    if (!opened.ok()) {
      std::fprintf(stderr, "tcpest estimate: --can-log %s: %s\n", can_log_path, hal::to_string(opened.error()));
      return kExitFailure;
    }
  }
  std::vector<std::uint8_t> pixels;
  EstimateRun run{setup, pipeline, reader, pixels, encoder.get(), overlay_dir, has_prior ? prior : nullptr,
                  args.flag("json"), can_log_path != nullptr ? &can_log : nullptr, &node, 0U, 0};
  int failures = 0;
  for (std::size_t i = 0U; i < args.positional_count(); ++i) {
    run.index = static_cast<std::uint32_t>(i);
    failures += estimate_image(run, args.positional(i)) ? 0 : 1;
    static_cast<void>(std::fflush(stdout));  // one line per image, as it comes
  }
  if (can_log_path != nullptr && (!can_log.close().ok() || run.can_log_errors > 0)) {
    std::fprintf(stderr, "tcpest estimate: --can-log %s: writing failed\n", can_log_path);
    return kExitFailure;
  }
  return failures == 0 ? kExitOk : kExitFailure;
}

}  // namespace cli
}  // namespace tcpest
