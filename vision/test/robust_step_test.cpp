// The robust Gauss-Newton step shared by the image fits (src/robust_step.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../src/robust_step.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

TEST(RobustStep, TheCutIsThreeMadScalesWithAFloor) {
  double spread[5] = {4.0, 1.0, 2.0, 3.0, 5.0};  // median 3
  EXPECT_NEAR(tukey_cut_px(spread, 5, 0.3), 3.0 * 1.4826 * 3.0, 1e-12);
  double agreeing[4] = {0.0, 0.01, 0.02, 0.0};  // the fit already agrees: the floor holds
  EXPECT_DOUBLE_EQ(tukey_cut_px(agreeing, 4, 1.0), 3.0);
}

TEST(RobustStep, TukeyWeightIsOneAtZeroAndZeroFromTheCut) {
  const RobustNormalEquations<2> equations(3.0);
  EXPECT_DOUBLE_EQ(equations.weight(0.0), 1.0);
  EXPECT_NEAR(equations.weight(1.5), 0.5625, 1e-12);  // (1 - 0.25)^2
  EXPECT_DOUBLE_EQ(equations.weight(3.0), 0.0);
  EXPECT_DOUBLE_EQ(equations.weight(-7.0), 0.0);
}

TEST(RobustStep, SolvesALinearProblemAndHoldsAnUnobservedParameterAtItsPrior) {
  // Residual r_i = row_i . delta_true for delta_true = (2, -1); the third
  // parameter is not observed and stays where the prior puts it.
  RobustNormalEquations<3> equations(1e3);  // cut far away: weights ~1
  const double truth[2] = {2.0, -1.0};
  const double rows[4][2] = {{1.0, 0.0}, {0.0, 1.0}, {1.0, 1.0}, {1.0, -2.0}};
  for (const auto& rw : rows) {
    const RobustNormalEquations<3>::Row row(rw[0], rw[1], 0.0);
    const double residual = rw[0] * truth[0] + rw[1] * truth[1];
    equations.add(row, residual, 1.0);
  }
  const double prior_sd[3] = {1e6, 1e6, 0.5};
  RobustNormalEquations<3>::Row delta;
  ASSERT_TRUE(equations.solve(prior_sd, RobustNormalEquations<3>::Row(0.0, 0.0, 0.2), delta));
  EXPECT_NEAR(delta[0], 2.0, 1e-6);
  EXPECT_NEAR(delta[1], -1.0, 1e-6);
  EXPECT_NEAR(delta[2], -0.2, 1e-12);  // back to the start
  EXPECT_GT(equations.rms_px(), 0.0);
}

TEST(RobustStep, NoReadingGivesTheSentinelRmsAndANonFiniteRowFailsTheSolve) {
  RobustNormalEquations<2> equations(3.0);
  EXPECT_DOUBLE_EQ(equations.rms_px(), 1e9);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  equations.add(RobustNormalEquations<2>::Row(nan, 1.0), 1.0, 1.0);
  const double prior_sd[2] = {1.0, 1.0};
  RobustNormalEquations<2>::Row delta;
  EXPECT_FALSE(equations.solve(prior_sd, RobustNormalEquations<2>::Row::Zero(), delta));
}

// A reading kept out of the RMS (the pose fit's grasper readings) still
// moves the step: the same step as with it counted, the RMS that of the
// others alone.
TEST(RobustStep, AReadingOutOfTheRmsStillSteersTheStep) {
  RobustNormalEquations<1> counted(1e3);
  RobustNormalEquations<1> uncounted(1e3);
  for (RobustNormalEquations<1>* equations : {&counted, &uncounted}) {
    equations->add(RobustNormalEquations<1>::Row(1.0), 1.0, 1.0);
    equations->add(RobustNormalEquations<1>::Row(1.0), 3.0, 1.0, equations == &counted);
  }
  EXPECT_DOUBLE_EQ(counted.rms_px(), std::sqrt(5.0));
  EXPECT_DOUBLE_EQ(uncounted.rms_px(), 1.0);
  const double prior_sd[1] = {1e6};
  RobustNormalEquations<1>::Row a;
  RobustNormalEquations<1>::Row b;
  ASSERT_TRUE(counted.solve(prior_sd, RobustNormalEquations<1>::Row::Zero(), a));
  ASSERT_TRUE(uncounted.solve(prior_sd, RobustNormalEquations<1>::Row::Zero(), b));
  EXPECT_DOUBLE_EQ(a[0], b[0]);
  EXPECT_NEAR(a[0], 2.0, 1e-6);
}

}  // namespace
}  // namespace detail
}  // namespace vision
}  // namespace tcpest
