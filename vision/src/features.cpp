// The composition of the four stages (features.hpp): creation, and the
// stages run on the extractor's Extraction.
#include "tcpest/vision/features.hpp"

#include <new>

#include "blurred_edge.hpp"
#include "fit_scratch.hpp"

namespace tcpest {
namespace vision {
namespace {

// The model-guided fits' part of the configuration.
bool refiner_config_valid(const RefinerConfig& config) noexcept {
  return config.refine_smear_tip_bias >= 0.0 && config.refine_smear_tip_bias <= 0.5 &&
         config.refine_streak_unsmeared_min_px >= 0.0 && config.refine_streak_arc_retry_min_px >= 0.0 &&
         config.refine_streak_unsmeared_min_boundaries >= 0 &&
         config.refine_streak_unsmeared_min_boundaries <= kNumBoundaries && config.refine_rim_scan_step_mm > 0.0 &&
         config.refine_rim_scan_range_mm >= 0.0 &&
         config.refine_rim_scan_range_mm <= config.refine_rim_scan_step_mm * FeatureExtractor::kMaxRimScanSteps &&
         config.refine_streak_edge_smear_search_px >= 0.0 &&
         config.refine_streak_edge_smear_search_px <= kMaxStreakEdgeSmearSearchPx;
}

}  // namespace

FeatureExtractor::~FeatureExtractor() = default;

Result<std::unique_ptr<FeatureExtractor>, VisionError> FeatureExtractor::create(const ExtractorConfig& config,
                                                                                const ColorModel& colors) noexcept {
  using R = Result<std::unique_ptr<FeatureExtractor>, VisionError>;
  if (!refiner_config_valid(config.refiner)) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<FeatureExtractor> e(new (std::nothrow) FeatureExtractor());
  if (e == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  e->config_ = config;
  e->colors_ = colors;
  auto regions = RegionFinder::create(config.regions, colors);
  if (!regions.ok()) {
    return R::failure(regions.error());
  }
  e->regions_ = std::move(regions.value());
  auto interpreter = Interpreter::create(config.interpretation);
  if (!interpreter.ok()) {
    return R::failure(interpreter.error());
  }
  e->interpreter_ = std::move(interpreter.value());
  auto border_fitter = BorderFitter::create(config.borders);
  if (!border_fitter.ok()) {
    return R::failure(border_fitter.error());
  }
  e->border_fitter_ = std::move(border_fitter.value());
  auto corner_finder = CornerFinder::create(config.corners, colors);
  if (!corner_finder.ok()) {
    return R::failure(corner_finder.error());
  }
  e->corner_finder_ = std::move(corner_finder.value());
  const std::size_t pixels =
      static_cast<std::size_t>(config.regions.max_width) * static_cast<std::size_t>(config.regions.max_height);
  for (auto& d : e->class_distance_) {
    d.reset(new (std::nothrow) std::uint16_t[pixels]);
  }
  e->edge_scratch_.reset(new (std::nothrow) detail::BlurredEdgeScratch());
  e->fit_scratch_.reset(new (std::nothrow) detail::FitScratch());
  if (e->class_distance_[0] == nullptr || e->class_distance_[1] == nullptr || e->edge_scratch_ == nullptr ||
      e->fit_scratch_ == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  return R::success(std::move(e));
}

Status<VisionError> FeatureExtractor::find_regions(const ImageView& image) noexcept {
  // A new frame: nothing of the last one survives (a later stage that is
  // not reached must not leave an older frame's results).
  result_.interpretation = Interpretation{};
  for (Border& b : result_.borders) {
    b.valid = false;
  }
  for (Corner& c : result_.corners) {
    c = Corner{};
  }
  result_.corner_count = 0;
  result_.refined = false;
  class_distance_ready_ = false;
  return regions_->find(image, result_.regions);
}

Status<VisionError> FeatureExtractor::interpret(const MarkerPriors& priors) noexcept {
  return interpreter_->interpret(result_.regions, regions_->image(), priors, result_.interpretation);
}

Status<VisionError> FeatureExtractor::fit_borders(const ImageView& image) noexcept {
  return border_fitter_->fit(image, regions_->classes(), result_.interpretation, result_.borders, result_.skeleton,
                             result_.skeleton_count);
}

Status<VisionError> FeatureExtractor::find_corners(const ImageView& image) noexcept {
  result_.refined = false;
  return corner_finder_->find(image, result_.interpretation, result_.borders, result_.corners, result_.corner_count);
}

Status<VisionError> FeatureExtractor::extract(const ImageView& image, const MarkerPriors& priors) noexcept {
  const auto s1 = find_regions(image);
  if (!s1.ok()) {
    return s1;
  }
  const auto s2 = interpret(priors);
  if (!s2.ok()) {
    return s2;
  }
  const auto s3 = fit_borders(image);
  if (!s3.ok()) {
    return s3;
  }
  return find_corners(image);
}

}  // namespace vision
}  // namespace tcpest
