// Shared vocabulary of the model: vector types, the configuration vector r and
// the feature indexing of model.md. Millimetres and radians everywhere.
#pragma once

#include <Eigen/Core>

namespace tcpest {
namespace solver {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// r = [x_ch, y_ch, psi, mu, lambda, phi, theta] (mm, mm, rad, rad, mm, rad, rad).
constexpr int kNumParams = 7;
using PoseVector = Eigen::Matrix<double, kNumParams, 1>;
enum PoseIndex : int { kXch = 0, kYch = 1, kPsi = 2, kMu = 3, kLambda = 4, kPhi = 5, kTheta = 6 };

// Six marker boundaries j = 0..5, two sides each: feature k = 2 j + side.
constexpr int kNumBoundaries = 6;
constexpr int kNumMarkers = kNumBoundaries - 1;
constexpr int kNumCorners = 2 * kNumBoundaries;
enum Side : int { kSideLeft = 0, kSideRight = 1 };
constexpr int corner_index(int boundary, int side) noexcept { return 2 * boundary + side; }

constexpr double kPi = 3.14159265358979323846;
constexpr double deg_to_rad(double deg) noexcept { return deg * kPi / 180.0; }
constexpr double rad_to_deg(double rad) noexcept { return rad * 180.0 / kPi; }

}  // namespace solver
}  // namespace tcpest
