#include "cli/vision_run.hpp"

#include <dirent.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "tcpest/common/json_escape.hpp"
#include "tcpest/vision/overlay.hpp"

namespace tcpest {
namespace cli {
namespace {

constexpr std::size_t kMaxFileBytes = std::size_t{64U} * 1024U * 1024U;

bool read_file(const char* path, std::vector<std::uint8_t>& out, char* error, std::size_t capacity) noexcept {
  std::FILE* f = std::fopen(path, "rb");
  if (f == nullptr) {
    static_cast<void>(std::snprintf(error, capacity, "cannot open: %s", std::strerror(errno)));  // message only
    return false;
  }
  out.clear();
  std::uint8_t chunk[65536];
  bool ok = true;
  for (;;) {  // bounded by kMaxFileBytes
    const std::size_t n = std::fread(chunk, 1U, sizeof chunk, f);
    if (n > 0U) {
      if (out.size() + n > kMaxFileBytes) {
        static_cast<void>(std::snprintf(error, capacity, "file larger than %zu bytes", kMaxFileBytes));  // message only
        ok = false;
        break;
      }
      out.insert(out.end(), chunk, chunk + n);
    }
    if (n < sizeof chunk) {
      if (std::ferror(f) != 0) {
        static_cast<void>(std::snprintf(error, capacity, "read error"));  // message only
        ok = false;
      }
      break;
    }
  }
  static_cast<void>(std::fclose(f));  // read-only: nothing to flush
  return ok;
}

// Parses a binary PGM (P5) or PPM (P6) header; returns the offset of the
// samples or 0 (not P5/P6, a missing or overlong number, a zero size).
std::size_t parse_pnm(const std::vector<std::uint8_t>& data, PnmInfo& info, long& maxval) noexcept {
  if (data.size() < 8U || data[0] != 'P' || (data[1] != '5' && data[1] != '6')) {
    return 0U;
  }
  const auto is_space = [](std::uint8_t c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; };
  std::size_t i = 2U;
  long values[3] = {0, 0, 0};
  for (int v = 0; v < 3; ++v) {
    // Skip white space and comments.
    while (i < data.size() && (is_space(data[i]) || data[i] == '#')) {
      if (data[i] == '#') {
        while (i < data.size() && data[i] != '\n') {
          ++i;
        }
      } else {
        ++i;
      }
    }
    long value = 0;
    int digits = 0;
    while (i < data.size() && data[i] >= '0' && data[i] <= '9' && digits < 7) {
      value = value * 10 + (data[i] - '0');
      ++i;
      ++digits;
    }
    if (digits == 0 || i >= data.size() || !is_space(data[i])) {
      return 0U;  // no number, or more than 7 digits (absurd), or no separator
    }
    values[v] = value;
  }
  if (values[0] <= 0 || values[1] <= 0) {
    return 0U;
  }
  info.width = static_cast<int>(values[0]);
  info.height = static_cast<int>(values[1]);
  info.channels = data[1] == '5' ? 1 : 3;
  maxval = values[2];
  return i + 1U;
}

double elapsed_us(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) noexcept {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

}  // namespace

bool ImageReader::init(int max_width, int max_height) noexcept {
  max_width_ = max_width;
  max_height_ = max_height;
  file_.reserve(std::size_t{4U} * 1024U * 1024U);
  return decoder_.init(max_width, max_height).ok();
}

bool ImageReader::read(const char* path, std::vector<std::uint8_t>& pixels, ImageView& view, char* error,
                       std::size_t error_capacity) noexcept {
  if (!read_file(path, file_, error, error_capacity)) {
    return false;
  }
  PnmInfo pnm;
  long maxval = 0;
  const std::size_t ppm_offset = parse_pnm(file_, pnm, maxval);
  int width = pnm.width;
  int height = pnm.height;
  if (ppm_offset > 0U && pnm.channels == 3 && maxval == 255) {
    const std::size_t bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3U;
    if (width > max_width_ || height > max_height_ || file_.size() < ppm_offset + bytes) {
      static_cast<void>(std::snprintf(error, error_capacity, "PPM too large or truncated"));  // message only
      return false;
    }
    pixels.assign(file_.begin() + static_cast<std::ptrdiff_t>(ppm_offset),
                  file_.begin() + static_cast<std::ptrdiff_t>(ppm_offset + bytes));
  } else {
    const auto info = decoder_.inspect(file_.data(), file_.size());
    if (!info.ok()) {
      static_cast<void>(std::snprintf(error, error_capacity, "not a readable JPEG or PPM (%s)",  // message only
                                      hal::to_string(info.error())));
      return false;
    }
    width = info.value().width;
    height = info.value().height;
    if (width > max_width_ || height > max_height_) {
      static_cast<void>(std::snprintf(error, error_capacity, "image %dx%d larger than %dx%d", width,  // message only
                                      height, max_width_, max_height_));
      return false;
    }
    pixels.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3U);
    const MutableImageView out{pixels.data(), width, height, static_cast<std::size_t>(width) * 3U};
    const auto decoded = decoder_.decode(file_.data(), file_.size(), out);
    if (!decoded.ok()) {
      static_cast<void>(std::snprintf(error, error_capacity, "JPEG decoding failed (%s)",  // message only
                                      hal::to_string(decoded.error())));
      return false;
    }
  }
  view = ImageView{pixels.data(), width, height, static_cast<std::size_t>(width) * 3U};
  return true;
}

bool ImageReader::read_pnm(const char* path, std::vector<std::uint8_t>& samples, PnmInfo& info, char* error,
                           std::size_t error_capacity) noexcept {
  if (!read_file(path, file_, error, error_capacity)) {
    return false;
  }
  long maxval = 0;
  const std::size_t offset = parse_pnm(file_, info, maxval);
  if (offset == 0U) {
    static_cast<void>(std::snprintf(error, error_capacity, "not a binary PGM (P5) or PPM (P6)"));  // message only
    return false;
  }
  if (maxval != 255) {
    static_cast<void>(std::snprintf(error, error_capacity,  // message only
                                    "maxval %ld, expected 255 (8 bits per sample)", maxval));
    return false;
  }
  if (info.width > max_width_ || info.height > max_height_) {
    static_cast<void>(std::snprintf(error, error_capacity, "%dx%d larger than %dx%d", info.width,  // message only
                                    info.height, max_width_, max_height_));
    return false;
  }
  const std::size_t bytes = static_cast<std::size_t>(info.width) * static_cast<std::size_t>(info.height) *
                            static_cast<std::size_t>(info.channels);
  if (file_.size() < offset + bytes) {
    static_cast<void>(std::snprintf(error, error_capacity, "truncated: %zu of %zu sample bytes",  // message only
                                    file_.size() - offset, bytes));
    return false;
  }
  samples.assign(file_.begin() + static_cast<std::ptrdiff_t>(offset),
                 file_.begin() + static_cast<std::ptrdiff_t>(offset + bytes));
  return true;
}

bool list_sidecars(const char* command, const std::string& dir, std::vector<std::string>& sidecars) {
  sidecars.clear();
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) {
    std::fprintf(stderr, "%s: cannot open directory %s: %s\n", command, dir.c_str(), std::strerror(errno));
    return false;
  }
  for (const dirent* entry = readdir(d); entry != nullptr; entry = readdir(d)) {
    const std::size_t n = std::strlen(entry->d_name);
    if (n > 5U && std::strcmp(entry->d_name + n - 5U, ".json") == 0) {
      sidecars.emplace_back(entry->d_name);
    }
  }
  static_cast<void>(closedir(d));  // read-only directory handle
  std::sort(sidecars.begin(), sidecars.end());
  if (sidecars.empty()) {
    std::fprintf(stderr, "%s: no sidecar (*.json) in %s\n", command, dir.c_str());
    return false;
  }
  return true;
}

bool load_color_model(const char* command, const char* path, vision::ColorModel& out) noexcept {
  if (path == nullptr) {
    out = vision::default_color_model();
    return true;
  }
  std::vector<std::uint8_t> data;
  char error[256];
  if (!read_file(path, data, error, sizeof error)) {
    std::fprintf(stderr, "tcpest %s: colour model %s: %s\n", command, path, error);
    return false;
  }
  const auto parsed =
      vision::parse_color_model(reinterpret_cast<const char*>(data.data()), data.size(), path);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): bytes to text
  if (!parsed.ok()) {
    char message[768];
    parsed.error().format(message, sizeof message);
    std::fprintf(stderr, "tcpest %s: colour model: %s\n", command, message);
    return false;
  }
  out = parsed.value();
  return true;
}

bool EstimatePipeline::init(const char* command, const ModelSetup& setup, const vision::ColorModel& colors,
                            const loop::LoopConfig& config) noexcept {
  setup_ = setup;
  config_ = config;
  auto created = vision::FrameEstimator::create(setup_.camera, setup_.instrument, colors, config.loop.estimator);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest %s: frame estimator: %s\n", command, vision::to_string(created.error()));
    return false;
  }
  estimator_ = std::move(created.value());
  track_.reset(new (std::nothrow) vision::Track(setup_.instrument, config.loop.track_drop_after));
  if (track_ == nullptr) {
    std::fprintf(stderr, "tcpest %s: out of memory\n", command);
    return false;
  }
  reset_sequence();
  return true;
}

bool EstimatePipeline::enable_dense(const vision::DenseOptions& options) noexcept {
  if (!vision::dense_options_valid(options)) {
    return false;
  }
  vision::DenseFitConfig config;
  config.max_width = setup_.camera.width();
  config.max_height = setup_.camera.height();
  config.max_work_pixels = options.coarse_pixels > options.fine_pixels ? options.coarse_pixels : options.fine_pixels;
  auto created = vision::DenseFit::create(setup_.camera, setup_.instrument, estimator_->extractor().colors(), config);
  if (!created.ok()) {
    return false;
  }
  dense_ = std::move(created.value());
  dense_options_ = options;
  return true;
}

void EstimatePipeline::apply_dense(const ImageView& image, const vision::GuidedResult& guided,
                                   const solver::PoseVector& start, bool encoders_given, solver::Estimate& estimate,
                                   EstimateResult& out) noexcept {
  // Seeds: the image fit's pose and the solve's, when the pipeline has them.
  solver::PoseVector seeds[vision::kMaxDenseSeeds];
  int seed_count = 0;
  if (guided.rounds_kept > 0) {
    seeds[seed_count++] = guided.fitted_r;
  }
  if (estimate.quality != solver::EstimateQuality::None) {
    seeds[seed_count++] = estimate.r;
  }
  const vision::DenseResult dense =
      vision::dense_estimate(*dense_, setup_.camera, setup_.instrument, image, seeds, seed_count, start,
                             encoders_given ? &start : nullptr, guided.fit.streak_px, dense_options_);
  out.dense_ran = true;
  if (!dense.ok) {
    return;
  }
  // The extractor still holds the pipeline's own corners here.
  std::array<vision::Corner, vision::kNumCorners> corners = dense.corners;
  vision::blend_pipeline_corners(corners, estimator_->extractor().result().corners, dense_options_);
  solver::CornerObservation observation;
  for (std::size_t k = 0; k < static_cast<std::size_t>(vision::kNumCorners); ++k) {
    if (corners[k].found) {
      observation.pixel[k] = solver::Vec2(corners[k].pixel.x, corners[k].pixel.y);
      observation.visible[k] = true;
    }
  }
  solver::Estimate refined = estimator_->solver().estimate(observation, estimator_->config().solve_mode, dense.r);
  if (refined.quality == solver::EstimateQuality::None) {
    return;  // the pipeline's own result stays
  }
  const double tcp_change_mm =
      estimate.quality == solver::EstimateQuality::None
          ? std::numeric_limits<double>::quiet_NaN()
          : (setup_.instrument.tcp(refined.r) - setup_.instrument.tcp(estimate.r)).norm();
  refined.quality = dense_kept_quality(estimate.quality, refined.quality, tcp_change_mm, dense_options_);
  estimate = refined;
  vision::FeatureExtractor::CornerSnapshot snapshot;
  snapshot.corners = corners;
  snapshot.refined = true;
  estimator_->extractor().restore_snapshot(snapshot);
  out.dense_kept = true;
  out.streak_px = dense.streak_px;
}

void EstimatePipeline::reset_sequence() noexcept {
  track_->reset();
  estimator_->drop_track();
}

void EstimatePipeline::reset_appearance() noexcept { estimator_->reset_appearance(); }

void EstimatePipeline::frame_failed() noexcept {
  if (track_->frame_failed()) {
    estimator_->drop_track();
  }
}

namespace {
// Times the estimator's steps on the wall clock (reported, never decided on).
class StepTimer final : public vision::StepObserver {
 public:
  StepTimer() noexcept : start_(std::chrono::steady_clock::now()), last_(start_) {}
  void step_done(vision::EstimationStep step) noexcept override {
    const auto now = std::chrono::steady_clock::now();
    us_[static_cast<std::size_t>(step)] += elapsed_us(last_, now);
    last_ = now;
  }
  double us(vision::EstimationStep step) const noexcept { return us_[static_cast<std::size_t>(step)]; }
  double total_us() const noexcept { return elapsed_us(start_, std::chrono::steady_clock::now()); }

 private:
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_;
  std::array<double, vision::kNumEstimationSteps> us_{};
};
}  // namespace

EstimateResult EstimatePipeline::process(const ImageView& image, const double* prior_joints) noexcept {
  EstimateResult out;
  const vision::FramePrior prior = track_->choose(prior_joints);
  StepTimer timer;
  const vision::FrameEstimate frame = estimator_->estimate(image, prior, &timer);
  // The track follows the estimator's own result, as in the loop, whether
  // or not the dense stage replaces it below.
  if (track_->update(frame)) {
    estimator_->drop_track();
  }
  solver::Estimate estimate = frame.estimate;
  out.encoder_disagrees = frame.encoder_disagrees;
  out.streak_px = frame.guided.fit.streak_px;
  out.measured_corners = measured_corner_count(estimator_->extractor().result(), estimator_->extractor().config());
  if (dense_ != nullptr && dense_stage_applies(estimate.quality, out.measured_corners, frame.encoder_disagrees,
                                               frame.guided.fit.streak_px.norm(), dense_options_)) {
    apply_dense(image, frame.guided, prior.r, prior_joints != nullptr, estimate, out);
    if (out.dense_kept) {
      // The stage replaced the estimate: the encoders' check and the
      // prior's equivalent joints again.
      out.encoder_disagrees = prior.source == vision::PriorSource::kEncoder &&
                              solver::check_against_encoders(estimate, prior.r, estimator_->config().encoder_check);
      estimate.r = solver::nearest_equivalent_joints(estimate.r, prior.r);
    }
  }
  out.times.stage_us[0] = timer.us(vision::EstimationStep::kClassify);
  out.times.stage_us[1] = timer.us(vision::EstimationStep::kInterpret);
  out.times.stage_us[2] = timer.us(vision::EstimationStep::kBorders);
  out.times.stage_us[3] = timer.us(vision::EstimationStep::kCorners);
  out.times.solve_us = timer.us(vision::EstimationStep::kSolve) + timer.us(vision::EstimationStep::kRefine);
  out.total_us = timer.total_us();
  out.extraction_ok = frame.extraction_ok;
  out.extraction_error = frame.extraction_ok ? "" : vision::to_string(frame.stage_error);
  out.summary = estimate.summary;
  out.status = estimate.quality;
  out.corners_rejected = estimate.corners_rejected;
  out.guided_rounds = frame.guided.rounds_kept;
  out.rows_tried = frame.guided.tried;
  out.rows_tried.add(vision::StepKind::kStage4Solve);
  out.rows_produced.add(frame.guided.produced_by);
  if (frame.guided.disagreement_demoted) {
    out.rows_produced.add(vision::StepKind::kFitAgreementCheck);
  }
  if (prior.source == vision::PriorSource::kEncoder) {
    out.rows_tried.add(vision::StepKind::kEncoderCheck);
    if (frame.encoder_disagrees) {
      out.rows_produced.add(vision::StepKind::kEncoderCheck);
    }
  }
  out.fit_disagrees = frame.guided.disagreement_demoted;
  if (estimate.quality != solver::EstimateQuality::None) {
    out.r = estimate.r;
    out.tcp = setup_.instrument.tcp(estimate.r);
  }
  if (frame.guided.rounds_kept > 0) {
    out.fit_tcp = setup_.instrument.tcp(frame.guided.fitted_r);
  }
  return out;
}

namespace {

// An optional integer option 0..max into `out`; false after printing an error.
bool apply_count(const char* command, const char* option, const char* value, int max, int& out) noexcept {
  if (value == nullptr) {
    return true;  // the configuration's value stays
  }
  unsigned long long n = 0ULL;
  if (!parse_unsigned(value, n) || n > static_cast<unsigned long long>(max)) {
    std::fprintf(stderr, "tcpest %s: --%s needs an integer 0..%d\n", command, option, max);
    return false;
  }
  out = static_cast<int>(n);
  return true;
}

}  // namespace

bool init_pipeline_from_args(const char* command, const Args& args, ModelSetup& setup, EstimatePipeline& pipeline,
                             int& exit_code) noexcept {
  exit_code = kExitConfig;
  const char* config_path = args.value("config");
  if (!load_model_setup(command, args.value("calib"), config_path, setup)) {
    return false;
  }
  // The loop's configuration from the same file: what `tcpest run` would use.
  static yaml::Document scratch;  // large: static storage
  static loop::LoopConfig config;
  const auto loaded = loop::load_loop_config(config_path, scratch, config);
  if (!loaded.ok()) {
    char message[768];
    loaded.error().format(message, sizeof message);
    std::fprintf(stderr, "tcpest %s: %s\n", command, message);
    return false;
  }
  vision::ColorModel colors;
  if (!load_color_model(command, args.value("colors"), colors)) {
    return false;
  }
  exit_code = kExitUsage;
  vision::EstimatorConfig& e = config.loop.estimator;
  if (args.flag("fixed-model")) {
    e.solve_mode = solver::SolveMode::FixedModel;
  }
  if (!apply_count(command, "guided-rounds", args.value("guided-rounds"), vision::kMaxGuidedRounds,
                   e.guided.rounds)) {
    return false;
  }
  exit_code = kExitConfig;
  if (!pipeline.init(command, setup, colors, config)) {
    return false;
  }
  if (args.flag("dense") && !pipeline.enable_dense(vision::DenseOptions{})) {
    std::fprintf(stderr, "tcpest %s: --dense: the dense fit's buffers could not be allocated\n", command);
    exit_code = kExitFailure;
    return false;
  }
  exit_code = kExitOk;
  return true;
}

void EstimatePipeline::draw_overlay(const EstimateResult& result, const MutableImageView& image) const noexcept {
  vision::ReprojectedModel model;
  if (result.status != solver::EstimateQuality::None) {
    solver::CornerSet cs;
    setup_.instrument.corners(setup_.camera, result.r, cs);
    model.valid = true;
    for (std::size_t k = 0U; k < static_cast<std::size_t>(vision::kNumCorners); ++k) {
      model.present[k] = cs.present[k];
      model.corners[k] = vision::Point{cs.pixel[k].x(), cs.pixel[k].y()};
    }
    solver::Vec2 tcp_px;
    if (setup_.camera.project(result.tcp, tcp_px)) {
      model.tcp_valid = true;
      model.tcp = vision::Point{tcp_px.x(), tcp_px.y()};
    }
  }
  vision::draw_extraction(image, estimator_->extractor().result(), model);
}

bool dense_stage_applies(solver::EstimateQuality quality, int measured_corners, bool encoders_disagree,
                         double streak_read_px, const vision::DenseOptions& options) noexcept {
  // NaN compares false: no streak read.
  if (options.run_where_streak_read && streak_read_px > vision::DenseFit::kMinStreakPx) {
    return true;
  }
  if (quality == solver::EstimateQuality::Valid) {
    return measured_corners <= options.max_measured_corners_valid;
  }
  return measured_corners <= options.max_measured_corners || (options.run_when_encoders_disagree && encoders_disagree);
}

solver::EstimateQuality dense_kept_quality(solver::EstimateQuality replaced, solver::EstimateQuality solved,
                                           double tcp_change_mm, const vision::DenseOptions& options) noexcept {
  if (solved == solver::EstimateQuality::None) {
    return solver::EstimateQuality::None;
  }
  // NaN (no estimate replaced) compares false.
  const bool agree = options.max_valid_tcp_change_mm > 0.0 && tcp_change_mm <= options.max_valid_tcp_change_mm;
  return replaced == solver::EstimateQuality::Valid && solved == solver::EstimateQuality::Valid && agree
             ? solver::EstimateQuality::Valid
             : solver::EstimateQuality::Degraded;
}

int measured_corner_count(const vision::Extraction& e, const vision::ExtractorConfig& config) noexcept {
  int count = 0;
  for (const vision::Corner& c : e.corners) {
    if (c.found && (!e.refined || c.confidence > config.refiner.refine_predicted_confidence)) {
      ++count;
    }
  }
  return count;
}

bool corner_reported(const EstimateResult& result, const vision::Extraction& extraction, std::size_t k) noexcept {
  return k < extraction.corners.size() && extraction.corners[k].found && (result.extraction_ok || extraction.refined);
}

void format_estimate_json(const char* image, const EstimateResult& result, const vision::Extraction& extraction,
                          char* out, std::size_t capacity) noexcept {
  if (capacity == 0U) {
    return;
  }
  out[0] = '\0';
  std::size_t used = 0U;
  // Each snprintf below writes at out + used; a truncated line stays terminated.
  const auto advance = [&used, capacity](int n) noexcept {
    if (n > 0) {
      used = std::min(capacity - 1U, used + static_cast<std::size_t>(n));
    }
  };
  advance(std::snprintf(out + used, capacity - used, "{\"image\": \""));
  // The image path as a JSON string (a longer one cut at a character, never mid-escape).
  advance(static_cast<int>(json::escape_string(image, out + used, capacity - used > 8U ? capacity - used - 8U : 1U)));
  advance(std::snprintf(out + used, capacity - used, "\", \"status\": \"%s\"", to_string(result.status)));
  if (result.status != solver::EstimateQuality::None) {
    advance(std::snprintf(out + used, capacity - used, ", \"tcp\": [%.4f, %.4f, %.4f], \"r\": [", result.tcp.x(),
                          result.tcp.y(), result.tcp.z()));
    for (int i = 0; i < solver::kNumParams; ++i) {
      advance(std::snprintf(out + used, capacity - used, i == 0 ? "%.6f" : ", %.6f", result.r[i]));
    }
    advance(std::snprintf(out + used, capacity - used, "]"));
  } else {
    advance(std::snprintf(out + used, capacity - used, ", \"tcp\": null, \"r\": null"));
  }
  advance(std::snprintf(out + used, capacity - used, ", \"corners\": ["));
  for (std::size_t k = 0U; k < static_cast<std::size_t>(vision::kNumCorners); ++k) {
    const vision::Corner& c = extraction.corners[k];
    const char* separator = k == 0U ? "" : ", ";
    if (corner_reported(result, extraction, k)) {
      advance(std::snprintf(out + used, capacity - used, "%s[%.3f, %.3f]", separator, c.pixel.x, c.pixel.y));
    } else {
      advance(std::snprintf(out + used, capacity - used, "%snull", separator));
    }
  }
  // Each reported corner's confidence (0..1, vision::Corner): 0.9 read on
  // the image around the fitted pose, 0.5 a limb point of that pose (its
  // arc not read); stage 4's own corners 0.45-1 (docs/vision.md).
  advance(std::snprintf(out + used, capacity - used, "], \"corner_confidence\": ["));
  for (std::size_t k = 0U; k < static_cast<std::size_t>(vision::kNumCorners); ++k) {
    const char* separator = k == 0U ? "" : ", ";
    if (corner_reported(result, extraction, k)) {
      advance(std::snprintf(out + used, capacity - used, "%s%.2f", separator, extraction.corners[k].confidence));
    } else {
      advance(std::snprintf(out + used, capacity - used, "%snull", separator));
    }
  }
  advance(std::snprintf(out + used, capacity - used, "], \"rms_px\": %.4f, \"iterations\": %d, \"time_us\": %.0f}",
                        result.summary.rms_px, result.summary.iterations, result.total_us));
}

void HardCaseTally::add(std::uint32_t hard_cases, bool success) noexcept {
  if ((hard_cases & render::kAllHardCases) == 0U) {
    ++clear_frames;
    clear_successes += success ? 1 : 0;
    return;
  }
  for (int bit = 0; bit < render::kNumHardCases; ++bit) {
    if ((hard_cases & (1U << static_cast<unsigned>(bit))) != 0U) {
      ++frames[static_cast<std::size_t>(bit)];
      successes[static_cast<std::size_t>(bit)] += success ? 1 : 0;
    }
  }
}

namespace {

// A "HEAD: name x % of n, name x % of n ..." line written item by item into
// a caller's buffer; items without frames are left out, and a full buffer
// keeps what fitted, terminated.
class ShareLine {
 public:
  ShareLine(const char* head, char* out, std::size_t capacity) noexcept : head_(head), out_(out), capacity_(capacity) {
    if (capacity_ > 0U) {
      out_[0] = '\0';
    }
  }
  void item(const char* name, int frames, int successes) noexcept {
    if (frames <= 0 || used_ + 1U >= capacity_) {
      return;
    }
    const int written = std::snprintf(out_ + used_, capacity_ - used_, "%s%s %.1f %% of %d", any_ ? ", " : head_,
                                      name, 100.0 * successes / frames, frames);
    if (written > 0) {
      used_ = std::min(capacity_ - 1U, used_ + static_cast<std::size_t>(written));
    }
    any_ = true;
  }

 private:
  const char* head_;
  char* out_;
  std::size_t capacity_;
  std::size_t used_ = 0U;
  bool any_ = false;
};

}  // namespace

void format_hard_case_tally(const HardCaseTally& tally, char* out, std::size_t capacity) noexcept {
  ShareLine line("frame success by hard case: ", out, capacity);
  bool hard = false;
  for (const int n : tally.frames) {
    hard = hard || n > 0;
  }
  if (!hard) {
    return;
  }
  for (int bit = 0; bit < render::kNumHardCases; ++bit) {
    const auto b = static_cast<std::size_t>(bit);
    line.item(render::hard_case_name(bit), tally.frames[b], tally.successes[b]);
  }
  line.item("none", tally.clear_frames, tally.clear_successes);
}

void VisibleCornersTally::add(int visible, bool success) noexcept {
  if (visible <= 0) {
    return;
  }
  const int bucket = visible <= 3 ? 0 : (visible <= 5 ? 1 : (visible <= 7 ? 2 : 3));
  ++frames[static_cast<std::size_t>(bucket)];
  successes[static_cast<std::size_t>(bucket)] += success ? 1 : 0;
}

void format_visible_corners_tally(const VisibleCornersTally& tally, char* out, std::size_t capacity) noexcept {
  static constexpr const char* kNames[VisibleCornersTally::kBuckets] = {"1-3", "4-5", "6-7", "8-12"};
  ShareLine line("frame success by visible corners: ", out, capacity);
  for (std::size_t b = 0U; b < static_cast<std::size_t>(VisibleCornersTally::kBuckets); ++b) {
    line.item(kNames[b], tally.frames[b], tally.successes[b]);
  }
}

void InsertionTally::add(double lambda_mm, bool success) noexcept {
  if (!std::isfinite(lambda_mm)) {
    return;
  }
  const double bin_mm = std::round((lambda_mm - kFirstMm) / kStepMm);
  const int bin = static_cast<int>(std::min(std::max(bin_mm, 0.0), static_cast<double>(kBins - 1)));
  ++frames[static_cast<std::size_t>(bin)];
  successes[static_cast<std::size_t>(bin)] += success ? 1 : 0;
}

void format_insertion_tally(const InsertionTally& tally, char* out, std::size_t capacity) noexcept {
  ShareLine line("frame success by insertion (mm): ", out, capacity);
  for (int b = 0; b < InsertionTally::kBins; ++b) {
    char name[8];
    static_cast<void>(std::snprintf(name, sizeof name, "%.0f", InsertionTally::kFirstMm + InsertionTally::kStepMm * b));
    line.item(name, tally.frames[static_cast<std::size_t>(b)], tally.successes[static_cast<std::size_t>(b)]);
  }
}

}  // namespace cli
}  // namespace tcpest
