#include "tcpest/solver/instrument.hpp"

#include <cmath>

#include "tcpest/common/dmath.hpp"

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
  return arc_position(k, s, bend_length, dmath::sin(k * s), dmath::cos(k * s));
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

Vec3 arc_tangent(double k, double s) noexcept { return Vec3(dmath::sin(k * s), 0.0, dmath::cos(k * s)); }
Vec3 arc_normal(double k, double s) noexcept { return Vec3(dmath::cos(k * s), 0.0, -dmath::sin(k * s)); }

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

// Every value within its plausible range (instrument.hpp). The signs the
// other checks need (positive lengths, k >= 0) are theirs; this bounds sizes.
bool plausible_geometry(const InstrumentGeometry& g) noexcept {
  const double lengths[] = {g.bend_length_mm,   g.radius_mm,       g.tcp_offset_mm,      g.shaft_radius_mm,
                            g.grasper_radius_mm, g.nominal_x_ch_mm, g.nominal_y_ch_mm,    g.lambda_min_mm,
                            g.lambda_max_mm,     g.penalty.position_scale_mm};
  for (double v : lengths) {
    if (!(std::fabs(v) <= kMaxGeometryLengthMm)) {
      return false;
    }
  }
  const double angles[] = {g.nominal_psi_rad, g.nominal_mu_rad, g.theta_max_rad, g.penalty.angle_scale_rad};
  for (double v : angles) {
    if (!(std::fabs(v) <= kMaxGeometryAngleRad)) {
      return false;
    }
  }
  return g.lambda_min_mm >= 0.0 && g.penalty.position_k <= kMaxPenaltyStiffness &&
         g.penalty.angle_k <= kMaxPenaltyStiffness;
}

}  // namespace

Mat3 rotation_x(double a) noexcept { return rotation_x_cs(dmath::cos(a), dmath::sin(a)); }
Mat3 rotation_y(double a) noexcept { return rotation_y_cs(dmath::cos(a), dmath::sin(a)); }
Mat3 rotation_z(double a) noexcept { return rotation_z_cs(dmath::cos(a), dmath::sin(a)); }

PoseVector nearest_equivalent_joints(const PoseVector& r, const PoseVector& reference) noexcept {
  if (!r.allFinite() || !reference.allFinite()) {
    return r;
  }
  const double phi_ref = reference[kPhi];
  const double theta_ref = reference[kTheta];
  // std::remainder(x, 2 pi) lies in [-pi, pi]: the turn of phi nearest the reference's.
  const double phi_same = phi_ref + std::remainder(r[kPhi] - phi_ref, 2.0 * kPi);
  const double phi_turned = phi_ref + std::remainder(r[kPhi] + kPi - phi_ref, 2.0 * kPi);
  const double theta_same = r[kTheta];
  const double theta_turned = -r[kTheta];
  const double cost_same =
      (phi_same - phi_ref) * (phi_same - phi_ref) + (theta_same - theta_ref) * (theta_same - theta_ref);
  const double cost_turned =
      (phi_turned - phi_ref) * (phi_turned - phi_ref) + (theta_turned - theta_ref) * (theta_turned - theta_ref);
  PoseVector out = r;
  if (cost_turned < cost_same) {
    out[kPhi] = phi_turned;
    out[kTheta] = theta_turned;
  } else {
    out[kPhi] = phi_same;
  }
  return out;
}

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
    case GeometryError::OutOfRange: return "a geometry value lies outside its plausible range (docs/model.md)";
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
  if (!plausible_geometry(g)) {
    return S::failure(GeometryError::OutOfRange);
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
  trig.cos_psi = dmath::cos(r[kPsi]);
  trig.sin_psi = dmath::sin(r[kPsi]);
  trig.cos_mu = dmath::cos(r[kMu]);
  trig.sin_mu = dmath::sin(r[kMu]);
  trig.cos_phi = dmath::cos(r[kPhi]);
  trig.sin_phi = dmath::sin(r[kPhi]);
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
  const double rho = dmath::hypot(a_coef, b_coef);
  if (!(rho > radius_mm)) {
    return false;
  }
  limb_centre_rad = dmath::atan2(b_coef, a_coef);
  limb_half_rad = dmath::acos(-radius_mm / rho);
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
    points[i] = cf.position + radius * (dmath::cos(a) * cf.normal + dmath::sin(a) * cf.binormal);
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

CentrelineFrame InstrumentModel::grasper_frame(const PoseFrames& f, double beyond_mm) const noexcept {
  CentrelineFrame cf = centreline(f, g_.bend_length_mm);
  cf.position += beyond_mm * cf.tangent;
  return cf;
}

CircleLimbs InstrumentModel::grasper_limbs(const CameraModel& camera, const PoseFrames& f,
                                           double beyond_mm) const noexcept {
  return circle_limbs(camera, grasper_frame(f, beyond_mm), g_.grasper_radius_mm);
}

Vec3 InstrumentModel::tcp(const PoseVector& r) const noexcept {
  const PoseFrames f = frames(r);
  const CentrelineFrame end = centreline(f, g_.bend_length_mm);
  return end.position + g_.tcp_offset_mm * end.tangent;
}

namespace {

// The base frame's derivatives with respect to r (model.md): R_b by psi,
// mu and phi, O_b by x_ch, y_ch, psi, mu and lambda (the other entries
// zero).
struct FrameDerivatives {
  Mat3 d_rb[kNumParams];
  Vec3 d_ob[kNumParams];
};

void frame_derivatives(const PoseVector& r, const PoseFrames& f, const PoseTrig& trig, FrameDerivatives& d) noexcept {
  const Mat3 d_rch_dpsi = rotation_y_derivative_cs(trig.cos_psi, trig.sin_psi) * trig.rx;
  const Mat3 d_rch_dmu = trig.ry * rotation_x_derivative_cs(trig.cos_mu, trig.sin_mu);
  for (int q = 0; q < kNumParams; ++q) {
    d.d_rb[q].setZero();
    d.d_ob[q].setZero();
  }
  d.d_ob[kXch] = Vec3::UnitX();
  d.d_ob[kYch] = Vec3::UnitY();
  d.d_ob[kPsi] = r[kLambda] * d_rch_dpsi.col(2);
  d.d_ob[kMu] = r[kLambda] * d_rch_dmu.col(2);
  d.d_ob[kLambda] = f.channel_rotation.col(2);
  d.d_rb[kPsi] = d_rch_dpsi * trig.rz;
  d.d_rb[kMu] = d_rch_dmu * trig.rz;
  d.d_rb[kPhi] = f.channel_rotation * rotation_z_derivative_cs(trig.cos_phi, trig.sin_phi);
}

// One boundary circle in the camera frame: its centre c, normal n, binormal
// b and tangent t, and (model.md) A = n . c, B = b . c, rho = hypot(A, B).
struct BoundaryCircle {
  double s = 0.0;  // arc length (mm)
  double sin_ks = 0.0;
  double cos_ks = 0.0;
  Vec3 p_local, n_local, t_local;  // in the base frame
  Vec3 c, n, b, t;
  double a_coef = 0.0;
  double b_coef = 0.0;
  double rho = 0.0;
};

// The two limb points of a boundary circle: the points, their pixels and
// projection Jacobians, validity, side labels and the angles' cosines and
// sines.
struct LimbPair {
  Vec3 points[2];
  Vec2 pixels[2];
  Eigen::Matrix<double, 2, 3> point_jac[2];
  bool valid[2] = {false, false};
  int sides[2] = {0, 0};
  double cos_angle[2] = {0.0, 0.0};
  double sin_angle[2] = {0.0, 0.0};
  double sin_delta = 0.0;
};

// The limb points of circle bc of `radius`. False where its centre does not
// project, the camera is inside the circle (no limb), or the view runs
// along the axis (both labels the same).
bool limb_pair(const CameraModel& camera, const BoundaryCircle& bc, double radius, LimbPair& lp) noexcept {
  Vec2 c_px;
  Eigen::Matrix<double, 2, 3> c_jac;
  if (!camera.project(bc.c, c_px, c_jac)) {
    return false;  // the boundary's centre is behind the camera or not projectable
  }
  if (!(bc.rho > radius)) {
    return false;  // the camera is inside the tube's circle: no limb
  }
  // a = atan2(B, A) +/- acos(-R / rho), its cosine and sine by the angle
  // sum formulas (no trigonometric call): cos(atan2(B, A)) = A / rho,
  // sin(atan2(B, A)) = B / rho, cos(delta) = w, sin(delta) = sqrt(1 - w^2) >= 0.
  const double cos_base = bc.a_coef / bc.rho;
  const double sin_base = bc.b_coef / bc.rho;
  const double w = -radius / bc.rho;
  lp.sin_delta = std::sqrt(1.0 - w * w);
  const Vec2 image_axis = c_jac * bc.t;  // image direction of the centreline, base -> tip
  for (int i = 0; i < 2; ++i) {
    const double sign = (i == 0) ? 1.0 : -1.0;
    lp.cos_angle[i] = cos_base * w - sign * sin_base * lp.sin_delta;
    lp.sin_angle[i] = sin_base * w + sign * cos_base * lp.sin_delta;
    lp.points[i] = bc.c + radius * (lp.cos_angle[i] * bc.n + lp.sin_angle[i] * bc.b);
    lp.valid[i] = camera.project(lp.points[i], lp.pixels[i], lp.point_jac[i]);
    if (lp.valid[i]) {
      const Vec2 v = lp.pixels[i] - c_px;
      const double cross = image_axis.x() * v.y() - image_axis.y() * v.x();
      lp.sides[i] = (cross < 0.0) ? kSideLeft : kSideRight;
    }
  }
  // A degenerate view along the axis: the labels would collide.
  return !(lp.valid[0] && lp.valid[1] && lp.sides[0] == lp.sides[1]);
}

// The derivatives of the circle's c, n and b with respect to r (3 x 7
// each). R_b depends on psi, mu, phi only and O_b on x_ch, y_ch, psi, mu,
// lambda: the other columns are skipped (the solver calls this every
// iteration).
void circle_derivatives(const PoseFrames& f, const FrameDerivatives& d, const BoundaryCircle& bc, double dk_dtheta,
                        Mat37& dc, Mat37& dn, Mat37& db) noexcept {
  const Vec3 dp_dk = arc_position_dk(f.curvature, bc.s, bc.sin_ks, bc.cos_ks);
  const Vec3 dn_dk = -bc.s * bc.t_local;  // d n(s)/dk
  dc.setZero();
  dn.setZero();
  db.setZero();
  constexpr int kRotationParams[3] = {kPsi, kMu, kPhi};
  for (int q : kRotationParams) {
    dc.col(q) = d.d_rb[q] * bc.p_local;
    dn.col(q) = d.d_rb[q] * bc.n_local;
    db.col(q) = d.d_rb[q].col(1);
  }
  constexpr int kOriginParams[5] = {kXch, kYch, kPsi, kMu, kLambda};
  for (int q : kOriginParams) {
    dc.col(q) += d.d_ob[q];
  }
  dc.col(kTheta) += f.base_rotation * dp_dk * dk_dtheta;
  dn.col(kTheta) += f.base_rotation * dn_dk * dk_dtheta;
}

// The image Jacobian (2 x 7) of limb point i from the circle's derivatives:
// through A, B and rho to the limb angle, then the point on the circle.
Eigen::Matrix<double, 2, kNumParams> limb_jacobian(const BoundaryCircle& bc, const LimbPair& lp, int i, double radius,
                                                   const Mat37& dc, const Mat37& dn, const Mat37& db) noexcept {
  const double sign = (i == 0) ? 1.0 : -1.0;
  const Eigen::Matrix<double, 1, kNumParams> d_a = bc.c.transpose() * dn + bc.n.transpose() * dc;
  const Eigen::Matrix<double, 1, kNumParams> d_b = bc.c.transpose() * db + bc.b.transpose() * dc;
  const Eigen::Matrix<double, 1, kNumParams> d_rho = (bc.a_coef * d_a + bc.b_coef * d_b) / bc.rho;
  const Eigen::Matrix<double, 1, kNumParams> d_base = (bc.a_coef * d_b - bc.b_coef * d_a) / (bc.rho * bc.rho);
  const Eigen::Matrix<double, 1, kNumParams> d_w = (radius / (bc.rho * bc.rho)) * d_rho;
  const Eigen::Matrix<double, 1, kNumParams> d_delta = (-1.0 / lp.sin_delta) * d_w;
  const Eigen::Matrix<double, 1, kNumParams> d_angle = d_base + sign * d_delta;
  const double ca = lp.cos_angle[i];
  const double sa = lp.sin_angle[i];
  const Vec3 along_circle = radius * (-sa * bc.n + ca * bc.b);
  const Mat37 d_point = dc + radius * (ca * dn + sa * db) + along_circle * d_angle;
  return lp.point_jac[i] * d_point;
}

}  // namespace

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
  FrameDerivatives d;
  const double dk_dtheta = 1.0 / g_.bend_length_mm;
  if (jacobians != nullptr) {
    frame_derivatives(r, f, trig, d);
  }
  for (int j = 0; j < kNumBoundaries; ++j) {
    BoundaryCircle bc;
    bc.s = g_.boundaries_mm[static_cast<std::size_t>(j)];
    // One sine/cosine pair per boundary (the solver calls this every iteration).
    bc.sin_ks = dmath::sin(f.curvature * bc.s);
    bc.cos_ks = dmath::cos(f.curvature * bc.s);
    bc.p_local = arc_position(f.curvature, bc.s, g_.bend_length_mm, bc.sin_ks, bc.cos_ks);
    bc.n_local = Vec3(bc.cos_ks, 0.0, -bc.sin_ks);
    bc.t_local = Vec3(bc.sin_ks, 0.0, bc.cos_ks);
    bc.c = f.base_origin + f.base_rotation * bc.p_local;
    bc.n = f.base_rotation * bc.n_local;
    bc.b = f.base_rotation.col(1);
    bc.t = f.base_rotation * bc.t_local;
    bc.a_coef = bc.n.dot(bc.c);
    bc.b_coef = bc.b.dot(bc.c);
    bc.rho = dmath::hypot(bc.a_coef, bc.b_coef);
    LimbPair lp;
    if (!limb_pair(camera, bc, radius, lp)) {
      continue;
    }
    Mat37 dc;
    Mat37 dn;
    Mat37 db;
    if (jacobians != nullptr) {
      circle_derivatives(f, d, bc, dk_dtheta, dc, dn, db);
    }
    for (int i = 0; i < 2; ++i) {
      if (!lp.valid[i]) {
        continue;
      }
      const int k = corner_index(j, lp.sides[i]);
      const std::size_t ku = static_cast<std::size_t>(k);
      out.present[ku] = true;
      out.point[ku] = lp.points[i];
      out.pixel[ku] = lp.pixels[i];
      out.in_image[ku] = camera.in_image(lp.pixels[i]);
      if (jacobians != nullptr) {
        (*jacobians)[ku] = limb_jacobian(bc, lp, i, radius, dc, dn, db);
      }
    }
  }
}

}  // namespace solver
}  // namespace tcpest
