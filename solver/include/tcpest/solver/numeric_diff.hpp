// A Levenberg–Marquardt problem (levenberg_marquardt.hpp) made from a
// residual function that has no derivatives of its own: the Jacobian by
// forward differences, one step per parameter (like Ceres'
// NumericDiffCostFunction with FORWARD). The fits whose residuals are read
// off the image (the regions' pose, the class image's chamfer fit) use it,
// so that every fit runs on the one minimiser.
//
// The residual function:
//
//   bool f(const Params& x, Residuals& residuals) noexcept;
//
// false when x is outside its domain. A shifted point outside the domain
// makes the evaluation fail like x itself: the minimiser then treats the
// trial as a failed step (more damping, same x). No allocation: the shifted
// residuals are a member of the adapter.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>

namespace tcpest {
namespace solver {

template <int kParams, int kResiduals, typename ResidualFunction>
class ForwardDifferenceProblem {
 public:
  using Params = Eigen::Matrix<double, kParams, 1>;
  using Residuals = Eigen::Matrix<double, kResiduals, 1>;
  using Jacobian = Eigen::Matrix<double, kResiduals, kParams>;
  using Normal = Eigen::Matrix<double, kParams, kParams>;

  // `steps`: the difference step of each parameter, in its unit (> 0).
  ForwardDifferenceProblem(ResidualFunction& function, const std::array<double, static_cast<std::size_t>(kParams)>& steps) noexcept
      : function_(function), steps_(steps) {}

  bool operator()(const Params& x, Residuals& residuals, Jacobian* jacobian) noexcept {
    if (!function_(x, residuals)) {
      return false;
    }
    if (jacobian == nullptr) {
      return true;
    }
    for (int k = 0; k < kParams; ++k) {
      const double h = steps_[static_cast<std::size_t>(k)];
      shifted_x_ = x;
      shifted_x_[k] += h;
      if (!function_(shifted_x_, shifted_)) {
        return false;
      }
      jacobian->col(k) = (shifted_ - residuals) / h;
    }
    return true;
  }

  // No second-order term is known.
  void add_curvature(const Params& /*x*/, Normal& /*normal*/) const noexcept {}

 private:
  ResidualFunction& function_;
  std::array<double, static_cast<std::size_t>(kParams)> steps_;
  Params shifted_x_ = Params::Zero();
  Residuals shifted_ = Residuals::Zero();
};

// Deduces the residual function's type: make_forward_difference<kParams, kResiduals>(f, steps).
template <int kParams, int kResiduals, typename ResidualFunction>
ForwardDifferenceProblem<kParams, kResiduals, ResidualFunction> make_forward_difference(
    ResidualFunction& function, const std::array<double, static_cast<std::size_t>(kParams)>& steps) noexcept {
  return ForwardDifferenceProblem<kParams, kResiduals, ResidualFunction>(function, steps);
}

}  // namespace solver
}  // namespace tcpest
