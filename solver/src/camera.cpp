#include "tcpest/solver/camera.hpp"

#include <cmath>
#include <limits>

namespace tcpest {
namespace solver {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Beyond r^2 = 1e6 (89.94 deg off axis) nothing is in view of an endoscope;
// the validity search stops there.
constexpr double kSearchLimitR2 = 1.0e6;
constexpr int kBisectionSteps = 200;
constexpr int kNewtonSteps = 30;

// f(s) = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3: d(r * radial(r))/dr with s = r^2.
double radial_slope(const CameraIntrinsics& k, double s) noexcept {
  return 1.0 + s * (3.0 * k.k1 + s * (5.0 * k.k2 + s * 7.0 * k.k3));
}

double radial_factor(const CameraIntrinsics& k, double r2) noexcept {
  return 1.0 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
}

// First root of radial_slope on (0, kSearchLimitR2], or infinity. The
// interval is split at the slope's own critical points (roots of the
// quadratic 3 k1 + 10 k2 s + 21 k3 s^2), so each piece is monotonic and one
// sign change per piece is all there can be.
double first_fold_r2(const CameraIntrinsics& k) noexcept {
  double cuts[4] = {0.0, kSearchLimitR2, kSearchLimitR2, kSearchLimitR2};
  int n = 1;
  const double a = 21.0 * k.k3;
  const double b = 10.0 * k.k2;
  const double c = 3.0 * k.k1;
  double roots[2] = {-1.0, -1.0};
  if (a != 0.0) {
    const double disc = b * b - 4.0 * a * c;
    if (disc >= 0.0) {
      const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
      roots[0] = (q != 0.0) ? q / a : -1.0;
      roots[1] = (q != 0.0) ? c / q : -1.0;
    }
  } else if (b != 0.0) {
    roots[0] = -c / b;
  }
  if (roots[0] > roots[1]) {
    const double t = roots[0];
    roots[0] = roots[1];
    roots[1] = t;
  }
  for (double root : roots) {
    if (root > 0.0 && root < kSearchLimitR2) {
      cuts[n] = root;
      ++n;
    }
  }
  cuts[n] = kSearchLimitR2;
  for (int i = 0; i < n; ++i) {
    double lo = cuts[i];
    double hi = cuts[i + 1];
    if (radial_slope(k, hi) > 0.0) {
      continue;
    }
    if (radial_slope(k, lo) <= 0.0) {
      return lo;
    }
    for (int step = 0; step < kBisectionSteps && hi - lo > 0.0; ++step) {
      const double mid = 0.5 * (lo + hi);
      if (mid <= lo || mid >= hi) {
        break;
      }
      if (radial_slope(k, mid) > 0.0) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    return hi;
  }
  return kInfinity;
}

bool all_finite(const CameraIntrinsics& k) noexcept {
  const double values[] = {k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2, k.k3};
  for (double v : values) {
    if (!std::isfinite(v)) {
      return false;
    }
  }
  return true;
}

bool focal_plausible(double f) noexcept { return f >= kMinFocalPx && f <= kMaxFocalPx; }

bool distortion_plausible(const CameraIntrinsics& k) noexcept {
  const double radial[] = {k.k1, k.k2, k.k3};
  for (double v : radial) {
    if (!(std::fabs(v) <= kMaxRadialCoefficient)) {
      return false;
    }
  }
  return std::fabs(k.p1) <= kMaxTangentialCoefficient && std::fabs(k.p2) <= kMaxTangentialCoefficient;
}

}  // namespace

CameraIntrinsics default_pal_camera() noexcept {
  CameraIntrinsics k;
  k.width = 720;
  k.height = 576;
  k.fx = 400.0;
  k.fy = 400.0;
  k.cx = 359.5;
  k.cy = 287.5;
  k.k1 = -0.32;
  k.k2 = 0.11;
  return k;
}

const char* to_string(CameraError e) noexcept {
  switch (e) {
    case CameraError::BadImageSize: return "image width and height must be between 1 and 16384 pixels";
    case CameraError::NonFiniteValue: return "a camera parameter is not a finite number";
    case CameraError::BadFocalLength: return "focal lengths fx and fy must be 1..1e5 pixels";
    case CameraError::BadPrincipalPoint: return "principal point must lie within one image width/height of the image";
    case CameraError::BadDistortion: return "distortion coefficients must be |k1|, |k2|, |k3| <= 100, |p1|, |p2| <= 1";
    case CameraError::NoValidRegion: return "the distortion model leaves no projectable region";
  }
  return "unknown camera error";
}

Result<CameraModel, CameraError> CameraModel::create(const CameraIntrinsics& intrinsics) noexcept {
  using R = Result<CameraModel, CameraError>;
  if (intrinsics.width <= 0 || intrinsics.height <= 0 || intrinsics.width > kMaxImageSide ||
      intrinsics.height > kMaxImageSide) {
    return R::failure(CameraError::BadImageSize);
  }
  if (!all_finite(intrinsics)) {
    return R::failure(CameraError::NonFiniteValue);
  }
  if (!focal_plausible(intrinsics.fx) || !focal_plausible(intrinsics.fy)) {
    return R::failure(CameraError::BadFocalLength);
  }
  const double w = intrinsics.width;
  const double h = intrinsics.height;
  if (intrinsics.cx < -w || intrinsics.cx > 2.0 * w || intrinsics.cy < -h || intrinsics.cy > 2.0 * h) {
    return R::failure(CameraError::BadPrincipalPoint);
  }
  if (!distortion_plausible(intrinsics)) {
    return R::failure(CameraError::BadDistortion);
  }
  CameraModel m;
  m.k_ = intrinsics;
  m.max_r2_ = first_fold_r2(intrinsics);
  if (!(m.max_r2_ > 1.0e-6)) {
    return R::failure(CameraError::NoValidRegion);
  }
  if (std::isfinite(m.max_r2_)) {
    const double r = std::sqrt(m.max_r2_);
    m.max_rd_ = r * radial_factor(intrinsics, m.max_r2_);
  } else {
    m.max_rd_ = kInfinity;
  }
  return R::success(m);
}

bool CameraModel::distort(const Vec2& n, Vec2& pixel) const noexcept {
  const double x = n.x();
  const double y = n.y();
  const double r2 = x * x + y * y;
  if (!(r2 < max_r2_)) {
    return false;
  }
  const double radial = radial_factor(k_, r2);
  const double xd = x * radial + 2.0 * k_.p1 * x * y + k_.p2 * (r2 + 2.0 * x * x);
  const double yd = y * radial + k_.p1 * (r2 + 2.0 * y * y) + 2.0 * k_.p2 * x * y;
  pixel = Vec2(k_.fx * xd + k_.cx, k_.fy * yd + k_.cy);
  return true;
}

bool CameraModel::distort(const Vec2& n, Vec2& pixel, Eigen::Matrix2d& jacobian) const noexcept {
  if (!distort(n, pixel)) {
    return false;
  }
  const double x = n.x();
  const double y = n.y();
  const double r2 = x * x + y * y;
  const double radial = radial_factor(k_, r2);
  const double dradial = k_.k1 + r2 * (2.0 * k_.k2 + r2 * 3.0 * k_.k3);  // d radial / d r2
  const double dxd_dx = radial + 2.0 * x * x * dradial + 2.0 * k_.p1 * y + 6.0 * k_.p2 * x;
  const double dxd_dy = 2.0 * x * y * dradial + 2.0 * k_.p1 * x + 2.0 * k_.p2 * y;
  const double dyd_dx = 2.0 * x * y * dradial + 2.0 * k_.p1 * x + 2.0 * k_.p2 * y;
  const double dyd_dy = radial + 2.0 * y * y * dradial + 6.0 * k_.p1 * y + 2.0 * k_.p2 * x;
  jacobian << k_.fx * dxd_dx, k_.fx * dxd_dy, k_.fy * dyd_dx, k_.fy * dyd_dy;
  return true;
}

bool CameraModel::project(const Vec3& point, Vec2& pixel) const noexcept {
  if (!(point.z() > 0.0) || !point.allFinite()) {
    return false;
  }
  return distort(Vec2(point.x() / point.z(), point.y() / point.z()), pixel);
}

bool CameraModel::project(const Vec3& point, Vec2& pixel, Eigen::Matrix<double, 2, 3>& jacobian) const noexcept {
  if (!(point.z() > 0.0) || !point.allFinite()) {
    return false;
  }
  const double inv_z = 1.0 / point.z();
  const Vec2 n(point.x() * inv_z, point.y() * inv_z);
  Eigen::Matrix2d d;
  if (!distort(n, pixel, d)) {
    return false;
  }
  Eigen::Matrix<double, 2, 3> dn;  // d(x, y)/d(X, Y, Z)
  dn << inv_z, 0.0, -n.x() * inv_z, 0.0, inv_z, -n.y() * inv_z;
  jacobian = d * dn;
  return true;
}

bool CameraModel::undistort(const Vec2& pixel, Vec2& normalised) const noexcept {
  if (!pixel.allFinite()) {
    return false;
  }
  const Vec2 target((pixel.x() - k_.cx) / k_.fx, (pixel.y() - k_.cy) / k_.fy);
  const double rd = target.norm();
  if (!(rd < max_rd_)) {
    return false;
  }
  // Start from the radial-only inverse (monotonic below the fold: bisection).
  double lo = 0.0;
  double hi = std::isfinite(max_r2_) ? std::sqrt(max_r2_) : std::sqrt(kSearchLimitR2);
  for (int step = 0; step < kBisectionSteps && hi - lo > 1e-15; ++step) {
    const double mid = 0.5 * (lo + hi);
    if (mid * radial_factor(k_, mid * mid) < rd) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  const double r = 0.5 * (lo + hi);
  Vec2 n = (rd > 0.0) ? Vec2(target * (r / rd)) : Vec2(0.0, 0.0);
  // Newton on the full model (tangential terms included).
  const Vec2& target_px = pixel;
  for (int step = 0; step < kNewtonSteps; ++step) {
    Vec2 px;
    Eigen::Matrix2d j;
    if (!distort(n, px, j)) {
      return false;
    }
    const Vec2 error = px - target_px;
    if (error.squaredNorm() < 1e-24) {
      break;
    }
    const double det = j(0, 0) * j(1, 1) - j(0, 1) * j(1, 0);
    if (!(std::fabs(det) > 0.0)) {
      return false;
    }
    // 2x2 inverse written out: no LU module needed for this size.
    n.x() -= (j(1, 1) * error.x() - j(0, 1) * error.y()) / det;
    n.y() -= (-j(1, 0) * error.x() + j(0, 0) * error.y()) / det;
  }
  Vec2 check;
  if (!distort(n, check) || (check - target_px).norm() > 1e-6) {
    return false;
  }
  normalised = n;
  return true;
}

bool CameraModel::in_image(const Vec2& pixel) const noexcept {
  return pixel.x() >= 0.0 && pixel.y() >= 0.0 && pixel.x() <= static_cast<double>(k_.width - 1) &&
         pixel.y() <= static_cast<double>(k_.height - 1);
}

}  // namespace solver
}  // namespace tcpest
