// The estimated joints against the truth's (what JOINTS tells the robot),
// for evaluate's and the demo's reports: insertion and bend errors, phi's
// where the tube is bent enough for phi to mean something, and how many
// estimates carry the truth's shape in its other representation
// (phi + pi, -theta: right for the TCP, wrong for the robot's joints;
// docs/model.md, "Equivalent joints"). Offline reporting: std::vector.
#pragma once

#include <cstddef>
#include <vector>

#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace cli {

class JointErrors {
 public:
  static constexpr double kBentRad = 0.2;  // |true theta| from which phi is scored

  // Ignores a pair with a non-finite value.
  void add(const solver::PoseVector& estimate, const solver::PoseVector& truth);
  std::size_t count() const noexcept { return lambda_mm_.size(); }
  // `prefix` then "error median lambda .. mm, theta .. rad, phi .. rad (true
  // theta of 0.2 rad or more: N); (phi + pi, -theta) instead of the truth's
  // joints: M". Truncated to `capacity`.
  void format(const char* prefix, char* out, std::size_t capacity) const;

 private:
  std::vector<double> lambda_mm_, theta_rad_, phi_rad_;
  long other_turn_ = 0;
};

}  // namespace cli
}  // namespace tcpest
