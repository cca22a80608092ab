#include "tcpest/vision/frame_estimator.hpp"

#include <new>

namespace tcpest {
namespace vision {

const char* to_string(PriorSource source) noexcept {
  switch (source) {
    case PriorSource::kGeneric:
      return "generic";
    case PriorSource::kTemporal:
      return "temporal";
    case PriorSource::kEncoder:
      return "encoder";
  }
  return "?";
}

bool config_valid(const EstimatorConfig& config) noexcept {
  const GuidedOptions& g = config.guided;
  return config.classify_step >= 0 && config.classify_step <= 2 && solver::options_valid(config.solve) &&
         solver::encoder_check_valid(config.encoder_check) && g.rounds >= 0 && g.rounds <= kMaxGuidedRounds &&
         g.max_valid_tcp_disagreement_mm >= 0.0 && g.max_valid_tcp_disagreement_mm < 1e3;
}

FrameEstimator::FrameEstimator(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                               const EstimatorConfig& config) noexcept
    : camera_(camera), model_(model), config_(config) {}

FrameEstimator::~FrameEstimator() = default;

Result<std::unique_ptr<FrameEstimator>, VisionError> FrameEstimator::create(const solver::CameraModel& camera,
                                                                          const solver::InstrumentModel& model,
                                                                          const ColorModel& colors,
                                                                          const EstimatorConfig& config,
                                                                          int max_width, int max_height) noexcept {
  using R = Result<std::unique_ptr<FrameEstimator>, VisionError>;
  if (!config_valid(config)) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<FrameEstimator> e(new (std::nothrow) FrameEstimator(camera, model, config));
  if (!e) {
    return R::failure(VisionError::OutOfMemory);
  }
  ExtractorConfig extractor;
  extractor.regions.max_width = max_width > camera.width() ? max_width : camera.width();
  extractor.regions.max_height = max_height > camera.height() ? max_height : camera.height();
  extractor.regions.classify_step = config.classify_step;
  const auto& g = model.geometry();
  for (std::size_t m = 0U; m < static_cast<std::size_t>(kNumMarkers); ++m) {
    extractor.interpretation.marker_classes[m] =
        g.marker_colors[m] == solver::MarkerColor::Blue ? PixelClass::Blue : PixelClass::Yellow;
  }
  auto created = FeatureExtractor::create(extractor, colors);
  if (!created.ok()) {
    return R::failure(created.error());
  }
  e->extractor_ = std::move(created.value());
  e->solver_.reset(new (std::nothrow) solver::PoseEstimator(camera, model, config.solve));
  if (!e->solver_) {
    return R::failure(VisionError::OutOfMemory);
  }
  e->generic_priors_ = generic_priors(camera, model);
  return R::success(std::move(e));
}

void FrameEstimator::drop_track() noexcept { temporal_.reset(); }

void FrameEstimator::reset_appearance() noexcept { extractor_->part_widths().reset(); }

Status<VisionError> FrameEstimator::run_stages(const ImageView& image, const FramePrior& prior,
                                               StepObserver* observer, FrameEstimate& out) noexcept {
  const auto done = [observer](EstimationStep step) noexcept {
    if (observer != nullptr) {
      observer->step_done(step);
    }
  };
  FeatureExtractor& fx = *extractor_;
  Status<VisionError> status = fx.find_regions(image);
  done(EstimationStep::kClassify);
  if (!status.ok()) {
    out.failed_step = EstimationStep::kClassify;
    return status;
  }
  switch (prior.source) {
    case PriorSource::kEncoder:
      priors_ = model_priors(camera_, model_, prior.r);
      break;
    case PriorSource::kTemporal:
      if (!temporal_.priors(priors_)) {
        priors_ = model_priors(camera_, model_, prior.r);
      }
      break;
    case PriorSource::kGeneric:
      priors_ = generic_priors_;
      break;
  }
  status = fx.interpret(priors_);
  done(EstimationStep::kInterpret);
  if (!status.ok()) {
    out.failed_step = EstimationStep::kInterpret;
    return status;
  }
  status = fx.fit_borders(image);
  done(EstimationStep::kBorders);
  if (!status.ok()) {
    out.failed_step = EstimationStep::kBorders;
    return status;
  }
  status = fx.find_corners(image);
  done(EstimationStep::kCorners);
  if (!status.ok()) {
    out.failed_step = EstimationStep::kCorners;
  }
  return status;
}

void FrameEstimator::apply_encoder_check(const FramePrior& prior, solver::Estimate& estimate,
                                         FrameEstimate& out) const noexcept {
  // The encoders' joints, when they are this frame's prior, bound what the
  // image may claim (solver::check_against_encoders).
  out.encoder_disagrees =
      prior.source == PriorSource::kEncoder && solver::check_against_encoders(estimate, prior.r, config_.encoder_check);
  // The joints reported (and the next frame's start): the prior's turn of
  // phi and sign of theta, not whichever the solve ended on.
  estimate.r = solver::nearest_equivalent_joints(estimate.r, prior.r);
}

void FrameEstimator::report_corners(FrameEstimate& out) const noexcept {
  const Extraction& e = extractor_->result();
  const double predicted = extractor_->config().refiner.refine_predicted_confidence;
  for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
    const Corner& c = e.corners[k];
    EstimatedCorner& r = out.corners[k];
    r = EstimatedCorner{};
    // After a failed stage and no guided round there are no corners of this frame.
    if (!c.found || !(out.extraction_ok || e.refined)) {
      continue;
    }
    r.pixel = c.pixel;
    r.confidence = c.confidence;
    if (!e.refined) {
      r.source = CornerSource::kStage4;
    } else {
      r.source = c.confidence > predicted ? CornerSource::kRemeasured : CornerSource::kPredicted;
    }
  }
}

bool measured_in_image(CornerSource source) noexcept {
  return source == CornerSource::kStage4 || source == CornerSource::kRemeasured;
}

int corners_measured(const FrameEstimate& estimate) noexcept {
  int n = 0;
  for (const EstimatedCorner& c : estimate.corners) {
    n += measured_in_image(c.source) ? 1 : 0;
  }
  return n;
}

int measured_corners_used(const FrameEstimate& estimate) noexcept {
  if (!estimate.solved()) {
    return 0;
  }
  int n = 0;
  for (std::size_t k = 0U; k < estimate.corners.size(); ++k) {
    n += measured_in_image(estimate.corners[k].source) && estimate.estimate.summary.used[k] ? 1 : 0;
  }
  return n;
}

FrameEstimate FrameEstimator::estimate(const ImageView& image, const FramePrior& prior,
                                       StepObserver* observer) noexcept {
  FrameEstimate out;
  out.prior = prior.source;
  const Status<VisionError> stages = run_stages(image, prior, observer, out);
  out.extraction_ok = stages.ok();
  solver::CornerObservation observed;  // none when a stage failed
  if (stages.ok()) {
    out.failed_step = EstimationStep::kSolve;
    corners_to_arrays(extractor_->result(), observed.pixel, observed.visible);
    out.corners_detected = observed.count_visible();
  } else {
    out.stage_error = stages.error();
  }
  // After a failed stage there are no corners (no pose from the solve), but
  // the model-guided step may still confirm a pose seeded from the labelled
  // regions or the prior.
  solver::Estimate first = solver_->estimate(observed, config_.solve_mode, prior.r);
  apply_encoder_check(prior, first, out);
  if (observer != nullptr) {
    observer->step_done(EstimationStep::kSolve);
  }
  out.guided = guided_rounds(*extractor_, *solver_, camera_, model_, image, config_.solve_mode, first, prior.r,
                             config_.guided);
  if (out.guided.rounds_kept > 0) {
    first = out.guided.estimate;
    apply_encoder_check(prior, first, out);
  }
  if (observer != nullptr) {
    observer->step_done(EstimationStep::kRefine);
  }
  out.estimate = first;
  if (out.solved()) {
    out.tcp_mm = model_.tcp(first.r);
    // The next frames' stage-2 priors follow the track (only a frame whose
    // interpretation succeeded carries one; failed_step is kSolve when
    // every stage succeeded).
    if (out.failed_step > EstimationStep::kInterpret) {
      temporal_.add(extractor_->result().interpretation);
    }
  }
  // A valid estimate whose pose the image fit gave: its part widths are
  // the scene's (PartWidths).
  if (out.estimate.quality == solver::EstimateQuality::Valid && out.guided.rounds_kept > 0) {
    extractor_->part_widths().learn(out.guided.fit);
  }
  report_corners(out);
  return out;
}

Track::Track(const solver::InstrumentModel& model, int drop_after) noexcept
    : generic_r_(model.geometry().nominal_pose(kGenericLambdaMm, 0.0, 0.0)),
      last_r_(generic_r_),
      drop_after_(drop_after < 1 ? 1 : drop_after) {}

FramePrior Track::choose(const double* encoder_joints) const noexcept {
  FramePrior prior;
  if (encoder_joints != nullptr) {
    prior.source = PriorSource::kEncoder;
    prior.r = alive_ ? last_r_ : generic_r_;
    prior.r[solver::kLambda] = encoder_joints[0];
    prior.r[solver::kPhi] = encoder_joints[1];
    prior.r[solver::kTheta] = encoder_joints[2];
  } else if (alive_) {
    prior.source = PriorSource::kTemporal;
    prior.r = last_r_;
  } else {
    prior.source = PriorSource::kGeneric;
    prior.r = generic_r_;
  }
  return prior;
}

bool Track::update(const FrameEstimate& estimate) noexcept {
  if (!estimate.solved()) {
    return frame_failed();
  }
  last_r_ = estimate.estimate.r;
  alive_ = true;
  has_estimate_ = true;
  failed_ = 0;
  return false;
}

bool Track::frame_failed() noexcept {
  ++failed_;
  if (alive_ && failed_ >= drop_after_) {
    alive_ = false;
    failed_ = 0;
    return true;
  }
  return false;
}

void Track::reset() noexcept {
  alive_ = false;
  has_estimate_ = false;
  failed_ = 0;
  last_r_ = generic_r_;
}

}  // namespace vision
}  // namespace tcpest
