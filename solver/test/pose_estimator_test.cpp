#include "tcpest/solver/pose_estimator.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "pose_problem.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace solver {
namespace {

using test_support::draw_problem;
using test_support::Problem;

class PoseEstimatorTest : public ::testing::Test {
 protected:
  CameraModel camera_ = test_support::pal_camera();
  InstrumentModel model_ = test_support::default_model();
};

// First visible corner of a problem (for the tests that displace one).
int first_visible(const CornerObservation& observed) {
  for (int k = 0; k < kNumCorners; ++k) {
    if (observed.visible[static_cast<std::size_t>(k)]) {
      return k;
    }
  }
  return -1;
}

// Verifies: REQ-SOLVER-008
TEST_F(PoseEstimatorTest, ExactCornersGiveAValidEstimateWithoutRejection) {
  std::mt19937 rng(3);
  PoseEstimator estimator(camera_, model_);
  for (int i = 0; i < 10; ++i) {
    Problem p;
    ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 0.0, 9, p));  // no play: zero residual at the truth
    const Estimate e = estimator.estimate(p.observed, SolveMode::Adaptive, p.prior);
    EXPECT_EQ(e.quality, EstimateQuality::Valid);
    EXPECT_EQ(e.corners_rejected, 0);
    EXPECT_EQ(e.solves, 1);
    EXPECT_LT(e.summary.rms_px, 0.5);
  }
}

// A corner 15 px off along the border is dropped and the pose solved again:
// the estimate's residual returns to the noise level.
// Verifies: REQ-SOLVER-009
TEST_F(PoseEstimatorTest, AMisplacedCornerIsRejectedAndThePoseResolved) {
  std::mt19937 rng(5);
  PoseEstimator estimator(camera_, model_);
  int rejected_right = 0;
  for (int i = 0; i < 10; ++i) {
    Problem p;
    ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 0.3, 10, p));
    const int bad = first_visible(p.observed);
    ASSERT_GE(bad, 0);
    p.observed.pixel[static_cast<std::size_t>(bad)] += Vec2(12.0, 9.0);
    const Estimate e = estimator.estimate(p.observed, SolveMode::Adaptive, p.prior);
    ASSERT_NE(e.quality, EstimateQuality::None);
    if (e.rejected[static_cast<std::size_t>(bad)]) {
      ++rejected_right;
      EXPECT_EQ(e.quality, EstimateQuality::Valid);
      EXPECT_LT(e.summary.rms_px, 1.0);
      EXPECT_FALSE(e.summary.used[static_cast<std::size_t>(bad)]);
    }
  }
  EXPECT_GE(rejected_right, 9);
}

// Verifies: REQ-SOLVER-009
TEST_F(PoseEstimatorTest, NoRejectionWhenDisabled) {
  std::mt19937 rng(5);
  EstimateOptions options;
  options.outlier_rounds = 0;
  PoseEstimator estimator(camera_, model_, options);
  Problem p;
  ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 0.3, 10, p));
  p.observed.pixel[static_cast<std::size_t>(first_visible(p.observed))] += Vec2(12.0, 9.0);
  const Estimate e = estimator.estimate(p.observed, SolveMode::Adaptive, p.prior);
  EXPECT_EQ(e.solves, 1);
  EXPECT_EQ(e.corners_rejected, 0);
  EXPECT_GT(e.summary.rms_px, 1.0);
}

// Verifies: REQ-SOLVER-008
TEST_F(PoseEstimatorTest, TooFewCornersIsNoneAndKeepsTheStart) {
  std::mt19937 rng(7);
  PoseEstimator estimator(camera_, model_);
  Problem p;
  ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 0.0, 8, p));
  int kept = 0;
  for (auto&& v : p.observed.visible) {
    if (v && kept < 3) {
      ++kept;
    } else {
      v = false;
    }
  }
  const Estimate e = estimator.estimate(p.observed, SolveMode::Adaptive, p.prior);
  EXPECT_EQ(e.quality, EstimateQuality::None);
  EXPECT_EQ(e.summary.status, SolveStatus::TooFewCorners);
  EXPECT_TRUE(e.r == p.prior);
}

// A start outside the model's bounds gives no estimate and keeps the start.
// Verifies: REQ-SOLVER-005, REQ-SOLVER-008
TEST_F(PoseEstimatorTest, AStartOutsideTheBoundsIsNone) {
  std::mt19937 rng(7);
  PoseEstimator estimator(camera_, model_);
  Problem p;
  ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 0.0, 8, p));
  PoseVector start = p.prior;
  start[kPhi] = 1e308;
  start[kTheta] = 1e308;
  const Estimate e = estimator.estimate(p.observed, SolveMode::Adaptive, start);
  EXPECT_EQ(e.quality, EstimateQuality::None);
  EXPECT_EQ(e.summary.status, SolveStatus::StartOutsideBounds);
  EXPECT_TRUE(e.r == start);
}

// Five exact corners: the solve converges, but fewer than min_corners_valid.
// Verifies: REQ-SOLVER-008
TEST_F(PoseEstimatorTest, FewCornersOrLargeResidualIsDegraded) {
  std::mt19937 rng(11);
  PoseEstimator estimator(camera_, model_);
  Problem p;
  ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 0.0, 8, p));
  int kept = 0;
  for (auto&& v : p.observed.visible) {
    if (v && kept < 5) {
      ++kept;
    } else {
      v = false;
    }
  }
  const Estimate few = estimator.estimate(p.observed, SolveMode::FixedModel, p.prior);
  EXPECT_EQ(few.quality, EstimateQuality::Degraded);

  Problem q;
  ASSERT_TRUE(draw_problem(rng, camera_, model_, false, 4.0, 10, q));
  estimator.options().max_rms_valid_px = 0.5;
  const Estimate noisy = estimator.estimate(q.observed, SolveMode::Adaptive, q.prior);
  EXPECT_EQ(noisy.quality, EstimateQuality::Degraded);
}

// Verifies: REQ-SOLVER-008
TEST(EstimateOptions, RangesAreChecked) {
  EXPECT_TRUE(options_valid(EstimateOptions{}));
  EstimateOptions o;
  o.min_corners_valid = 3;
  EXPECT_FALSE(options_valid(o));
  o = EstimateOptions{};
  o.outlier_rounds = kMaxOutlierRounds + 1;
  EXPECT_FALSE(options_valid(o));
  o = EstimateOptions{};
  o.max_rms_valid_px = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(options_valid(o));
  o = EstimateOptions{};
  o.outlier_median_factor = 0.5;
  EXPECT_FALSE(options_valid(o));
}

// An estimate of joints (lambda mm, phi rad, theta rad) of `quality`.
Estimate estimate_at(const InstrumentModel& model, double lambda_mm, double phi_rad, double theta_rad,
                     EstimateQuality quality) {
  Estimate e;
  e.quality = quality;
  e.r = model.geometry().nominal_pose(lambda_mm, phi_rad, theta_rad);
  return e;
}

// Within the encoders' accuracy nothing changes; beyond it, in insertion or
// in bend, the estimate loses one level. phi is compared through the bend
// vector: on a nearly straight tube any phi agrees.
// Verifies: REQ-SOLVER-010
TEST_F(PoseEstimatorTest, AnEstimateFarFromTheEncodersIsDemotedOneLevel) {
  const EncoderCheck check;  // 6 mm, 0.5 rad
  const PoseVector encoders = model_.geometry().nominal_pose(25.0, 0.3, 0.8);
  Estimate e = estimate_at(model_, 29.0, 0.5, 0.6, EstimateQuality::Valid);  // 4 mm, bend 0.24 rad off
  EXPECT_FALSE(check_against_encoders(e, encoders, check));
  EXPECT_EQ(e.quality, EstimateQuality::Valid);
  e = estimate_at(model_, 31.5, 0.3, 0.8, EstimateQuality::Valid);  // 6.5 mm off
  EXPECT_TRUE(check_against_encoders(e, encoders, check));
  EXPECT_EQ(e.quality, EstimateQuality::Degraded);
  e = estimate_at(model_, 25.0, 0.3, 0.2, EstimateQuality::Degraded);  // bend 0.6 rad off
  EXPECT_TRUE(check_against_encoders(e, encoders, check));
  EXPECT_EQ(e.quality, EstimateQuality::None);
  e = estimate_at(model_, 25.0, 0.3, 0.2, EstimateQuality::None);  // no pose: nothing to check
  EXPECT_FALSE(check_against_encoders(e, encoders, check));
  // A straight tube: phi differs by pi, the bend by 0.1 rad.
  const PoseVector straight = model_.geometry().nominal_pose(25.0, 0.0, 0.05);
  e = estimate_at(model_, 25.0, 3.14159, 0.05, EstimateQuality::Valid);
  EXPECT_FALSE(check_against_encoders(e, straight, check));
  // Tolerances of 0 check nothing; non-finite encoders neither.
  e = estimate_at(model_, 40.0, 0.3, -0.8, EstimateQuality::Valid);
  EXPECT_FALSE(check_against_encoders(e, encoders, EncoderCheck{0.0, 0.0}));
  PoseVector unknown = encoders;
  unknown[kLambda] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(check_against_encoders(e, unknown, check));
  EXPECT_EQ(e.quality, EstimateQuality::Valid);
  // The predicate answers the same and changes nothing.
  e = estimate_at(model_, 31.5, 0.3, 0.8, EstimateQuality::Valid);
  EXPECT_TRUE(disagrees_with_encoders(e, encoders, check));
  EXPECT_EQ(e.quality, EstimateQuality::Valid);
  EXPECT_FALSE(disagrees_with_encoders(estimate_at(model_, 29.0, 0.5, 0.6, EstimateQuality::Valid), encoders, check));
  EXPECT_FALSE(disagrees_with_encoders(estimate_at(model_, 40.0, 0.3, 0.2, EstimateQuality::None), encoders, check));
  EXPECT_EQ(demoted_one_level(EstimateQuality::Valid), EstimateQuality::Degraded);
  EXPECT_EQ(demoted_one_level(EstimateQuality::Degraded), EstimateQuality::None);
  EXPECT_EQ(demoted_one_level(EstimateQuality::None), EstimateQuality::None);
  EXPECT_TRUE(encoder_check_valid(check));
  EXPECT_FALSE(encoder_check_valid(EncoderCheck{-1.0, 0.5}));
  EXPECT_FALSE(encoder_check_valid(EncoderCheck{6.0, std::numeric_limits<double>::infinity()}));
}

// Verifies: REQ-SOLVER-007
TEST_F(PoseEstimatorTest, EstimateDoesNotAllocate) {
  std::mt19937 rng(13);
  PoseEstimator estimator(camera_, model_);
  Problem problems[6];
  for (auto& p : problems) {
    ASSERT_TRUE(draw_problem(rng, camera_, model_, true, 1.0, 9, p));
    p.observed.pixel[static_cast<std::size_t>(first_visible(p.observed))] += Vec2(10.0, 0.0);  // forces re-solves
  }
  std::size_t allocations = 0;
  {
    const tcpest::test::AllocationScope scope;
    for (const auto& p : problems) {
      static_cast<void>(estimator.estimate(p.observed, SolveMode::Adaptive, p.prior));  // only allocations matter here
    }
    allocations = scope.count();
  }
  EXPECT_EQ(allocations, 0U);
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
