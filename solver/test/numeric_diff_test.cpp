// The forward-difference problem adapter (numeric_diff.hpp) on the
// Levenberg-Marquardt: its Jacobian against the exact one, a fit of a
// function without derivatives, and the domain passed through.
#include <gtest/gtest.h>

#include <array>

#include "tcpest/solver/levenberg_marquardt.hpp"
#include "tcpest/solver/numeric_diff.hpp"

namespace tcpest {
namespace solver {
namespace {

using Params = Eigen::Vector2d;
using Residuals = Eigen::Vector3d;

// r(x) = (x0^2 - 4, x0 x1 - 2, x1 - 1): zero at (2, 1).
struct Curved {
  int calls = 0;
  Evaluation operator()(const Params& x, Residuals& r) noexcept {
    ++calls;
    r << x[0] * x[0] - 4.0, x[0] * x[1] - 2.0, x[1] - 1.0;
    return Evaluation::kAcceptable;
  }
};

TEST(ForwardDifference, TheJacobianIsTheDerivativeToTheStepsOrder) {
  Curved f;
  auto problem = make_forward_difference<2, 3>(f, std::array<double, 2>{1e-6, 1e-6});
  const Params x(1.5, -0.5);
  Residuals r;
  Eigen::Matrix<double, 3, 2> j;
  ASSERT_TRUE(problem(x, r, &j));
  Eigen::Matrix<double, 3, 2> exact;
  exact << 2.0 * x[0], 0.0, x[1], x[0], 0.0, 1.0;
  EXPECT_LT((j - exact).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_EQ(f.calls, 3);  // the point and one shift per parameter
  ASSERT_TRUE(problem(x, r, nullptr));
  EXPECT_EQ(f.calls, 4);  // residuals alone: no shift
  ASSERT_TRUE(problem(x, r, &j));
  EXPECT_EQ(f.calls, 6);  // the Jacobian where the residuals were just computed: only the shifts
}

TEST(ForwardDifference, TheMinimiserFindsTheZeroWithoutDerivatives) {
  Curved f;
  auto problem = make_forward_difference<2, 3>(f, std::array<double, 2>{1e-7, 1e-7});
  LevenbergMarquardt<2, 3> lm;
  Params x(1.0, 3.0);
  const LmOutcome out = lm.minimise(problem, x, SolverOptions{});
  EXPECT_TRUE(out.status == LmStatus::ConvergedGradient || out.status == LmStatus::ConvergedStep ||
              out.status == LmStatus::ConvergedCostChange)
      << static_cast<int>(out.status);
  EXPECT_NEAR(x[0], 2.0, 1e-5);
  EXPECT_NEAR(x[1], 1.0, 1e-5);
}

// r(x) = x - 3, defined on x < 2.6, acceptable on x < 2.5 (or, `undefined_beyond`,
// defined only where acceptable): a trial outside the domain fails the
// evaluation, so the minimiser stops at the domain's edge, never beyond; a
// difference step may cross the edge where the residuals are still defined.
struct Bounded {
  bool undefined_beyond = false;
  Evaluation operator()(const Eigen::Matrix<double, 1, 1>& x, Eigen::Matrix<double, 1, 1>& r) const noexcept {
    if (!(x[0] < (undefined_beyond ? 2.5 : 2.6))) {
      return Evaluation::kUndefined;
    }
    r[0] = x[0] - 3.0;
    return x[0] < 2.5 ? Evaluation::kAcceptable : Evaluation::kDefinedOnly;
  }
};

TEST(ForwardDifference, TheFunctionsDomainIsTheProblemsDomain) {
  Bounded f;
  auto problem = make_forward_difference<1, 1>(f, std::array<double, 1>{1e-3});
  Eigen::Matrix<double, 1, 1> x;
  x[0] = 0.0;
  Eigen::Matrix<double, 1, 1> r;
  Eigen::Matrix<double, 1, 1> j;
  ASSERT_TRUE(problem(x, r, &j));
  x[0] = 2.4995;  // the shift crosses the edge of the acceptable points: still defined
  EXPECT_TRUE(problem(x, r, &j));
  EXPECT_NEAR(j(0, 0), 1.0, 1e-9);
  x[0] = 2.5;  // not acceptable itself
  EXPECT_FALSE(problem(x, r, &j));
  Bounded strict{true};
  auto strict_problem = make_forward_difference<1, 1>(strict, std::array<double, 1>{1e-3});
  x[0] = 2.4995;  // the shift leaves the residuals' domain
  EXPECT_FALSE(strict_problem(x, r, &j));
  LevenbergMarquardt<1, 1> lm;
  x[0] = 0.0;
  SolverOptions options;
  options.max_iterations = 50;
  lm.minimise(problem, x, options);
  EXPECT_LT(x[0], 2.5);
  EXPECT_GT(x[0], 2.0);
}

TEST(LevenbergMarquardt, MarquardtsScheduleFindsTheZeroToo) {
  Curved f;
  auto problem = make_forward_difference<2, 3>(f, std::array<double, 2>{1e-7, 1e-7});
  LevenbergMarquardt<2, 3> lm;
  Params x(1.0, 3.0);
  SolverOptions options;
  options.schedule = DampingSchedule::kMarquardt;
  options.initial_damping = 1e-2;
  const LmOutcome out = lm.minimise(problem, x, options);
  EXPECT_NE(out.status, LmStatus::InvalidInput);
  EXPECT_NEAR(x[0], 2.0, 1e-4);
  EXPECT_NEAR(x[1], 1.0, 1e-4);
}

// No trial lowers a cost whose every step leaves the domain: under
// Marquardt's schedule six rejections in a row end the minimisation, long
// before max_iterations, at the start.
struct NowhereLower {
  Evaluation operator()(const Eigen::Matrix<double, 1, 1>& x, Eigen::Matrix<double, 1, 1>& r) const noexcept {
    r[0] = x[0] - 3.0;
    return x[0] <= 0.0 ? Evaluation::kAcceptable : Evaluation::kDefinedOnly;
  }
};

TEST(LevenbergMarquardt, MarquardtsScheduleStopsAfterSixRejectionsInARow) {
  NowhereLower f;
  auto problem = make_forward_difference<1, 1>(f, std::array<double, 1>{1e-6});
  LevenbergMarquardt<1, 1> lm;
  Eigen::Matrix<double, 1, 1> x;
  x[0] = 0.0;
  SolverOptions options;
  options.schedule = DampingSchedule::kMarquardt;
  options.max_iterations = 100;
  const LmOutcome out = lm.minimise(problem, x, options);
  EXPECT_EQ(out.status, LmStatus::MaxIterations);
  EXPECT_EQ(out.iterations, 6);
  EXPECT_EQ(x[0], 0.0);
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
