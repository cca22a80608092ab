// A Levenberg–Marquardt problem (levenberg_marquardt.hpp) made from a
// residual function that has no derivatives of its own: the Jacobian by
// forward differences, one step per parameter (like Ceres'
// NumericDiffCostFunction with FORWARD). The fits whose residuals are read
// off the image (the class image's chamfer fit) use it,
// so that every fit runs on the one minimiser.
//
// The residual function:
//
//   Evaluation f(const Params& x, Residuals& residuals) noexcept;
//
// says whether x is acceptable (kAcceptable), whether the residuals are
// defined there although x may not be an answer (kDefinedOnly: a
// constraint of the fit, e.g. too few samples in view), or whether they
// are not defined (kUndefined: e.g. a point that does not project). A
// point must be acceptable; its shifts need only be defined. Otherwise the
// evaluation fails and the minimiser treats the trial as a failed step
// (more damping, same x). No allocation: the shifted residuals are a
// member of the adapter. The residual function must be deterministic: the
// residuals of the last acceptable point are reused when the Jacobian is
// asked there next.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

#include "tcpest/solver/levenberg_marquardt.hpp"

namespace tcpest {
namespace solver {

enum class Evaluation : std::uint8_t {
  kAcceptable,   // residuals defined, and x may be an answer
  kDefinedOnly,  // residuals defined, x outside the fit's domain (a trial there is refused)
  kUndefined,    // residuals not defined at x
};

template <int kParams, int kResiduals, typename ResidualFunction>
class ForwardDifferenceProblem {
 public:
  // The minimiser's types: the adapter is a problem of LevenbergMarquardt<kParams, kResiduals>.
  using Solver = LevenbergMarquardt<kParams, kResiduals>;
  using Params = typename Solver::Params;
  using Residuals = typename Solver::Residuals;
  using Jacobian = typename Solver::Jacobian;
  using Normal = typename Solver::Normal;

  // `steps`: the difference step of each parameter, in its unit (> 0).
  ForwardDifferenceProblem(ResidualFunction& function, const std::array<double, static_cast<std::size_t>(kParams)>& steps) noexcept
      : function_(function), steps_(steps) {}

  bool operator()(const Params& x, Residuals& residuals, Jacobian* jacobian) noexcept {
    // The minimiser asks for the Jacobian at a trial it has just evaluated
    // and accepted: the residuals there are not computed again.
    if (jacobian != nullptr && have_last_ && x == last_x_) {
      residuals = last_residuals_;
    } else if (function_(x, residuals) != Evaluation::kAcceptable) {
      have_last_ = false;
      return false;
    }
    last_x_ = x;
    last_residuals_ = residuals;
    have_last_ = true;
    if (jacobian == nullptr) {
      return true;
    }
    for (int k = 0; k < kParams; ++k) {
      const double h = steps_[static_cast<std::size_t>(k)];
      shifted_x_ = x;
      shifted_x_[k] += h;
      if (function_(shifted_x_, shifted_) == Evaluation::kUndefined) {
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
  // The last acceptable point evaluated and its residuals.
  bool have_last_ = false;
  Params last_x_ = Params::Zero();
  Residuals last_residuals_ = Residuals::Zero();
};

// Deduces the residual function's type: make_forward_difference<kParams, kResiduals>(f, steps).
template <int kParams, int kResiduals, typename ResidualFunction>
ForwardDifferenceProblem<kParams, kResiduals, ResidualFunction> make_forward_difference(
    ResidualFunction& function, const std::array<double, static_cast<std::size_t>(kParams)>& steps) noexcept {
  return ForwardDifferenceProblem<kParams, kResiduals, ResidualFunction>(function, steps);
}

}  // namespace solver
}  // namespace tcpest
