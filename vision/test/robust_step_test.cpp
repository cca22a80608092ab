// The robust round shared by the image fits (src/robust_step.hpp): Tukey's
// cut and weights, and the round's problem solved on the solver's
// Levenberg-Marquardt.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "../src/robust_step.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

template <int kParams, int kMaxRows>
std::unique_ptr<RobustRows<kParams, kMaxRows>> rows_with_cut(double cut_px) {
  auto rows = std::make_unique<RobustRows<kParams, kMaxRows>>();
  rows->start(cut_px);
  return rows;
}

TEST(RobustStep, TheCutIsThreeMadScalesWithAFloor) {
  double spread[5] = {4.0, 1.0, 2.0, 3.0, 5.0};  // median 3
  EXPECT_NEAR(tukey_cut_px(spread, 5, 0.3), 3.0 * 1.4826 * 3.0, 1e-12);
  double agreeing[4] = {0.0, 0.01, 0.02, 0.0};  // the fit already agrees: the floor holds
  EXPECT_DOUBLE_EQ(tukey_cut_px(agreeing, 4, 1.0), 3.0);
}

TEST(RobustStep, TukeyWeightIsOneAtZeroAndZeroFromTheCut) {
  const auto equations = rows_with_cut<2, 4>(3.0);
  EXPECT_DOUBLE_EQ(equations->weight(0.0), 1.0);
  EXPECT_NEAR(equations->weight(1.5), 0.5625, 1e-12);  // (1 - 0.25)^2
  EXPECT_DOUBLE_EQ(equations->weight(3.0), 0.0);
  EXPECT_DOUBLE_EQ(equations->weight(-7.0), 0.0);
}

TEST(RobustStep, SolvesALinearProblemAndHoldsAnUnobservedParameterAtItsPrior) {
  // Residual r_i = row_i . delta_true for delta_true = (2, -1); the third
  // parameter is not observed and stays where the prior puts it.
  auto equations = rows_with_cut<3, 8>(1e3);  // cut far away: weights ~1
  using Row = RobustRows<3, 8>::Row;
  const double truth[2] = {2.0, -1.0};
  const double rows[4][2] = {{1.0, 0.0}, {0.0, 1.0}, {1.0, 1.0}, {1.0, -2.0}};
  for (const auto& rw : rows) {
    const Row row(rw[0], rw[1], 0.0);
    const double residual = rw[0] * truth[0] + rw[1] * truth[1];
    ASSERT_TRUE(equations->add(row, residual, 1.0));
  }
  const double prior_sd[3] = {1e6, 1e6, 0.5};
  Row delta;
  ASSERT_TRUE(equations->solve(prior_sd, Row(0.0, 0.0, 0.2), delta));
  EXPECT_NEAR(delta[0], 2.0, 1e-6);
  EXPECT_NEAR(delta[1], -1.0, 1e-6);
  EXPECT_NEAR(delta[2], -0.2, 1e-9);  // back to the start
  EXPECT_GT(equations->rms_px(), 0.0);
}

// The weights enter as in the normal equations: a reading of weight w pulls
// as w readings of weight 1.
TEST(RobustStep, AWeightCountsAsRepeatedReadings) {
  auto weighted = rows_with_cut<1, 4>(1e3);
  auto repeated = rows_with_cut<1, 4>(1e3);
  using Row = RobustRows<1, 4>::Row;
  ASSERT_TRUE(weighted->add(Row(1.0), 0.0, 1.0));
  ASSERT_TRUE(weighted->add(Row(1.0), 3.0, 2.0));
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(repeated->add(Row(1.0), i == 0 ? 0.0 : 3.0, 1.0));
  }
  const double prior_sd[1] = {1e6};
  Row a;
  Row b;
  ASSERT_TRUE(weighted->solve(prior_sd, Row::Zero(), a));
  ASSERT_TRUE(repeated->solve(prior_sd, Row::Zero(), b));
  EXPECT_NEAR(a[0], 2.0, 1e-9);
  EXPECT_NEAR(a[0], b[0], 1e-12);
}

TEST(RobustStep, NoReadingGivesTheSentinelRmsAndANonFiniteRowFailsTheSolve) {
  auto equations = rows_with_cut<2, 4>(3.0);
  using Row = RobustRows<2, 4>::Row;
  EXPECT_DOUBLE_EQ(equations->rms_px(), 1e9);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ASSERT_TRUE(equations->add(Row(nan, 1.0), 1.0, 1.0));
  const double prior_sd[2] = {1.0, 1.0};
  Row delta;
  EXPECT_FALSE(equations->solve(prior_sd, Row::Zero(), delta));
}

TEST(RobustStep, AddingBeyondTheCapacityIsRefused) {
  auto equations = rows_with_cut<1, 2>(3.0);
  using Row = RobustRows<1, 2>::Row;
  EXPECT_TRUE(equations->add(Row(1.0), 0.0, 1.0));
  EXPECT_TRUE(equations->add(Row(1.0), 0.0, 1.0));
  EXPECT_FALSE(equations->add(Row(1.0), 0.0, 1.0));
  // A new round starts empty.
  equations->start(3.0);
  EXPECT_DOUBLE_EQ(equations->rms_px(), 1e9);
  EXPECT_TRUE(equations->add(Row(1.0), 0.0, 1.0));
}

// A reading kept out of the RMS (the pose fit's grasper readings) still
// moves the step: the same step as with it counted, the RMS that of the
// others alone.
TEST(RobustStep, AReadingOutOfTheRmsStillSteersTheStep) {
  auto counted = rows_with_cut<1, 4>(1e3);
  auto uncounted = rows_with_cut<1, 4>(1e3);
  using Row = RobustRows<1, 4>::Row;
  for (RobustRows<1, 4>* equations : {counted.get(), uncounted.get()}) {
    ASSERT_TRUE(equations->add(Row(1.0), 1.0, 1.0));
    ASSERT_TRUE(equations->add(Row(1.0), 3.0, 1.0, equations == counted.get()));
  }
  EXPECT_DOUBLE_EQ(counted->rms_px(), std::sqrt(5.0));
  EXPECT_DOUBLE_EQ(uncounted->rms_px(), 1.0);
  const double prior_sd[1] = {1e6};
  Row a;
  Row b;
  ASSERT_TRUE(counted->solve(prior_sd, Row::Zero(), a));
  ASSERT_TRUE(uncounted->solve(prior_sd, Row::Zero(), b));
  EXPECT_DOUBLE_EQ(a[0], b[0]);
  EXPECT_NEAR(a[0], 2.0, 1e-6);
}

}  // namespace
}  // namespace detail
}  // namespace vision
}  // namespace tcpest
