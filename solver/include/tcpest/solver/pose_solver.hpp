// The pose solver of the paper's section 2.4: minimises eq. 8 of model.md,
//
//   chi2(r) = 1/2 sum_k used |f_k - f_hat_k(r)|^2 + sum_i (k_i/3) |(r_m,i - r*_m,i) / a_i|^3,
//
// over all seven parameters (Adaptive) or over lambda, phi, theta with
// r_m = r*_m (FixedModel), by Levenberg–Marquardt. The cubic penalty enters
// as the exact least-squares residual sqrt(2k/3) |u/a|^1.5 sign(u), whose
// square halved is (k/3)|u/a|^3. Fixed-size, allocation-free, bounded.
//
// Corners without a model counterpart: at the start, a visible measured
// corner that the model does not give at the start configuration is left out
// of the solve (corners_used says how many remain; fewer than 4 ends with
// TooFewCorners). During the iterations, a trial step that loses a corner in
// use is rejected like a step that raises the cost (more damping, same r), so
// the set of residuals, hence the cost, never changes within a solve.
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/solver/levenberg_marquardt.hpp"
#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace solver {

enum class SolveMode : std::uint8_t {
  Adaptive,    // x_ch, y_ch, psi, mu, lambda, phi, theta
  FixedModel,  // lambda, phi, theta; r_m held at r*_m of the geometry
};
const char* to_string(SolveMode mode) noexcept;

// Every way a pose solve ends: the minimisation's (LmStatus, in the same
// order and meaning) and the pose problem's own refusals of its corners.
// The first three are the converged ones.
enum class SolveStatus : std::uint8_t {
  ConvergedGradient,      // max |J^T r| <= gradient_tolerance
  ConvergedStep,          // |dx| <= step_tolerance * (|x| + step_tolerance)
  ConvergedCostChange,    // a step lowered (or would by the model lower) the cost by <= cost_change_tolerance * cost
  MaxIterations,          // options.max_iterations trial steps without converging
  NonFiniteResidual,      // a residual or the cost at the start is NaN/inf
  NonFiniteJacobian,      // the Jacobian (or J^T J, J^T r) at the start is NaN/inf
  SingularSystem,         // the damped normal equations could not be solved
  TooFewCorners,          // fewer than 4 usable corners (empty mask included)
  NonFiniteCorner,        // a visible measured corner is NaN/inf
  CornerFarOutsideImage,  // a visible measured corner lies far outside the image
  InvalidInput,           // bad options or a non-finite start
  StartOutsideBounds,     // the start lies outside the model's bounds (see start_within_bounds)
  OutsideModelBounds,     // the minimisation ended (converged or not) outside the model's bounds: no estimate
};
constexpr int kNumSolveStatuses = 13;

// Stable snake_case name (JSON output), e.g. "converged_gradient".
const char* to_string(SolveStatus status) noexcept;
// One sentence for people.
const char* describe(SolveStatus status) noexcept;
bool is_converged(SolveStatus status) noexcept;
// The minimisation's ending as the pose solve's.
SolveStatus to_solve_status(LmStatus status) noexcept;

// Measured corners in pixels, indexed k = 2 j + side; only `visible` ones are used.
struct CornerObservation {
  std::array<Vec2, kNumCorners> pixel{};
  std::array<bool, kNumCorners> visible{};
  int count_visible() const noexcept;
};

struct SolveSummary {
  SolveStatus status = SolveStatus::InvalidInput;
  SolveMode mode = SolveMode::Adaptive;
  double initial_cost = 0.0;  // chi2 at the start (px^2), 0 when refused before evaluation
  double final_cost = 0.0;    // chi2 at the returned r
  int iterations = 0;         // LM trial steps
  double rms_px = 0.0;        // sqrt(mean over used corners of |f_k - f_hat_k|^2) at the returned r
  int corners_used = 0;
  std::array<bool, kNumCorners> used{};
};

constexpr int kMinCorners = 4;
// Number of residual rows: two per corner, then the four play penalties.
constexpr int kNumPenalties = 4;
constexpr int kNumResiduals = 2 * kNumCorners + kNumPenalties;
constexpr int kNumFixedModelParams = 3;
// A visible corner more than this many image widths/heights outside the
// image is refused (CornerFarOutsideImage): no detector reports such a point.
constexpr double kFarOutsideImageFraction = 1.0;

// The model's bounds, from the instrument geometry: lambda_min <= lambda <=
// lambda_max and |theta| <= theta_max, the joint range the instrument
// reaches. A start must also have |phi| <= kMaxStartPhiRad and an r_m with
// |x_ch|, |y_ch| <= kMaxGeometryLengthMm and |psi|, |mu| <= 2 pi
// (instrument.hpp's ranges).
// phi counts modulo 2 pi, and a prior keeps the encoders' representation,
// which may count whole turns: four turns either way are accepted. Beyond,
// it is a unit or typing error (at 1e308, sin and cos mean nothing and the
// step test relative to |x| is met at once).
constexpr double kMaxStartPhiRad = 8.0 * kPi;
bool start_within_bounds(const InstrumentGeometry& g, const PoseVector& r) noexcept;
// The end of a solve: the joints within the instrument's range (lambda,
// theta). Outside it the corners were fitted by a configuration the
// instrument cannot take.
bool estimate_within_bounds(const InstrumentGeometry& g, const PoseVector& r) noexcept;

// The residual vector of eq. 8 and its Jacobian for a chosen set of corners:
// rows 2k, 2k+1 = f_hat_k(r) - f_k for used corners (zero otherwise), rows
// 24..27 the penalties of x_ch, y_ch, psi, mu (zero in FixedModel).
// kParams = 7 (Adaptive, x = r) or 3 (FixedModel, x = [lambda, phi, theta]).
template <int kParams>
class PoseResidual {
 public:
  using Params = Eigen::Matrix<double, kParams, 1>;
  using Residuals = Eigen::Matrix<double, kNumResiduals, 1>;
  using Jacobian = Eigen::Matrix<double, kNumResiduals, kParams>;

  // `used` selects the corners. With `select_count`, the first evaluation
  // sets `used` to the visible corners the model gives there, writes their
  // number to *select_count, and fails if fewer than kMinCorners.
  PoseResidual(const CameraModel& camera, const InstrumentModel& model, const CornerObservation& observed,
               std::array<bool, kNumCorners>& used, int* select_count) noexcept;
  // False when a used corner has no model counterpart at x.
  bool operator()(const Params& x, Residuals& residuals, Jacobian* jacobian) noexcept;
  // The penalty's exact second-order term e * e'' = 0.5 k |u| / a^3 on the
  // diagonal of x_ch, y_ch, psi, mu (with it, the normal matrix holds the
  // penalty's true curvature 2 k |u| / a^3 instead of Gauss-Newton's 3/4 of
  // it, and the iterations converge faster). Nothing in FixedModel.
  void add_curvature(const Params& x, Eigen::Matrix<double, kParams, kParams>& normal) const noexcept;
  // The full configuration r for x.
  PoseVector pose(const Params& x) const noexcept;

 private:
  const CameraModel& camera_;
  const InstrumentModel& model_;
  const CornerObservation& observed_;
  std::array<bool, kNumCorners>& used_;
  int* select_count_;
  CornerSet corners_{};
  CornerJacobians corner_jacobians_{};
  // The play penalty of x_ch, y_ch, psi, mu, read from the geometry once.
  struct PenaltyTable {
    double nominal[kNumPenalties];    // r*_m (mm, mm, rad, rad)
    double stiffness[kNumPenalties];  // k
    double scale[kNumPenalties];      // a (mm, mm, rad, rad)
  };
  PenaltyTable penalties_{};
};

extern template class PoseResidual<kNumParams>;
extern template class PoseResidual<kNumFixedModelParams>;

class PoseSolver {
 public:
  // Keeps references: camera and model must outlive the solver.
  PoseSolver(const CameraModel& camera, const InstrumentModel& model,
             const SolverOptions& options = SolverOptions{}) noexcept;

  SolverOptions& options() noexcept { return options_; }
  const SolverOptions& options() const noexcept { return options_; }

  // r: the start on entry (its r_m is replaced by r*_m in FixedModel), the
  // estimate on return (the start when the input is refused).
  SolveSummary solve(const CornerObservation& observed, SolveMode mode, PoseVector& r) noexcept;

  // The value of eq. 8 at r for the given corners (all visible ones that the
  // model gives at r). For tests and tools; the solver does not call it.
  double cost(const CornerObservation& observed, const PoseVector& r) noexcept;

 private:
  // Checks the measured corners; Converged* is never returned, InvalidInput means OK here.
  bool check_input(const CornerObservation& observed, const PoseVector& r, SolveSummary& summary) const noexcept;
  static void finish(const Eigen::Matrix<double, kNumResiduals, 1>& residuals, SolveSummary& summary) noexcept;

  const CameraModel& camera_;
  const InstrumentModel& model_;
  SolverOptions options_;
  CornerSet corners_{};
  LevenbergMarquardt<kNumParams, kNumResiduals> adaptive_lm_;
  LevenbergMarquardt<kNumFixedModelParams, kNumResiduals> fixed_lm_;
};

}  // namespace solver
}  // namespace tcpest
