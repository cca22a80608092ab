#include "tcpest/solver/instrument.hpp"

#include <cmath>

namespace tcpest {
namespace solver {

namespace {

// Below |k s| = kSeriesArc the derivative of p(s) with respect to k uses its
// series (the closed form cancels badly there).
constexpr double kSeriesArc = 1.0e-3;
// model.md: below |k L| = 1e-6 the position uses the series.
constexpr double kSeriesCurvatureArc = 1.0e-6;

using Mat37 = Eigen::Matrix<double, 3, kNumParams>;

// 1 - cos(x) without cancellation: sin^2 / (1 + cos) where cos > 0.
double one_minus_cos(double sin_x, double cos_x) noexcept {
  return (cos_x > 0.0) ? sin_x * sin_x / (1.0 + cos_x) : 1.0 - cos_x;
}

// p(s) in the base frame (model.md), with the series for tiny k L.
// sin_ks, cos_ks = sin(k s), cos(k s), computed once by the caller.
Vec3 arc_position(double k, double s, double bend_length, double sin_ks, double cos_ks) noexcept {
  if (std::fabs(k * bend_length) < kSeriesCurvatureArc) {
    return Vec3(k * s * s / 2.0, 0.0, s - k * k * s * s * s / 6.0);
  }
  return Vec3(one_minus_cos(sin_ks, cos_ks) / k, 0.0, sin_ks / k);
}
Vec3 arc_position(double k, double s, double bend_length) noexcept {
  return arc_position(k, s, bend_length, std::sin(k * s), std::cos(k * s));
}

// d p(s) / d k.
Vec3 arc_position_dk(double k, double s, double sin_ks, double cos_ks) noexcept {
  const double ks = k * s;
  if (std::fabs(ks) < kSeriesArc) {
    const double ks2 = ks * ks;
    return Vec3(s * s * (0.5 - ks2 / 8.0 + ks2 * ks2 / 144.0), 0.0, s * s * ks * (-1.0 / 3.0 + ks2 / 30.0));
  }
  return Vec3((ks * sin_ks - one_minus_cos(sin_ks, cos_ks)) / (k * k), 0.0, (ks * cos_ks - sin_ks) / (k * k));
}

// Elementary rotations and their derivatives from a cosine/sine pair.
Mat3 rotation_x_cs(double c, double s) noexcept {
  Mat3 m;
  m << 1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c;
  return m;
}
Mat3 rotation_y_cs(double c, double s) noexcept {
  Mat3 m;
  m << c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c;
  return m;
}
Mat3 rotation_z_cs(double c, double s) noexcept {
  Mat3 m;
  m << c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0;
  return m;
}
Mat3 rotation_x_derivative_cs(double c, double s) noexcept {
  Mat3 m;
  m << 0.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s;
  return m;
}
Mat3 rotation_y_derivative_cs(double c, double s) noexcept {
  Mat3 m;
  m << -s, 0.0, c, 0.0, 0.0, 0.0, -c, 0.0, -s;
  return m;
}
Mat3 rotation_z_derivative_cs(double c, double s) noexcept {
  Mat3 m;
  m << -s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0;
  return m;
}

Vec3 arc_tangent(double k, double s) noexcept { return Vec3(std::sin(k * s), 0.0, std::cos(k * s)); }
Vec3 arc_normal(double k, double s) noexcept { return Vec3(std::cos(k * s), 0.0, -std::sin(k * s)); }

bool finite_geometry(const InstrumentGeometry& g) noexcept {
  const double values[] = {g.bend_length_mm,    g.radius_mm,         g.tcp_offset_mm,         g.shaft_radius_mm,
                           g.grasper_radius_mm, g.nominal_x_ch_mm,   g.nominal_y_ch_mm,       g.nominal_psi_rad,
                           g.nominal_mu_rad,    g.penalty.position_k, g.penalty.position_scale_mm,
                           g.penalty.angle_k,   g.penalty.angle_scale_rad, g.theta_max_rad,   g.lambda_min_mm,
                           g.lambda_max_mm};
  for (double v : values) {
    if (!std::isfinite(v)) {
      return false;
    }
  }
  for (double b : g.boundaries_mm) {
    if (!std::isfinite(b)) {
      return false;
    }
  }
  return true;
}

}  // namespace

Mat3 rotation_x(double a) noexcept { return rotation_x_cs(std::cos(a), std::sin(a)); }
Mat3 rotation_y(double a) noexcept { return rotation_y_cs(std::cos(a), std::sin(a)); }
Mat3 rotation_z(double a) noexcept { return rotation_z_cs(std::cos(a), std::sin(a)); }

PoseVector InstrumentGeometry::nominal_pose(double lambda_mm, double phi_rad, double theta_rad) const noexcept {
  PoseVector r;
  r << nominal_x_ch_mm, nominal_y_ch_mm, nominal_psi_rad, nominal_mu_rad, lambda_mm, phi_rad, theta_rad;
  return r;
}

const char* to_string(GeometryError e) noexcept {
  switch (e) {
    case GeometryError::NonFiniteValue: return "a geometry value is not a finite number";
    case GeometryError::NonPositiveLength: return "bend length, radii and TCP offset must be positive";
    case GeometryError::BadBoundaries: return "marker boundaries must increase from 0 to the bend length";
    case GeometryError::RadiusTooLarge: return "tube radius too large for the tightest bend (R must be < L / theta_max)";
    case GeometryError::BadPenalty: return "penalty k must be >= 0 and its scale a > 0";
    case GeometryError::BadJointRange: return "theta_max must be positive and lambda_min < lambda_max";
  }
  return "unknown geometry error";
}

Status<GeometryError> validate(const InstrumentGeometry& g) noexcept {
  using S = Status<GeometryError>;
  if (!finite_geometry(g)) {
    return S::failure(GeometryError::NonFiniteValue);
  }
  if (!(g.bend_length_mm > 0.0) || !(g.radius_mm > 0.0) || !(g.tcp_offset_mm > 0.0) || !(g.shaft_radius_mm > 0.0) ||
      !(g.grasper_radius_mm > 0.0)) {
    return S::failure(GeometryError::NonPositiveLength);
  }
  constexpr double kTolerance = 1e-9;
  if (std::fabs(g.boundaries_mm[0]) > kTolerance ||
      std::fabs(g.boundaries_mm[kNumBoundaries - 1] - g.bend_length_mm) > kTolerance) {
    return S::failure(GeometryError::BadBoundaries);
  }
  for (int j = 1; j < kNumBoundaries; ++j) {
    if (!(g.boundaries_mm[static_cast<std::size_t>(j)] > g.boundaries_mm[static_cast<std::size_t>(j - 1)])) {
      return S::failure(GeometryError::BadBoundaries);
    }
  }
  if (!(g.theta_max_rad > 0.0) || !(g.lambda_min_mm < g.lambda_max_mm)) {
    return S::failure(GeometryError::BadJointRange);
  }
  if (!(g.radius_mm < g.bend_length_mm / g.theta_max_rad)) {
    return S::failure(GeometryError::RadiusTooLarge);
  }
  if (!(g.penalty.position_k >= 0.0) || !(g.penalty.angle_k >= 0.0) || !(g.penalty.position_scale_mm > 0.0) ||
      !(g.penalty.angle_scale_rad > 0.0)) {
    return S::failure(GeometryError::BadPenalty);
  }
  return S::success(Unit{});
}

int CornerSet::count_present() const noexcept {
  int n = 0;
  for (bool p : present) {
    n += p ? 1 : 0;
  }
  return n;
}

int CornerSet::count_in_image() const noexcept {
  int n = 0;
  for (bool p : in_image) {
    n += p ? 1 : 0;
  }
  return n;
}

Result<InstrumentModel, GeometryError> InstrumentModel::create(const InstrumentGeometry& geometry) noexcept {
  const auto status = validate(geometry);
  if (!status.ok()) {
    return Result<InstrumentModel, GeometryError>::failure(status.error());
  }
  InstrumentModel m;
  m.g_ = geometry;
  return Result<InstrumentModel, GeometryError>::success(m);
}

namespace {

// The elementary rotations of r, each angle's cosine and sine computed once:
// the frames and (in corners()) their derivatives share them.
struct PoseTrig {
  double cos_psi, sin_psi, cos_mu, sin_mu, cos_phi, sin_phi;
  Mat3 ry, rx, rz;
};

PoseFrames build_frames(const PoseVector& r, double bend_length_mm, PoseTrig& trig) noexcept {
  trig.cos_psi = std::cos(r[kPsi]);
  trig.sin_psi = std::sin(r[kPsi]);
  trig.cos_mu = std::cos(r[kMu]);
  trig.sin_mu = std::sin(r[kMu]);
  trig.cos_phi = std::cos(r[kPhi]);
  trig.sin_phi = std::sin(r[kPhi]);
  trig.ry = rotation_y_cs(trig.cos_psi, trig.sin_psi);
  trig.rx = rotation_x_cs(trig.cos_mu, trig.sin_mu);
  trig.rz = rotation_z_cs(trig.cos_phi, trig.sin_phi);
  PoseFrames f;
  f.channel_origin = Vec3(r[kXch], r[kYch], 0.0);
  f.channel_rotation = trig.ry * trig.rx;
  f.base_origin = f.channel_origin + r[kLambda] * f.channel_rotation.col(2);
  f.base_rotation = f.channel_rotation * trig.rz;
  f.curvature = r[kTheta] / bend_length_mm;
  return f;
}

}  // namespace

PoseFrames InstrumentModel::frames(const PoseVector& r) const noexcept {
  PoseTrig trig{};
  return build_frames(r, g_.bend_length_mm, trig);
}

CentrelineFrame InstrumentModel::centreline(const PoseFrames& f, double s_mm) const noexcept {
  CentrelineFrame c;
  c.position = f.base_origin + f.base_rotation * arc_position(f.curvature, s_mm, g_.bend_length_mm);
  c.tangent = f.base_rotation * arc_tangent(f.curvature, s_mm);
  c.normal = f.base_rotation * arc_normal(f.curvature, s_mm);
  c.binormal = f.base_rotation.col(1);
  return c;
}

bool circle_limb_angles(const CentrelineFrame& cf, double radius_mm, double& limb_centre_rad,
                        double& limb_half_rad) noexcept {
  // model.md: A = n . c, B = b . c, rho = hypot(A, B), a = atan2(B, A) +/- acos(-R / rho).
  const double a_coef = cf.normal.dot(cf.position);
  const double b_coef = cf.binormal.dot(cf.position);
  const double rho = std::hypot(a_coef, b_coef);
  if (!(rho > radius_mm)) {
    return false;
  }
  limb_centre_rad = std::atan2(b_coef, a_coef);
  limb_half_rad = std::acos(-radius_mm / rho);
  return true;
}

namespace {

// The limb points of the circle of `radius` at cf, labelled by side
// (model.md's rules).
CircleLimbs circle_limbs(const CameraModel& camera, const CentrelineFrame& cf, double radius) noexcept {
  CircleLimbs out;
  Vec2 c_px;
  Eigen::Matrix<double, 2, 3> c_jac;
  if (!camera.project(cf.position, c_px, c_jac)) {
    return out;
  }
  double base = 0.0;
  double delta = 0.0;
  if (!circle_limb_angles(cf, radius, base, delta)) {
    return out;
  }
  const Vec2 image_axis = c_jac * cf.tangent;
  std::array<bool, 2> valid{};
  std::array<int, 2> sides{};
  std::array<Vec2, 2> pixels{};
  std::array<Vec3, 2> points{};
  for (std::size_t i = 0U; i < 2U; ++i) {
    const double a = base + (i == 0U ? -delta : delta);
    points[i] = cf.position + radius * (std::cos(a) * cf.normal + std::sin(a) * cf.binormal);
    valid[i] = camera.project(points[i], pixels[i]);
    if (valid[i]) {
      const Vec2 v = pixels[i] - c_px;
      sides[i] = (image_axis.x() * v.y() - image_axis.y() * v.x() < 0.0) ? kSideLeft : kSideRight;
    }
  }
  if (valid[0] && valid[1] && sides[0] == sides[1]) {
    return out;  // degenerate view along the axis: the labels would collide
  }
  for (std::size_t i = 0U; i < 2U; ++i) {
    if (valid[i]) {
      const auto side = static_cast<std::size_t>(sides[i]);
      out.present[side] = true;
      out.pixel[side] = pixels[i];
      out.point[side] = points[i];
    }
  }
  return out;
}

}  // namespace

CircleLimbs InstrumentModel::limbs(const CameraModel& camera, const PoseFrames& f, double s_mm) const noexcept {
  return circle_limbs(camera, centreline(f, s_mm), g_.radius_mm);
}

CentrelineFrame InstrumentModel::shaft_frame(const PoseFrames& f, double back_mm) const noexcept {
  CentrelineFrame cf;
  cf.tangent = f.base_rotation.col(2);  // R_b z = R_ch z: Rz(phi) keeps the channel axis
  cf.normal = f.base_rotation.col(0);
  cf.binormal = f.base_rotation.col(1);
  cf.position = f.base_origin - back_mm * cf.tangent;
  return cf;
}

CircleLimbs InstrumentModel::shaft_limbs(const CameraModel& camera, const PoseFrames& f, double back_mm) const noexcept {
  return circle_limbs(camera, shaft_frame(f, back_mm), g_.shaft_radius_mm);
}

Vec3 InstrumentModel::tcp(const PoseVector& r) const noexcept {
  const PoseFrames f = frames(r);
  const CentrelineFrame end = centreline(f, g_.bend_length_mm);
  return end.position + g_.tcp_offset_mm * end.tangent;
}

void InstrumentModel::corners(const CameraModel& camera, const PoseVector& r, CornerSet& out,
                              CornerJacobians* jacobians) const noexcept {
  out.present.fill(false);
  out.in_image.fill(false);
  // The solver calls this every iteration: the trig of r is shared with the
  // derivatives below.
  PoseTrig trig{};
  const PoseFrames f = build_frames(r, g_.bend_length_mm, trig);
  {
    const CentrelineFrame end = centreline(f, g_.bend_length_mm);
    out.tcp = end.position + g_.tcp_offset_mm * end.tangent;
  }
  const double radius = g_.radius_mm;

  // Derivatives of the frames with respect to r (only when asked).
  Mat3 d_rch_dpsi;
  Mat3 d_rch_dmu;
  Mat3 d_rb[kNumParams];
  Vec3 d_ob[kNumParams];
  const double dk_dtheta = 1.0 / g_.bend_length_mm;
  if (jacobians != nullptr) {
    d_rch_dpsi = rotation_y_derivative_cs(trig.cos_psi, trig.sin_psi) * trig.rx;
    d_rch_dmu = trig.ry * rotation_x_derivative_cs(trig.cos_mu, trig.sin_mu);
    for (int q = 0; q < kNumParams; ++q) {
      d_rb[q].setZero();
      d_ob[q].setZero();
    }
    d_ob[kXch] = Vec3::UnitX();
    d_ob[kYch] = Vec3::UnitY();
    d_ob[kPsi] = r[kLambda] * d_rch_dpsi.col(2);
    d_ob[kMu] = r[kLambda] * d_rch_dmu.col(2);
    d_ob[kLambda] = f.channel_rotation.col(2);
    d_rb[kPsi] = d_rch_dpsi * trig.rz;
    d_rb[kMu] = d_rch_dmu * trig.rz;
    d_rb[kPhi] = f.channel_rotation * rotation_z_derivative_cs(trig.cos_phi, trig.sin_phi);
  }

  for (int j = 0; j < kNumBoundaries; ++j) {
    const double s = g_.boundaries_mm[static_cast<std::size_t>(j)];
    // One sine/cosine pair per boundary (the solver calls this every iteration).
    const double sin_ks = std::sin(f.curvature * s);
    const double cos_ks = std::cos(f.curvature * s);
    const Vec3 p_local = arc_position(f.curvature, s, g_.bend_length_mm, sin_ks, cos_ks);
    const Vec3 n_local(cos_ks, 0.0, -sin_ks);
    const Vec3 t_local(sin_ks, 0.0, cos_ks);
    const Vec3 c = f.base_origin + f.base_rotation * p_local;
    const Vec3 n = f.base_rotation * n_local;
    const Vec3 b = f.base_rotation.col(1);
    const Vec3 t = f.base_rotation * t_local;

    Vec2 c_px;
    Eigen::Matrix<double, 2, 3> c_jac;
    if (!camera.project(c, c_px, c_jac)) {
      continue;  // the boundary's centre is behind the camera or not projectable
    }
    const double a_coef = n.dot(c);
    const double b_coef = b.dot(c);
    const double rho = std::hypot(a_coef, b_coef);
    if (!(rho > radius)) {
      continue;  // the camera is inside the tube's circle: no limb
    }
    // a = atan2(B, A) +/- acos(-R / rho), its cosine and sine by the angle
    // sum formulas (no trigonometric call): cos(atan2(B, A)) = A / rho,
    // sin(atan2(B, A)) = B / rho, cos(delta) = w, sin(delta) = sqrt(1 - w^2) >= 0.
    const double cos_base = a_coef / rho;
    const double sin_base = b_coef / rho;
    const double w = -radius / rho;
    const double sin_delta = std::sqrt(1.0 - w * w);
    const Vec2 image_axis = c_jac * t;  // image direction of the centreline, base -> tip

    Vec3 points[2];
    Vec2 pixels[2];
    Eigen::Matrix<double, 2, 3> point_jac[2];
    bool valid[2] = {false, false};
    int sides[2] = {0, 0};
    double cos_angle[2] = {0.0, 0.0};
    double sin_angle[2] = {0.0, 0.0};
    for (int i = 0; i < 2; ++i) {
      const double sign = (i == 0) ? 1.0 : -1.0;
      cos_angle[i] = cos_base * w - sign * sin_base * sin_delta;
      sin_angle[i] = sin_base * w + sign * cos_base * sin_delta;
      points[i] = c + radius * (cos_angle[i] * n + sin_angle[i] * b);
      valid[i] = camera.project(points[i], pixels[i], point_jac[i]);
      if (valid[i]) {
        const Vec2 v = pixels[i] - c_px;
        const double cross = image_axis.x() * v.y() - image_axis.y() * v.x();
        sides[i] = (cross < 0.0) ? kSideLeft : kSideRight;
      }
    }
    if (valid[0] && valid[1] && sides[0] == sides[1]) {
      continue;  // degenerate view along the axis: the labels would collide
    }

    // Derivatives of c, n, b for this boundary (3x7 each).
    Mat37 dc;
    Mat37 dn;
    Mat37 db;
    if (jacobians != nullptr) {
      const Vec3 dp_dk = arc_position_dk(f.curvature, s, sin_ks, cos_ks);
      const Vec3 dn_dk = -s * t_local;  // d n(s)/dk
      // R_b depends on psi, mu, phi only and O_b on x_ch, y_ch, psi, mu,
      // lambda: the other columns are skipped (the solver calls this every
      // iteration).
      dc.setZero();
      dn.setZero();
      db.setZero();
      constexpr int kRotationParams[3] = {kPsi, kMu, kPhi};
      for (int q : kRotationParams) {
        dc.col(q) = d_rb[q] * p_local;
        dn.col(q) = d_rb[q] * n_local;
        db.col(q) = d_rb[q].col(1);
      }
      constexpr int kOriginParams[5] = {kXch, kYch, kPsi, kMu, kLambda};
      for (int q : kOriginParams) {
        dc.col(q) += d_ob[q];
      }
      dc.col(kTheta) += f.base_rotation * dp_dk * dk_dtheta;
      dn.col(kTheta) += f.base_rotation * dn_dk * dk_dtheta;
    }

    for (int i = 0; i < 2; ++i) {
      if (!valid[i]) {
        continue;
      }
      const int k = corner_index(j, sides[i]);
      const std::size_t ku = static_cast<std::size_t>(k);
      out.present[ku] = true;
      out.point[ku] = points[i];
      out.pixel[ku] = pixels[i];
      out.in_image[ku] = camera.in_image(pixels[i]);
      if (jacobians != nullptr) {
        const double sign = (i == 0) ? 1.0 : -1.0;
        const Eigen::Matrix<double, 1, kNumParams> d_a = c.transpose() * dn + n.transpose() * dc;
        const Eigen::Matrix<double, 1, kNumParams> d_b = c.transpose() * db + b.transpose() * dc;
        const Eigen::Matrix<double, 1, kNumParams> d_rho = (a_coef * d_a + b_coef * d_b) / rho;
        const Eigen::Matrix<double, 1, kNumParams> d_base = (a_coef * d_b - b_coef * d_a) / (rho * rho);
        const Eigen::Matrix<double, 1, kNumParams> d_w = (radius / (rho * rho)) * d_rho;
        const Eigen::Matrix<double, 1, kNumParams> d_delta = (-1.0 / sin_delta) * d_w;
        const Eigen::Matrix<double, 1, kNumParams> d_angle = d_base + sign * d_delta;
        const double ca = cos_angle[i];
        const double sa = sin_angle[i];
        const Vec3 along_circle = radius * (-sa * n + ca * b);
        const Mat37 d_point = dc + radius * (ca * dn + sa * db) + along_circle * d_angle;
        (*jacobians)[ku] = point_jac[i] * d_point;
      }
    }
  }
}

}  // namespace solver
}  // namespace tcpest
