#include "tcpest/solver/pose_solver.hpp"

#include <cmath>

namespace tcpest {
namespace solver {

namespace {

// Penalty residual e(u) = sqrt(2k/3) |u/a|^1.5 sign(u): 0.5 e^2 = (k/3)|u/a|^3.
double penalty_residual(double u, double k, double a) noexcept {
  const double scaled = u / a;
  const double abs_scaled = std::fabs(scaled);
  const double magnitude = std::sqrt(2.0 * k / 3.0) * abs_scaled * std::sqrt(abs_scaled);  // |u/a|^1.5
  return std::copysign(magnitude, scaled);
}

// de/du = 1.5 sqrt(2k/3) |u/a|^0.5 / a.
double penalty_derivative(double u, double k, double a) noexcept {
  return 1.5 * std::sqrt(2.0 * k / 3.0) * std::sqrt(std::fabs(u / a)) / a;
}

}  // namespace

const char* to_string(SolveStatus status) noexcept {
  switch (status) {
    case SolveStatus::ConvergedGradient: return "converged_gradient";
    case SolveStatus::ConvergedStep: return "converged_step";
    case SolveStatus::ConvergedCostChange: return "converged_cost_change";
    case SolveStatus::MaxIterations: return "max_iterations";
    case SolveStatus::NonFiniteResidual: return "non_finite_residual";
    case SolveStatus::NonFiniteJacobian: return "non_finite_jacobian";
    case SolveStatus::SingularSystem: return "singular_system";
    case SolveStatus::TooFewCorners: return "too_few_corners";
    case SolveStatus::NonFiniteCorner: return "non_finite_corner";
    case SolveStatus::CornerFarOutsideImage: return "corner_far_outside_image";
    case SolveStatus::InvalidInput: return "invalid_input";
    case SolveStatus::StartOutsideBounds: return "start_outside_bounds";
    case SolveStatus::OutsideModelBounds: return "outside_model_bounds";
  }
  return "unknown";
}

const char* describe(SolveStatus status) noexcept {
  switch (status) {
    case SolveStatus::ConvergedGradient: return "converged: the gradient vanished";
    case SolveStatus::ConvergedStep: return "converged: the step became negligible";
    case SolveStatus::ConvergedCostChange: return "converged: the cost stopped decreasing";
    case SolveStatus::MaxIterations: return "stopped at the iteration limit without converging";
    case SolveStatus::NonFiniteResidual: return "a residual or the cost at the start is not finite";
    case SolveStatus::NonFiniteJacobian: return "the Jacobian at the start is not finite";
    case SolveStatus::SingularSystem: return "the damped normal equations are singular";
    case SolveStatus::TooFewCorners: return "fewer than 4 usable corners";
    case SolveStatus::NonFiniteCorner: return "a visible corner is NaN or infinite";
    case SolveStatus::CornerFarOutsideImage: return "a visible corner lies far outside the image";
    case SolveStatus::InvalidInput: return "invalid solver options or start configuration";
    case SolveStatus::StartOutsideBounds: return "the start lies outside the model's bounds";
    case SolveStatus::OutsideModelBounds: return "the solve ended outside the instrument's joint range (not converged)";
  }
  return "unknown status";
}

bool is_converged(SolveStatus status) noexcept {
  return status == SolveStatus::ConvergedGradient || status == SolveStatus::ConvergedStep ||
         status == SolveStatus::ConvergedCostChange;
}

SolveStatus to_solve_status(LmStatus status) noexcept {
  switch (status) {
    case LmStatus::ConvergedGradient: return SolveStatus::ConvergedGradient;
    case LmStatus::ConvergedStep: return SolveStatus::ConvergedStep;
    case LmStatus::ConvergedCostChange: return SolveStatus::ConvergedCostChange;
    case LmStatus::MaxIterations: return SolveStatus::MaxIterations;
    case LmStatus::NonFiniteResidual: return SolveStatus::NonFiniteResidual;
    case LmStatus::NonFiniteJacobian: return SolveStatus::NonFiniteJacobian;
    case LmStatus::SingularSystem: return SolveStatus::SingularSystem;
    case LmStatus::InvalidInput: return SolveStatus::InvalidInput;
  }
  return SolveStatus::InvalidInput;
}

bool valid(const SolverOptions& o) noexcept {
  const bool finite = std::isfinite(o.gradient_tolerance) && std::isfinite(o.step_tolerance) &&
                      std::isfinite(o.cost_change_tolerance) && std::isfinite(o.initial_damping);
  return finite && o.max_iterations >= 1 && o.max_iterations <= kMaxIterationsCap && o.gradient_tolerance >= 0.0 &&
         o.step_tolerance >= 0.0 && o.cost_change_tolerance >= 0.0 && o.initial_damping > 0.0;
}

bool estimate_within_bounds(const InstrumentGeometry& g, const PoseVector& r) noexcept {
  return r[kLambda] >= g.lambda_min_mm && r[kLambda] <= g.lambda_max_mm && std::fabs(r[kTheta]) <= g.theta_max_rad;
}

bool start_within_bounds(const InstrumentGeometry& g, const PoseVector& r) noexcept {
  constexpr double kFullTurn = 2.0 * kPi;
  return estimate_within_bounds(g, r) && std::fabs(r[kPhi]) <= kMaxStartPhiRad &&
         std::fabs(r[kXch]) <= kMaxGeometryLengthMm && std::fabs(r[kYch]) <= kMaxGeometryLengthMm &&
         std::fabs(r[kPsi]) <= kFullTurn && std::fabs(r[kMu]) <= kFullTurn;
}

const char* to_string(SolveMode mode) noexcept {
  switch (mode) {
    case SolveMode::Adaptive: return "adaptive";
    case SolveMode::FixedModel: return "fixed_model";
  }
  return "unknown";
}

int CornerObservation::count_visible() const noexcept {
  int n = 0;
  for (bool v : visible) {
    n += v ? 1 : 0;
  }
  return n;
}

// ---------------------------------------------------------------------------

template <int kParams>
PoseResidual<kParams>::PoseResidual(const CameraModel& camera, const InstrumentModel& model,
                                    const CornerObservation& observed,
                                    std::array<bool, kNumCorners>& used, int* select_count) noexcept
    : camera_(camera), model_(model), observed_(observed), used_(used), select_count_(select_count) {
  const InstrumentGeometry& g = model_.geometry();
  penalties_ = PenaltyTable{{g.nominal_x_ch_mm, g.nominal_y_ch_mm, g.nominal_psi_rad, g.nominal_mu_rad},
                            {g.penalty.position_k, g.penalty.position_k, g.penalty.angle_k, g.penalty.angle_k},
                            {g.penalty.position_scale_mm, g.penalty.position_scale_mm, g.penalty.angle_scale_rad,
                             g.penalty.angle_scale_rad}};
}

template <int kParams>
PoseVector PoseResidual<kParams>::pose(const Params& x) const noexcept {
  if constexpr (kParams == kNumParams) {
    return x;
  } else {
    static_assert(kParams == kNumFixedModelParams, "7 (Adaptive) or 3 (FixedModel) parameters");
    return model_.geometry().nominal_pose(x[0], x[1], x[2]);
  }
}

template <int kParams>
bool PoseResidual<kParams>::operator()(const Params& x, Residuals& residuals, Jacobian* jacobian) noexcept {
  const PoseVector r = pose(x);
  model_.corners(camera_, r, corners_, (jacobian != nullptr) ? &corner_jacobians_ : nullptr);
  residuals.setZero();
  if (jacobian != nullptr) {
    jacobian->setZero();
  }
  if (select_count_ != nullptr) {
    // First evaluation, at the start: choose the corners in use once.
    int count = 0;
    for (std::size_t k = 0; k < used_.size(); ++k) {
      used_[k] = observed_.visible[k] && corners_.present[k];
      count += used_[k] ? 1 : 0;
    }
    *select_count_ = count;
    select_count_ = nullptr;
    if (count < kMinCorners) {
      return false;
    }
  }
  for (int k = 0; k < kNumCorners; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    if (!used_[ku]) {
      continue;
    }
    if (!corners_.present[ku]) {
      return false;  // a corner in use has no model counterpart here
    }
    const Eigen::Index row = 2 * static_cast<Eigen::Index>(k);
    residuals.template segment<2>(row) = corners_.pixel[ku] - observed_.pixel[ku];
    if (jacobian != nullptr) {
      if constexpr (kParams == kNumParams) {
        jacobian->template block<2, kNumParams>(row, 0) = corner_jacobians_[ku];
      } else {
        jacobian->template block<2, kNumFixedModelParams>(row, 0) =
            corner_jacobians_[ku].template rightCols<kNumFixedModelParams>();
      }
    }
  }
  if constexpr (kParams == kNumParams) {
    const double* nominal = penalties_.nominal;
    const double* stiffness = penalties_.stiffness;
    const double* scale = penalties_.scale;
    for (int i = 0; i < kNumPenalties; ++i) {
      const double u = x[i] - nominal[i];
      const int row = 2 * kNumCorners + i;
      residuals[row] = penalty_residual(u, stiffness[i], scale[i]);
      if (jacobian != nullptr) {
        (*jacobian)(row, i) = penalty_derivative(u, stiffness[i], scale[i]);
      }
    }
  }
  return true;
}

template <int kParams>
void PoseResidual<kParams>::add_curvature(const Params& x,
                                          Eigen::Matrix<double, kParams, kParams>& normal) const noexcept {
  if constexpr (kParams == kNumParams) {
    const double* nominal = penalties_.nominal;
    const double* stiffness = penalties_.stiffness;
    const double* scale = penalties_.scale;
    for (int i = 0; i < kNumPenalties; ++i) {
      normal(i, i) += 0.5 * stiffness[i] * std::fabs(x[i] - nominal[i]) / (scale[i] * scale[i] * scale[i]);
    }
  } else {
    static_cast<void>(x);       // r_m is fixed: no penalty
    static_cast<void>(normal);  // idem
  }
}

template class PoseResidual<kNumParams>;
template class PoseResidual<kNumFixedModelParams>;

// ---------------------------------------------------------------------------

PoseSolver::PoseSolver(const CameraModel& camera, const InstrumentModel& model, const SolverOptions& options) noexcept
    : camera_(camera), model_(model), options_(options) {}

bool PoseSolver::check_input(const CornerObservation& observed, const PoseVector& r,
                             SolveSummary& summary) const noexcept {
  if (!valid(options_) || !r.allFinite()) {
    summary.status = SolveStatus::InvalidInput;
    return false;
  }
  if (!start_within_bounds(model_.geometry(), r)) {
    summary.status = SolveStatus::StartOutsideBounds;
    return false;
  }
  const double width = static_cast<double>(camera_.width());
  const double height = static_cast<double>(camera_.height());
  const double margin_u = kFarOutsideImageFraction * width;
  const double margin_v = kFarOutsideImageFraction * height;
  for (int k = 0; k < kNumCorners; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    if (!observed.visible[ku]) {
      continue;
    }
    const Vec2& f = observed.pixel[ku];
    if (!f.allFinite()) {
      summary.status = SolveStatus::NonFiniteCorner;
      return false;
    }
    if (f.x() < -margin_u || f.x() > width - 1.0 + margin_u || f.y() < -margin_v || f.y() > height - 1.0 + margin_v) {
      summary.status = SolveStatus::CornerFarOutsideImage;
      return false;
    }
  }
  if (observed.count_visible() < kMinCorners) {
    summary.status = SolveStatus::TooFewCorners;
    return false;
  }
  return true;
}

void PoseSolver::finish(const Eigen::Matrix<double, kNumResiduals, 1>& residuals, SolveSummary& summary) noexcept {
  // Rows 0..23 hold f_hat_k - f_k of the used corners (zero otherwise) at the returned r.
  const double sum_sq = residuals.head<2 * kNumCorners>().squaredNorm();
  summary.rms_px = (summary.corners_used > 0) ? std::sqrt(sum_sq / static_cast<double>(summary.corners_used)) : 0.0;
}

SolveSummary PoseSolver::solve(const CornerObservation& observed, SolveMode mode, PoseVector& r) noexcept {
  SolveSummary summary;
  summary.mode = mode;
  if (mode == SolveMode::FixedModel) {
    const InstrumentGeometry& g = model_.geometry();
    r[kXch] = g.nominal_x_ch_mm;
    r[kYch] = g.nominal_y_ch_mm;
    r[kPsi] = g.nominal_psi_rad;
    r[kMu] = g.nominal_mu_rad;
  }
  if (!check_input(observed, r, summary)) {
    return summary;
  }
  // The corners in use are the visible ones the model gives at the start:
  // chosen by the residual at its first evaluation (no separate model call).
  LmOutcome outcome;
  if (mode == SolveMode::Adaptive) {
    PoseResidual<kNumParams> residual(camera_, model_, observed, summary.used, &summary.corners_used);
    PoseVector x = r;
    outcome = adaptive_lm_.minimise(residual, x, options_);
    r = x;
  } else {
    PoseResidual<kNumFixedModelParams> residual(camera_, model_, observed, summary.used, &summary.corners_used);
    Eigen::Matrix<double, kNumFixedModelParams, 1> x(r[kLambda], r[kPhi], r[kTheta]);
    outcome = fixed_lm_.minimise(residual, x, options_);
    r = residual.pose(x);
  }
  if (summary.corners_used < kMinCorners) {
    summary.status = SolveStatus::TooFewCorners;  // the residual refused the start; r is unchanged
    return summary;
  }
  summary.status = to_solve_status(outcome.status);
  summary.iterations = outcome.iterations;
  summary.initial_cost = outcome.initial_cost;
  summary.final_cost = outcome.final_cost;
  finish((mode == SolveMode::Adaptive) ? adaptive_lm_.residuals() : fixed_lm_.residuals(), summary);
  const bool has_end = is_converged(summary.status) || summary.status == SolveStatus::MaxIterations;
  if (has_end && !estimate_within_bounds(model_.geometry(), r)) {
    summary.status = SolveStatus::OutsideModelBounds;  // r is where it ended, for diagnosis
  }
  return summary;
}

double PoseSolver::cost(const CornerObservation& observed, const PoseVector& r) noexcept {
  std::array<bool, kNumCorners> used{};
  model_.corners(camera_, r, corners_, nullptr);
  for (std::size_t k = 0; k < used.size(); ++k) {
    used[k] = observed.visible[k] && corners_.present[k];
  }
  PoseResidual<kNumParams> residual(camera_, model_, observed, used, nullptr);
  Eigen::Matrix<double, kNumResiduals, 1> values;
  static_cast<void>(residual(r, values, nullptr));  // every used corner is present at r by construction
  return 0.5 * values.squaredNorm();
}

}  // namespace solver
}  // namespace tcpest
