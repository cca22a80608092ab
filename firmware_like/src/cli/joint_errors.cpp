#include "cli/joint_errors.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace tcpest {
namespace cli {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) {
    return 0.0;
  }
  const auto middle = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2U);
  std::nth_element(v.begin(), middle, v.end());
  return *middle;
}

}  // namespace

void JointErrors::add(const solver::PoseVector& estimate, const solver::PoseVector& truth) {
  if (!estimate.allFinite() || !truth.allFinite()) {
    return;
  }
  lambda_mm_.push_back(std::fabs(estimate[solver::kLambda] - truth[solver::kLambda]));
  theta_rad_.push_back(std::fabs(estimate[solver::kTheta] - truth[solver::kTheta]));
  if (std::fabs(truth[solver::kTheta]) < kBentRad) {
    return;
  }
  const double phi_error = std::remainder(estimate[solver::kPhi] - truth[solver::kPhi], 2.0 * solver::kPi);
  phi_rad_.push_back(std::fabs(phi_error));
  if (std::fabs(phi_error) > solver::kPi / 2.0 && estimate[solver::kTheta] * truth[solver::kTheta] < 0.0) {
    ++other_turn_;
  }
}

void JointErrors::format(const char* prefix, char* out, std::size_t capacity) const {
  if (capacity == 0U) {
    return;
  }
  static_cast<void>(std::snprintf(out, capacity,
                                  "%serror median lambda %.2f mm, theta %.3f rad, phi %.3f rad (true theta "
                                  "of %.1f rad or more: %zu); (phi + pi, -theta) instead of the truth's joints: %ld",
                                  prefix, median(lambda_mm_), median(theta_rad_), median(phi_rad_), kBentRad,
                                  phi_rad_.size(), other_turn_));  // a report line: truncation is harmless
}

}  // namespace cli
}  // namespace tcpest
