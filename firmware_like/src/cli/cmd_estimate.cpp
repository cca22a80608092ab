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
    kFallbackSeedsOption,
    {"overlay", "DIR", "write DIR/<image name>.overlay.jpg: borders, corners, model at the estimate, TCP"},
    {"json", nullptr, "one JSON object per image and line"},
};
constexpr std::size_t kSpecCount = sizeof kSpecs / sizeof kSpecs[0];

const char* base_name(const char* path) noexcept {
  const char* slash = std::strrchr(path, '/');
  return slash == nullptr ? path : slash + 1;
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
                "[--fixed-model] [--guided-rounds N] [--fallback-seeds N] [--overlay DIR] [--json] IMAGE...",
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
  if (!load_model_setup("estimate", args.value("calib"), args.value("config"), setup)) {
    return kExitConfig;
  }
  vision::ColorModel colors;
  if (!load_color_model("estimate", args.value("colors"), colors)) {
    return kExitConfig;
  }
  static EstimatePipeline pipeline;  // large: static storage
  if (!pipeline.init("estimate", setup, colors, args.flag("fixed-model"))) {
    return kExitConfig;
  }
  if (!apply_guided_rounds("estimate", args.value("guided-rounds"), pipeline)) {
    return kExitUsage;
  }
  if (!apply_fallback_seeds("estimate", args.value("fallback-seeds"), pipeline)) {
    return kExitUsage;
  }
  ImageReader reader;
  if (!reader.init(pipeline.extractor().config().max_width, pipeline.extractor().config().max_height)) {
    std::fprintf(stderr, "tcpest estimate: JPEG decoder initialisation failed\n");
    return kExitFailure;
  }
  const char* overlay_dir = args.value("overlay");
  std::unique_ptr<render::JpegEncoder> encoder;
  if (overlay_dir != nullptr) {
    if (!make_directory(overlay_dir)) {
      std::fprintf(stderr, "tcpest estimate: cannot create the overlay directory %s\n", overlay_dir);
      return kExitFailure;
    }
    auto created = render::JpegEncoder::create(pipeline.extractor().config().max_width,
                                               pipeline.extractor().config().max_height);
    if (!created.ok()) {
      std::fprintf(stderr, "tcpest estimate: JPEG encoder: %s\n", render::to_string(created.error()));
      return kExitFailure;
    }
    encoder = std::move(created.value());
  }
  const bool json = args.flag("json");
  std::vector<std::uint8_t> pixels;
  int failures = 0;
  for (std::size_t i = 0U; i < args.positional_count(); ++i) {
    const char* path = args.positional(i);
    ImageView view;
    if (!reader.read(path, pixels, view, error, sizeof error)) {
      std::fprintf(stderr, "tcpest estimate: %s: %s\n", path, error);
      if (json) {
        std::printf("{\"image\": \"%s\", \"status\": \"none\", \"error\": \"unreadable image\"}\n", path);
      }
      ++failures;
      continue;
    }
    if (view.width != setup.camera.width() || view.height != setup.camera.height()) {
      std::fprintf(stderr, "tcpest estimate: %s: image is %dx%d, the calibration %dx%d\n", path, view.width,
                   view.height, setup.camera.width(), setup.camera.height());
      if (json) {
        std::printf("{\"image\": \"%s\", \"status\": \"none\", \"error\": \"image size differs from calibration\"}\n",
                    path);
      }
      ++failures;
      continue;
    }
    const EstimateResult result = pipeline.process(view, has_prior ? prior : nullptr);
    const vision::Extraction& e = pipeline.extractor().result();
    if (json) {
      char line[4096];
      format_estimate_json(path, result, e, line, sizeof line);
      std::printf("%s\n", line);
    } else {
      std::printf("%s: %s, %d corners%s%s", path, to_string(result.status), e.corner_count,
                  result.extraction_ok ? "" : " (", result.extraction_ok ? "" : result.extraction_error);
      if (!result.extraction_ok) {
        std::printf(")");
      }
      if (result.status != EstimateStatus::None) {
        std::printf(", TCP [%.2f, %.2f, %.2f] mm, rms %.3f px, %d iterations", result.tcp.x(), result.tcp.y(),
                    result.tcp.z(), result.summary.rms_px, result.summary.iterations);
      }
      std::printf(", %.0f us\n", result.total_us);
    }
    if (encoder != nullptr) {
      pipeline.draw_overlay(result, MutableImageView{pixels.data(), view.width, view.height, view.stride_bytes});
      char out_path[1024];
      static_cast<void>(std::snprintf(out_path, sizeof out_path, "%s/%s.overlay.jpg", overlay_dir,  // checked below
                                      base_name(path)));
      const auto written = encoder->write_file(view, 90, out_path);
      if (!written.ok()) {
        std::fprintf(stderr, "tcpest estimate: %s: %s\n", out_path, render::to_string(written.error()));
      }
    }
    static_cast<void>(std::fflush(stdout));  // one line per image, as it comes
  }
  return failures == 0 ? kExitOk : kExitFailure;
}

}  // namespace cli
}  // namespace tcpest
