// The comparison rule that decides whether a seed's result replaces the
// current one (replaces_result, guided_estimate.hpp), on constructed
// results with a known answer: no image, no fit.
#include <gtest/gtest.h>

#include "tcpest/vision/guided_estimate.hpp"

namespace tcpest {
namespace vision {
namespace {

// A result whose last image fit read `run` consecutive boundaries (and as
// many boundaries), `silhouette` silhouette points, at `rms_px`; `rounds`
// kept (0: not confirmed by a fit: stage 4's corners).
GuidedResult result(solver::EstimateQuality quality, int rounds, int run, int silhouette, double rms_px) {
  GuidedResult r;
  r.estimate.quality = quality;
  r.rounds_kept = rounds;
  r.fit.boundaries = run;
  r.fit.boundary_run = run;
  r.fit.silhouette_readings = silhouette;
  r.fit.plain_silhouette_readings = silhouette;
  r.fit.rms_px = rms_px;
  return r;
}

constexpr auto kValid = solver::EstimateQuality::Valid;
constexpr auto kDegraded = solver::EstimateQuality::Degraded;
constexpr auto kNone = solver::EstimateQuality::None;

TEST(ResultChoice, ACandidateWithoutARoundKeptNeverReplaces) {
  const GuidedOptions options;
  EXPECT_FALSE(replaces_result(result(kValid, 0, 5, 20, 0.1), result(kNone, 0, 0, 0, 0.0), options));
  EXPECT_TRUE(replaces_result(result(kDegraded, 1, 1, 4, 0.5), result(kNone, 0, 0, 0, 0.0), options));
}

// A valid result no fit confirmed (stage 4's corners) against a degraded
// one whose fit has a valid estimate's support (a run of 3 boundaries, 12
// silhouette points): the image's word wins (prefer_fit_confirmed); without
// the rule, the better quality.
TEST(ResultChoice, AFitConfirmedResultReplacesAnUnconfirmedValidOne) {
  GuidedOptions options;
  const GuidedResult unconfirmed = result(kValid, 0, 0, 0, 0.0);
  const GuidedResult confirmed = result(kDegraded, 1, options.min_valid_fit_boundaries,
                                        options.min_valid_fit_silhouette_readings, 0.3);
  EXPECT_TRUE(replaces_result(confirmed, unconfirmed, options));
  // Short of a valid one's support, the quality decides.
  const GuidedResult thin = result(kDegraded, 1, options.min_valid_fit_boundaries - 1,
                                   options.min_valid_fit_silhouette_readings, 0.3);
  EXPECT_FALSE(replaces_result(thin, unconfirmed, options));
  options.prefer_fit_confirmed = false;
  EXPECT_FALSE(replaces_result(confirmed, unconfirmed, options));
}

// Two fit-confirmed results: a degraded one whose fit read as much of the
// image at less than prefer_fit_rms_ratio times the valid one's residual
// replaces it; reading fewer boundaries, or with the rule off, it does not.
TEST(ResultChoice, AClearlyBetterFitReplacesAValidResult) {
  GuidedOptions options;
  const GuidedResult valid = result(kValid, 1, 4, 16, 0.48);
  EXPECT_TRUE(replaces_result(result(kDegraded, 1, 4, 16, 0.15), valid, options));
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 3, 16, 0.15), valid, options));
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 4, 15, 0.15), valid, options));
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 4, 16, 0.34), valid, options));  // 0.34 > 0.7 * 0.48
  options.prefer_fit_rms_ratio = 0.0;
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 4, 16, 0.15), valid, options));
}

// At the same quality, a fit that read a shorter run of boundaries needs a
// residual below longer_run_rms_ratio times the longer run's (a fit two
// stripes along reads fewer and settles lower); a longer run needs only
// not to be clearly worse. Off (0): the lower residual alone.
TEST(ResultChoice, AtTheSameQualityTheLongerRunIsKept) {
  GuidedOptions options;
  const GuidedResult longer = result(kDegraded, 1, 4, 12, 0.30);
  const GuidedResult shorter = result(kDegraded, 1, 2, 12, 0.25);
  EXPECT_FALSE(replaces_result(shorter, longer, options));
  EXPECT_TRUE(replaces_result(result(kDegraded, 1, 2, 12, 0.20), longer, options));  // 0.20 < 0.7 * 0.30
  EXPECT_TRUE(replaces_result(longer, shorter, options));
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 4, 12, 0.40), shorter, options));  // 0.7 * 0.40 > 0.25
  options.longer_run_rms_ratio = 0.0;
  EXPECT_TRUE(replaces_result(shorter, longer, options));
  EXPECT_FALSE(replaces_result(longer, shorter, options));
}

// Otherwise the better quality, then the lower residual; a fit-confirmed
// result replaces stage 4's at the same quality.
TEST(ResultChoice, OtherwiseTheQualityThenTheLowerResidual) {
  const GuidedOptions options;
  EXPECT_TRUE(replaces_result(result(kValid, 1, 4, 12, 0.40), result(kDegraded, 1, 4, 12, 0.30), options));
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 4, 12, 0.30), result(kValid, 1, 4, 12, 0.40), options));
  EXPECT_TRUE(replaces_result(result(kDegraded, 1, 4, 12, 0.29), result(kDegraded, 1, 4, 12, 0.30), options));
  EXPECT_FALSE(replaces_result(result(kDegraded, 1, 4, 12, 0.31), result(kDegraded, 1, 4, 12, 0.30), options));
  EXPECT_TRUE(replaces_result(result(kDegraded, 1, 1, 4, 0.5), result(kDegraded, 0, 0, 0, 0.0), options));
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
