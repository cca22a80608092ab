// The robust Gauss-Newton step of the image fits (private header): the pose
// fit to the image (fit_pose_to_image) and the channel fit to the shaft
// (fit_channel_to_shaft) both weight their readings with Tukey's biweight
// (cut = 3 x the MAD scale, floored), add a Gaussian prior around their
// start and solve the normal equations by LDLT. Fixed size, no allocation.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace tcpest {
namespace vision {
namespace detail {

// Median of v[0..n) (reorders v). n >= 1.
inline double median_of(double* v, int n) noexcept {
  std::sort(v, v + n);
  return (n % 2 == 1) ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Tukey's cut (px) for residuals whose absolute values are abs_residuals[0..n)
// (reordered): 3 x the MAD scale, the scale at least floor_px (a fit that
// already agrees must not turn every reading into an outlier).
inline double tukey_cut_px(double* abs_residuals, int n, double floor_px) noexcept {
  return 3.0 * std::max(floor_px, 1.4826 * median_of(abs_residuals, n));
}

template <int kParams>
class RobustNormalEquations {
 public:
  using Row = Eigen::Matrix<double, kParams, 1>;

  explicit RobustNormalEquations(double cut_px) noexcept : cut_px_(cut_px) {}

  // Tukey's biweight of a residual: 0 beyond the cut (the caller skips the
  // reading then, before computing its row).
  double weight(double residual_px) const noexcept {
    const double u = residual_px / cut_px_;
    return std::fabs(u) < 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
  }

  // One reading: its residual (px), its weight, and d(residual)/d(params);
  // `in_rms`: whether it counts in rms_px.
  void add(const Row& row, double residual_px, double w, bool in_rms = true) noexcept {
    a_ += w * row * row.transpose();
    b_ += w * residual_px * row;
    if (in_rms) {
      sum_w_ += w;
      sum_wr2_ += w * residual_px * residual_px;
    }
  }

  // Weighted RMS of the residuals added that count in it (px); 1e9 when
  // none was.
  double rms_px() const noexcept { return sum_w_ > 0.0 ? std::sqrt(sum_wr2_ / sum_w_) : 1e9; }

  // The step with the prior N(start, prior_sd[k]^2) on each parameter k
  // (prior_sd: kParams values), where `from_start` = params - start. False
  // when the factorisation fails or the step is not finite.
  bool solve(const double* prior_sd, const Row& from_start, Row& delta) noexcept {
    for (int k = 0; k < kParams; ++k) {
      const double inv_var = 1.0 / (prior_sd[k] * prior_sd[k]);
      a_(k, k) += inv_var;
      b_[k] -= inv_var * from_start[k];
    }
    const Eigen::LDLT<Eigen::Matrix<double, kParams, kParams>> ldlt(a_);
    if (ldlt.info() != Eigen::Success) {
      return false;
    }
    delta = ldlt.solve(b_);
    return delta.allFinite();
  }

 private:
  double cut_px_;
  Eigen::Matrix<double, kParams, kParams> a_ = Eigen::Matrix<double, kParams, kParams>::Zero();
  Row b_ = Row::Zero();
  double sum_w_ = 0.0;
  double sum_wr2_ = 0.0;
};

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
