// The robust round of the image fits (private header): the pose fit to the
// image (fit_pose_to_image) and the channel fit to the shaft
// (fit_channel_to_shaft) both weight their readings with Tukey's biweight
// (cut = 3 x the MAD scale, floored), add a Gaussian prior around their
// start and solve the round's problem on the solver's Levenberg-Marquardt.
// Fixed size, no allocation.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "robust_scale.hpp"
#include "tcpest/solver/levenberg_marquardt.hpp"

namespace tcpest {
namespace vision {
namespace detail {

// Tukey's cut (px) for residuals whose absolute values are abs_residuals[0..n)
// (reordered): 3 x the MAD scale, the scale at least floor_px (a fit that
// already agrees must not turn every reading into an outlier).
inline double tukey_cut_px(double* abs_residuals, int n, double floor_px) noexcept {
  return 3.0 * std::max(floor_px, kMadToSigma * median_of(abs_residuals, n));
}

// One round of an image fit (IRLS with re-measurement): the round's
// readings, each a row d(reading)/d(params) and its offset, weighted by
// Tukey's biweight, and a Gaussian prior around the fit's start. The image
// is read again at the next round, so a round's problem is the linearised
// one, min |W^1/2 (rows . delta - offsets)|^2 + |(from_start + delta) / sd|^2,
// and it is solved by the one Levenberg-Marquardt (a linear problem: one
// step, the damping guarding an ill-conditioned system). Fixed size: at
// most kMaxRows readings; the minimiser is a member (no allocation).
template <int kParams, int kMaxRows>
class RobustRows {
 public:
  using Row = Eigen::Matrix<double, kParams, 1>;
  static constexpr int kRows = kMaxRows + kParams;  // readings, prior
  using Residuals = Eigen::Matrix<double, kRows, 1>;
  using Jacobian = Eigen::Matrix<double, kRows, kParams>;

  // A new round: no reading, Tukey's cut at cut_px.
  void start(double cut_px) noexcept {
    cut_px_ = cut_px;
    count_ = 0;
    rows_.setZero();
    targets_.setZero();
    sum_w_ = 0.0;
    sum_wr2_ = 0.0;
  }

  // Tukey's biweight of a residual: 0 beyond the cut (the caller skips the
  // reading then, before computing its row).
  double weight(double residual_px) const noexcept {
    const double u = residual_px / cut_px_;
    return std::fabs(u) < 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
  }

  // One reading: d(reading)/d(params), its offset (px) and its weight;
  // `in_rms`: whether it counts in rms_px. False when kMaxRows are held.
  bool add(const Row& row, double residual_px, double w, bool in_rms = true) noexcept {
    if (count_ >= kMaxRows) {
      return false;
    }
    const double sqrt_w = std::sqrt(w);
    rows_.row(count_) = sqrt_w * row.transpose();
    targets_[count_] = sqrt_w * residual_px;
    ++count_;
    if (in_rms) {
      sum_w_ += w;
      sum_wr2_ += w * residual_px * residual_px;
    }
    return true;
  }

  // Weighted RMS of the offsets added that count in it (px); 1e9 when none was.
  double rms_px() const noexcept { return sum_w_ > 0.0 ? std::sqrt(sum_wr2_ / sum_w_) : 1e9; }

  // The round's step with the prior N(start, prior_sd[k]^2) on each
  // parameter k (prior_sd: kParams values), where `from_start` = params -
  // start. False when the minimiser fails or the step is not finite.
  bool solve(const double* prior_sd, const Row& from_start, Row& delta) noexcept {
    for (int k = 0; k < kParams; ++k) {
      rows_.row(kMaxRows + k).setZero();
      rows_(kMaxRows + k, k) = 1.0 / prior_sd[k];
      targets_[kMaxRows + k] = -from_start[k] / prior_sd[k];
    }
    delta.setZero();
    Problem problem{rows_, targets_};
    return solver::ended_at_a_point(lm_.minimise(problem, delta, kRoundSolve).status) && delta.allFinite();
  }

 private:
  // The linear residuals rows . delta - targets (unused rows are zero).
  struct Problem {
    const Jacobian& rows;
    const Residuals& targets;
    bool operator()(const Row& delta, Residuals& residuals, Jacobian* jacobian) const noexcept {
      residuals.noalias() = rows * delta;
      residuals -= targets;
      if (jacobian != nullptr) {
        *jacobian = rows;
      }
      return true;
    }
    void add_curvature(const Row& /*delta*/, Eigen::Matrix<double, kParams, kParams>& /*normal*/) const noexcept {}
  };
  // A linear problem: the first step lands on the minimum (the damping,
  // relative to J^T J's diagonal, is negligible there), the second finds
  // nothing left to gain.
  static constexpr solver::SolverOptions kRoundSolve{8, 0.0, 1e-12, 1e-12, 1e-12};

  double cut_px_ = 1.0;
  int count_ = 0;
  Jacobian rows_ = Jacobian::Zero();
  Residuals targets_ = Residuals::Zero();
  double sum_w_ = 0.0;
  double sum_wr2_ = 0.0;
  solver::LevenbergMarquardt<kParams, kRows> lm_;
};

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
