// The camera model of model.md: OpenCV pinhole with plumb_bob distortion
// (k1, k2, p1, p2, k3), pixel centres at integer coordinates. A point is
// projectable only in front of the camera and inside the radius where the
// radial polynomial is still monotonic (past it the model folds back).
#pragma once

#include <cstdint>

#include "tcpest/common/result.hpp"
#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace solver {

// Only plumb_bob now; the enum leaves room for a fisheye (equidistant) model.
enum class DistortionModel : std::uint8_t { PlumbBob };

// Plausible ranges (docs/model.md, "Plausible ranges"): finite values outside
// them are refused as a damaged or mistyped calibration.
struct CameraIntrinsics {
  int width = 0;   // pixels, 1..kMaxImageSide
  int height = 0;  // pixels, 1..kMaxImageSide
  double fx = 0.0, fy = 0.0;  // pixels, kMinFocalPx..kMaxFocalPx
  double cx = 0.0, cy = 0.0;  // pixels, within one image width (height) of the image: -W..2W (-H..2H)
  DistortionModel model = DistortionModel::PlumbBob;
  double k1 = 0.0, k2 = 0.0, k3 = 0.0;  // radial, |k| <= kMaxRadialCoefficient
  double p1 = 0.0, p2 = 0.0;            // tangential, |p| <= kMaxTangentialCoefficient
};

constexpr int kMaxImageSide = 16384;
// A focal length below 1 px or above 1e5 px (a field of view under 0.01 deg
// on a 16384 px image) is no endoscope's.
constexpr double kMinFocalPx = 1.0;
constexpr double kMaxFocalPx = 1.0e5;
// Calibrated radial coefficients of strong wide-angle lenses stay within a
// few units; 100 leaves a wide margin. Tangential terms come from a lens
// decentred by a fraction of the focal length: real ones are below 0.01.
constexpr double kMaxRadialCoefficient = 100.0;
constexpr double kMaxTangentialCoefficient = 1.0;

// The default PAL camera of model.md (720 x 576).
CameraIntrinsics default_pal_camera() noexcept;

enum class CameraError : std::uint8_t {
  BadImageSize,      // width or height not positive, or absurdly large
  NonFiniteValue,    // a NaN or infinite parameter
  BadFocalLength,    // fx or fy outside kMinFocalPx..kMaxFocalPx
  BadPrincipalPoint, // principal point far outside the image
  BadDistortion,     // a distortion coefficient outside its plausible range
  NoValidRegion,     // the distortion leaves no projectable region around the axis
};
const char* to_string(CameraError e) noexcept;

class CameraModel {
 public:
  CameraModel() noexcept = default;
  static Result<CameraModel, CameraError> create(const CameraIntrinsics& intrinsics) noexcept;

  const CameraIntrinsics& intrinsics() const noexcept { return k_; }
  int width() const noexcept { return k_.width; }
  int height() const noexcept { return k_.height; }
  // Undistorted r^2 = x^2 + y^2 at which the radial map stops being monotonic
  // (infinity when it never does). Points at or beyond it are not projectable.
  double max_r2() const noexcept { return max_r2_; }
  // Largest distorted radius (normalised) that has a ray.
  double max_distorted_radius() const noexcept { return max_rd_; }

  // Camera-frame point (mm) to pixel. False when not projectable.
  bool project(const Vec3& point, Vec2& pixel) const noexcept;
  // Same, with d(pixel)/d(point), 2x3.
  bool project(const Vec3& point, Vec2& pixel, Eigen::Matrix<double, 2, 3>& jacobian) const noexcept;
  // Normalised undistorted coordinates (x, y) to pixel, with d(pixel)/d(x, y).
  bool distort(const Vec2& normalised, Vec2& pixel) const noexcept;
  bool distort(const Vec2& normalised, Vec2& pixel, Eigen::Matrix2d& jacobian) const noexcept;
  // Pixel to normalised undistorted coordinates (the ray x, y, 1), by Newton
  // iteration (bounded). False when the pixel has no ray.
  bool undistort(const Vec2& pixel, Vec2& normalised) const noexcept;
  // 0 <= u <= W-1 and 0 <= v <= H-1.
  bool in_image(const Vec2& pixel) const noexcept;

 private:
  CameraIntrinsics k_{};
  double max_r2_ = 0.0;
  double max_rd_ = 0.0;
};

}  // namespace solver
}  // namespace tcpest
