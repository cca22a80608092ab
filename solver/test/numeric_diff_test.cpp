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
  bool operator()(const Params& x, Residuals& r) noexcept {
    ++calls;
    r << x[0] * x[0] - 4.0, x[0] * x[1] - 2.0, x[1] - 1.0;
    return true;
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

// r(x) = x - 3 on x < 2.5: a shift or a trial outside the domain fails the
// evaluation, so the minimiser stops at the domain's edge, never beyond.
struct Bounded {
  bool operator()(const Eigen::Matrix<double, 1, 1>& x, Eigen::Matrix<double, 1, 1>& r) const noexcept {
    if (!(x[0] < 2.5)) {
      return false;
    }
    r[0] = x[0] - 3.0;
    return true;
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
  x[0] = 2.4995;  // the shift crosses the edge
  EXPECT_FALSE(problem(x, r, &j));
  LevenbergMarquardt<1, 1> lm;
  x[0] = 0.0;
  SolverOptions options;
  options.max_iterations = 50;
  lm.minimise(problem, x, options);
  EXPECT_LT(x[0], 2.5);
  EXPECT_GT(x[0], 2.0);
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
