// A small dense Levenberg–Marquardt, shaped like Ceres' tiny_solver.h:
// fixed-size Eigen matrices (parameters and residual rows known at compile
// time), all scratch memory owned by the object, no allocation, no recursion,
// one bounded loop. The problem is a function object:
//
//   bool f(const Params& x, Residuals& residuals, Jacobian* jacobian) noexcept;
//
// returning false when x is outside the function's domain (for the pose
// problem: a corner in use has no model counterpart at x), and
//
//   void f.add_curvature(const Params& x, Normal& normal) noexcept;
//
// adding to J^T J any exact, positive semi-definite second-order term of
// the cost's Hessian it knows (or nothing). Unused residual rows must be
// zero (rows and Jacobian rows), they then add nothing.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace tcpest {
namespace solver {

// Every way a minimisation ends. The first three are the converged ones.
// Problem-specific refusals (the pose solver's corner checks) are the
// problem's own statuses, not this header's.
enum class LmStatus : std::uint8_t {
  ConvergedGradient,    // max |J^T r| <= gradient_tolerance
  ConvergedStep,        // |dx| <= step_tolerance * (|x| + step_tolerance)
  ConvergedCostChange,  // a step lowered (or would by the model lower) the cost by <= cost_change_tolerance * cost
  MaxIterations,        // options.max_iterations trial steps without converging
  NonFiniteResidual,    // a residual or the cost at the start is NaN/inf
  NonFiniteJacobian,    // the Jacobian (or J^T J, J^T r) at the start is NaN/inf
  SingularSystem,       // the damped normal equations could not be solved
  InvalidInput,         // bad options, a non-finite start, or a start outside the function's domain
};

// Whether x on return is the minimisation's answer: converged, or the
// best point within the iteration budget (not a refusal or a breakdown).
constexpr bool ended_at_a_point(LmStatus status) noexcept {
  return status == LmStatus::ConvergedGradient || status == LmStatus::ConvergedStep ||
         status == LmStatus::ConvergedCostChange || status == LmStatus::MaxIterations;
}

// A hard cap on any options.max_iterations: the worst case of a solve is
// bounded by it whatever the caller asks.
constexpr int kMaxIterationsCap = 500;

// How the damping follows the trial steps.
enum class DampingSchedule : std::uint8_t {
  // Nielsen's (tiny_solver's): an accepted step scales mu by
  // max(1/3, 1 - (2 rho - 1)^3), a rejected one by nu (2, 4, 8, ...). For
  // smooth costs whose quadratic model is good (the pose solve).
  kNielsen,
  // Marquardt's: an accepted step scales mu by 0.3, never below
  // initial_damping / 100; a rejected one by 10, and six rejections in a row
  // end the minimisation (MaxIterations: no step lowers the cost at any
  // reasonable damping); a step is tried even where the quadratic model
  // promises little. For piecewise linear costs (chamfer distances), whose
  // quadratic model says little about the next step.
  kMarquardt,
};

// When the Jacobian is evaluated.
enum class JacobianEvaluation : std::uint8_t {
  kWithEveryTrial,  // with each trial's residuals: an analytic Jacobian costs little beside them (the pose solve)
  kWhenTaken,       // only at a trial that is taken (tiny_solver's order): a numeric one costs a residual
                    // evaluation per parameter, which a rejected trial then does not pay
};

struct SolverOptions {
  int max_iterations = 100;              // trial steps (accepted or rejected), 1..kMaxIterationsCap
  double gradient_tolerance = 1e-8;      // on max |J^T r| (cost units per parameter unit)
  double step_tolerance = 1e-9;          // relative step size
  double cost_change_tolerance = 1e-6;  // relative cost decrease of an accepted step
  double initial_damping = 1e-4;         // mu0, relative to diag(J^T J) (tiny_solver: 1 / 1e4)
  DampingSchedule schedule = DampingSchedule::kNielsen;
  JacobianEvaluation jacobian = JacobianEvaluation::kWithEveryTrial;
};

// True when every field is in range (finite, positive where it must be).
bool valid(const SolverOptions& options) noexcept;

struct LmOutcome {
  LmStatus status = LmStatus::InvalidInput;
  int iterations = 0;         // trial steps evaluated (accepted or rejected)
  double initial_cost = 0.0;  // 0.5 |r(x0)|^2
  double final_cost = 0.0;    // 0.5 |r(x)|^2 at the returned x
};

template <int kParams, int kResiduals>
class LevenbergMarquardt {
 public:
  using Params = Eigen::Matrix<double, kParams, 1>;
  using Residuals = Eigen::Matrix<double, kResiduals, 1>;
  using Jacobian = Eigen::Matrix<double, kResiduals, kParams>;
  using Normal = Eigen::Matrix<double, kParams, kParams>;

  // Minimises 0.5 |f(x)|^2 from x; x holds the best point found on return
  // (the start when the solve is refused before the first step).
  template <typename Function>
  LmOutcome minimise(Function& f, Params& x, const SolverOptions& options) noexcept {
    LmOutcome out;
    if (!valid(options) || !x.allFinite()) {
      out.status = LmStatus::InvalidInput;
      return out;
    }
    if (!f(x, residuals_, &jacobian_)) {
      out.status = LmStatus::InvalidInput;
      return out;
    }
    double cost = 0.5 * residuals_.squaredNorm();
    out.initial_cost = cost;
    out.final_cost = cost;
    if (!residuals_.allFinite() || !std::isfinite(cost)) {
      out.status = LmStatus::NonFiniteResidual;
      return out;
    }
    if (!jacobian_.allFinite() || !update_normal_equations(f, x)) {
      out.status = LmStatus::NonFiniteJacobian;
      return out;
    }
    Damping damping{options.initial_damping};
    for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
      out.iterations = iteration;
      if (gradient_.template lpNorm<Eigen::Infinity>() <= options.gradient_tolerance) {
        out.status = LmStatus::ConvergedGradient;
        return out;
      }
      if (!solve_damped_step(damping.mu)) {
        out.status = LmStatus::SingularSystem;
        return out;
      }
      if (step_.norm() <= options.step_tolerance * (x.norm() + options.step_tolerance)) {
        out.status = LmStatus::ConvergedStep;
        return out;
      }
      // Decrease the quadratic model promises for this step. When even that
      // is below the cost-change tolerance, the step is not worth an
      // evaluation: converged by cost change at the current x.
      // Under Marquardt's schedule the quadratic model is not trusted for
      // this: the step is tried.
      const double predicted = -(step_.dot(gradient_) + 0.5 * step_.dot(normal_ * step_));
      if (options.schedule == DampingSchedule::kNielsen && predicted <= options.cost_change_tolerance * cost) {
        out.status = LmStatus::ConvergedCostChange;
        return out;
      }
      out.iterations = iteration + 1;
      trial_x_ = x + step_;
      double trial_cost = cost;
      const Trial trial = evaluate_trial(f, options, cost, trial_cost);
      if (trial == Trial::kLast) {
        x = trial_x_;  // taken, and the last: no Jacobian is needed after it
        residuals_ = trial_residuals_;
        out.final_cost = trial_cost;
        out.status = LmStatus::ConvergedCostChange;
        return out;
      }
      if (trial == Trial::kTaken) {
        const double actual = cost - trial_cost;
        x = trial_x_;
        residuals_ = trial_residuals_;
        jacobian_ = trial_jacobian_;
        cost = trial_cost;
        out.final_cost = cost;
        if (!update_normal_equations(f, x)) {
          // A finite J whose J^T J overflows: no sound step can follow.
          out.status = LmStatus::NonFiniteJacobian;
          return out;
        }
        damping.taken(options, actual, predicted);
      } else if (!damping.refused(options)) {
        out.status = LmStatus::MaxIterations;  // Marquardt's: six refusals in a row
        return out;
      }
    }
    out.iterations = options.max_iterations;
    out.status = LmStatus::MaxIterations;
    return out;
  }

  // The residuals at the returned x.
  const Residuals& residuals() const noexcept { return residuals_; }

 private:
  static constexpr double kMinDiagonal = 1e-6;
  static constexpr double kMaxDiagonal = 1e32;
  static constexpr double kMinDamping = 1e-16;
  static constexpr double kMaxDamping = 1e32;
  static constexpr double kMaxDampingGrowth = 1073741824.0;  // 2^30
  static constexpr double kMarquardtShrink = 0.3;
  static constexpr double kMarquardtGrowth = 10.0;
  static constexpr double kMarquardtFloorShare = 0.01;
  static constexpr int kMarquardtMaxRejections = 6;

  // The damping mu and its schedule's state.
  struct Damping {
    double mu = 0.0;
    double growth = 2.0;  // Nielsen's nu
    int refusals_in_a_row = 0;

    void taken(const SolverOptions& options, double actual, double predicted) noexcept {
      refusals_in_a_row = 0;
      if (options.schedule == DampingSchedule::kMarquardt) {
        mu = std::max(mu * kMarquardtShrink, options.initial_damping * kMarquardtFloorShare);
        return;
      }
      const double ratio = (predicted > 0.0) ? actual / predicted : 0.0;
      const double shape = 2.0 * ratio - 1.0;
      mu = std::max(mu * std::max(1.0 / 3.0, 1.0 - shape * shape * shape), kMinDamping);
      growth = 2.0;
    }
    // False when the minimisation should end (Marquardt's: six in a row).
    bool refused(const SolverOptions& options) noexcept {
      if (options.schedule == DampingSchedule::kMarquardt) {
        mu = std::min(mu * kMarquardtGrowth, kMaxDamping);
        return ++refusals_in_a_row < kMarquardtMaxRejections;
      }
      mu = std::min(mu * growth, kMaxDamping);
      growth = std::min(growth * 2.0, kMaxDampingGrowth);
      return true;
    }
  };

  // Marquardt's scaling, clamped as tiny_solver does so that a parameter
  // the residuals do not see (e.g. phi of a straight tube) still gets a
  // finite, damped step. False when the damped system does not solve.
  bool solve_damped_step(double mu) noexcept {
    damped_ = normal_;
    for (int i = 0; i < kParams; ++i) {
      damped_(i, i) += mu * std::min(std::max(normal_(i, i), kMinDiagonal), kMaxDiagonal);
    }
    llt_.compute(damped_);
    if (llt_.info() != Eigen::Success) {
      return false;
    }
    step_ = llt_.solve(-gradient_);
    return step_.allFinite();
  }

  enum class Trial : std::uint8_t { kRefused, kTaken, kLast };

  // The trial at trial_x_: refused (outside the domain, a non-finite value
  // or no lower cost: a failed step like any other, more damping, same x),
  // taken (trial_residuals_ and trial_jacobian_ set), or taken as the last
  // (lower by at most the cost-change tolerance: its Jacobian not needed).
  template <typename Function>
  Trial evaluate_trial(Function& f, const SolverOptions& options, double cost, double& trial_cost) noexcept {
    const bool jacobian_with_trial = options.jacobian == JacobianEvaluation::kWithEveryTrial;
    bool usable = f(trial_x_, trial_residuals_, jacobian_with_trial ? &trial_jacobian_ : nullptr);
    trial_cost = 0.5 * trial_residuals_.squaredNorm();
    usable = usable && std::isfinite(trial_cost) && trial_residuals_.allFinite() &&
             (!jacobian_with_trial || trial_jacobian_.allFinite());
    if (!usable || !(trial_cost < cost)) {
      return Trial::kRefused;
    }
    if (cost - trial_cost <= options.cost_change_tolerance * cost) {
      return Trial::kLast;
    }
    if (!jacobian_with_trial) {
      const bool in_domain = f(trial_x_, trial_residuals_, &trial_jacobian_);
      if (!in_domain || !trial_residuals_.allFinite() || !trial_jacobian_.allFinite() ||
          !(0.5 * trial_residuals_.squaredNorm() == trial_cost)) {
        return Trial::kRefused;
      }
    }
    return Trial::kTaken;
  }

  template <typename Function>
  bool update_normal_equations(Function& f, const Params& x) noexcept {
    // The lower triangle column by column, then mirrored: for these small
    // fixed sizes faster than Eigen's blocked GEMM path.
    for (int col = 0; col < kParams; ++col) {
      for (int row = col; row < kParams; ++row) {
        normal_(row, col) = jacobian_.col(row).dot(jacobian_.col(col));
      }
    }
    normal_.template triangularView<Eigen::StrictlyUpper>() = normal_.transpose();
    // Second-order terms sum_i e_i * Hessian(e_i) that the function knows to
    // be exact and positive (the pose problem: its penalty residuals). They
    // change the model of the cost the step is computed from, not the cost.
    f.add_curvature(x, normal_);
    gradient_.noalias() = jacobian_.transpose().lazyProduct(residuals_);
    return normal_.allFinite() && gradient_.allFinite();
  }

  Residuals residuals_ = Residuals::Zero();
  Residuals trial_residuals_ = Residuals::Zero();
  Jacobian jacobian_ = Jacobian::Zero();
  Jacobian trial_jacobian_ = Jacobian::Zero();
  Normal normal_ = Normal::Zero();
  Normal damped_ = Normal::Zero();
  Params gradient_ = Params::Zero();
  Params step_ = Params::Zero();
  Params trial_x_ = Params::Zero();
  Eigen::LLT<Normal> llt_;
};

}  // namespace solver
}  // namespace tcpest
