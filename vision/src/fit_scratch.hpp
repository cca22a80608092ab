// The model-guided fits' scratch (private header): the fixed sizes of
// their problems and their minimisers, owned by the extractor (allocated
// at create(); no allocation per frame). Every fit runs on the solver's
// Levenberg-Marquardt: the chamfer fit on the class image
// (fit_pose_to_classes) directly, the image fit (fit_pose_to_image) and the
// shaft fit (fit_channel_to_shaft) one robust round at a time (RobustRows).
#pragma once

#include "robust_step.hpp"
#include "tcpest/solver/levenberg_marquardt.hpp"
#include "tcpest/solver/types.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {
namespace detail {

// The class image's chamfer fit (class_fit.cpp).
constexpr int kClassStepsAlong = 3;    // samples along each stripe (at 0.2, 0.5, 0.8 of its length)
constexpr int kClassStepsAround = 12;  // samples around the tube
constexpr int kClassMaxSamples = kNumMarkers * kClassStepsAlong * kClassStepsAround;
constexpr int kClassMaxCoverage = 64;  // coloured pixels of the class image that should lie near a sample
constexpr int kClassParams = solver::kNumParams;
constexpr int kClassRows = kClassMaxSamples + kClassMaxCoverage + kClassParams;  // samples, coverage, prior

// The image fit's readings per round (image_fit.cpp).
constexpr int kFitArcSamples = 12;         // per boundary
constexpr int kFitSilhouetteSamples = 10;  // per side
constexpr int kFitShaftSamples = 6;        // per side: the shaft's silhouette just before the base
constexpr int kFitGrasperSamples = 6;      // per side: the grasper's silhouette past the tip
constexpr int kMaxFitReadings = kNumBoundaries * kFitArcSamples + 2 * kFitSilhouetteSamples +
                                2 * kFitShaftSamples + 2 * kFitGrasperSamples;
// Where they lie: the tube's silhouette samples spread over its length (not
// at its very ends, where the shaft and the grasper meet it); the shaft's
// from kFitShaftFirstMm before the base, kFitShaftStepMm apart.
constexpr double kFitShaftFirstMm = 1.0;
constexpr double kFitShaftStepMm = 1.5;
constexpr double fit_silhouette_s_mm(double bend_length_mm, int i) noexcept {
  return bend_length_mm * (0.03 + 0.94 * i / (kFitSilhouetteSamples - 1.0));
}
constexpr double fit_shaft_back_mm(int i) noexcept { return kFitShaftFirstMm + kFitShaftStepMm * i; }

// The shaft fit (shaft_fit.cpp): the channel's pose x_ch, y_ch, psi, mu
// from the shaft's silhouette.
constexpr int kShaftParams = 4;
constexpr int kShaftSamples = 8;  // per side
constexpr int kMaxShaftReadings = 2 * kShaftSamples;

struct FitScratch {
  solver::LevenbergMarquardt<kClassParams, kClassRows> class_fit;
  RobustRows<solver::kNumParams, kMaxFitReadings> image_fit;
  RobustRows<kShaftParams, kMaxShaftReadings> shaft_fit;
};

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
