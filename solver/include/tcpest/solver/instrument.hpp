// The instrument model of model.md: the channel pose, the constant-curvature
// bending section, the marker boundaries, the apparent corners with their
// left/right labels, and the TCP. Pure geometry: no I/O, no allocation.
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/common/result.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace solver {

enum class MarkerColor : std::uint8_t { Blue, Yellow };

// Plausible ranges of the geometry (docs/model.md, "Plausible ranges"):
// finite values outside them are refused as a damaged or mistyped file.
constexpr double kMaxGeometryLengthMm = 1000.0;  // lengths, radii, |positions|, lambda
constexpr double kMaxGeometryAngleRad = 2.0 * kPi;  // |angles|, theta_max, the angle scale
constexpr double kMaxPenaltyStiffness = 1.0e6;   // k of the play penalty (px^2, like the cost)

// The cubic play penalty rho(u) = (k/3) |u/a|^3 of the paper's eq. 8.
struct PenaltyParameters {
  double position_k = 15.0;                   // for x_ch, y_ch; 0..kMaxPenaltyStiffness
  double position_scale_mm = 1.0;             // a; 0 < a <= kMaxGeometryLengthMm
  double angle_k = 2.0;                       // for psi, mu; 0..kMaxPenaltyStiffness
  double angle_scale_rad = deg_to_rad(1.0);   // a; 0 < a <= kMaxGeometryAngleRad
};

// Lengths: 0 < x <= kMaxGeometryLengthMm unless said otherwise.
struct InstrumentGeometry {
  double bend_length_mm = 18.5;   // L
  double radius_mm = 1.81;        // R, over the markers; R < L / theta_max
  double tcp_offset_mm = 15.8;    // d_tcp, along the tip tangent
  std::array<double, kNumBoundaries> boundaries_mm{{0.0, 3.7, 7.4, 11.1, 14.8, 18.5}};  // s_j, 0 = s_0 < .. < s_5 = L
  std::array<MarkerColor, kNumMarkers> marker_colors{
      {MarkerColor::Blue, MarkerColor::Yellow, MarkerColor::Blue, MarkerColor::Yellow, MarkerColor::Blue}};
  // Parts the solver does not use (rendering).
  double shaft_radius_mm = 1.75;
  double grasper_radius_mm = 1.5;
  // Nominal (CAD) channel pose r_m*, left channel.
  double nominal_x_ch_mm = -13.3;             // |x| <= kMaxGeometryLengthMm
  double nominal_y_ch_mm = 6.2;               // |y| <= kMaxGeometryLengthMm
  double nominal_psi_rad = deg_to_rad(10.0);  // |psi| <= kMaxGeometryAngleRad
  double nominal_mu_rad = 0.0;                // |mu| <= kMaxGeometryAngleRad
  PenaltyParameters penalty{};
  // Joint range the instrument can reach (used to validate the geometry: the
  // tube must not fold on itself at the tightest bend; by the solver, which
  // refuses a start outside it and reports no convergence outside it; and by
  // consumers to flag absurd estimates).
  double theta_max_rad = deg_to_rad(135.0);  // 0 < theta_max <= kMaxGeometryAngleRad
  double lambda_min_mm = 0.0;                // 0 <= lambda_min < lambda_max
  double lambda_max_mm = 60.0;               // lambda_max <= kMaxGeometryLengthMm

  // r_m* followed by the given joints.
  PoseVector nominal_pose(double lambda_mm, double phi_rad, double theta_rad) const noexcept;
};

enum class GeometryError : std::uint8_t {
  NonFiniteValue,         // a NaN or infinite value
  NonPositiveLength,      // bend length, radii or TCP offset not positive
  BadBoundaries,          // not increasing, or outside [0, L]
  RadiusTooLarge,         // R >= L / theta_max: the tube would fold on itself
  BadPenalty,             // penalty k negative or scale not positive
  BadJointRange,          // theta_max not positive or lambda range empty
  OutOfRange,             // a finite value outside its plausible range (see above)
};
const char* to_string(GeometryError e) noexcept;
Status<GeometryError> validate(const InstrumentGeometry& g) noexcept;

// A point of the centreline with its frame, in the camera frame.
struct CentrelineFrame {
  Vec3 position;  // c(s)
  Vec3 tangent;   // R_b t(s), base -> tip
  Vec3 normal;    // R_b n(s), in the bending plane
  Vec3 binormal;  // R_b b
};

// The circle of the tube at one arc length as seen from the camera: its two
// limb points (model.md's apparent corners for s = s_j) labelled by side.
struct CircleLimbs {
  std::array<bool, 2> present{};   // [side]
  std::array<Vec2, 2> pixel{};     // [side]
  std::array<Vec3, 2> point{};     // [side], camera frame (mm)
};

// The tube's circle at a centreline frame, as seen from the camera (at the
// origin): the angles a of X(a) = c + R (cos a n + sin a b) of its two limb
// points are limb_centre_rad -/+ limb_half_rad; the arc facing the camera
// is centred on limb_centre_rad + pi and spans +/- (pi - limb_half_rad).
// False when the camera is inside the circle's cone (no limb).
bool circle_limb_angles(const CentrelineFrame& cf, double radius_mm, double& limb_centre_rad,
                        double& limb_half_rad) noexcept;

// Channel and base frames for a configuration r.
struct PoseFrames {
  Vec3 channel_origin;    // O_ch
  Mat3 channel_rotation;  // R_ch = Ry(psi) Rx(mu)
  Vec3 base_origin;       // O_b
  Mat3 base_rotation;     // R_b = R_ch Rz(phi)
  double curvature = 0.0; // k = theta / L, 1/mm
};

struct CornerSet {
  std::array<Vec2, kNumCorners> pixel{};     // f_hat_k, pixels
  std::array<Vec3, kNumCorners> point{};     // limb point, camera frame, mm
  std::array<bool, kNumCorners> present{};   // the model gives feature k (projectable)
  std::array<bool, kNumCorners> in_image{};  // present and inside the image
  Vec3 tcp = Vec3::Zero();
  int count_present() const noexcept;
  int count_in_image() const noexcept;
};

// d f_hat_k / d r for every present corner, 2x7.
using CornerJacobian = Eigen::Matrix<double, 2, kNumParams>;
using CornerJacobians = std::array<CornerJacobian, kNumCorners>;

Mat3 rotation_x(double angle_rad) noexcept;
Mat3 rotation_y(double angle_rad) noexcept;
Mat3 rotation_z(double angle_rad) noexcept;

// The joints (phi, theta) and (phi + pi, -theta) bend the section alike (the
// arc turns the other way in a base frame turned half round), and phi counts
// modulo 2 pi: the image gives the shape, not which of these joint values
// the robot holds. Returns `r` with (phi, theta) replaced by the equivalent
// pair nearest `reference`'s (the encoders' joints, or the start's): phi
// within pi of the reference's, and of the two turns the one with the least
// (phi - phi_ref)^2 + (theta - theta_ref)^2 (a tie keeps theta's sign). The
// other five values, the corners and the TCP are unchanged. A non-finite
// `r` or `reference` returns `r` as it is.
PoseVector nearest_equivalent_joints(const PoseVector& r, const PoseVector& reference) noexcept;

class InstrumentModel {
 public:
  InstrumentModel() noexcept = default;
  static Result<InstrumentModel, GeometryError> create(const InstrumentGeometry& geometry) noexcept;

  const InstrumentGeometry& geometry() const noexcept { return g_; }

  PoseFrames frames(const PoseVector& r) const noexcept;
  // Centreline frame at arc length s (mm, 0 = base, L = tip end).
  CentrelineFrame centreline(const PoseFrames& f, double s_mm) const noexcept;
  Vec3 tcp(const PoseVector& r) const noexcept;
  // The limb points of the tube's circle (radius R) at arc length s, with
  // model.md's rules (none if the centre or the point is not projectable,
  // none if the camera is inside the circle's cone, neither if both fall
  // on one side). At s = s_j they are corners() of boundary j (tested).
  CircleLimbs limbs(const CameraModel& camera, const PoseFrames& f, double s_mm) const noexcept;
  // The shaft (model.md: a straight tube of shaft_radius_mm along the
  // channel axis, from the channel exit to the base): its axis point
  // `back_mm` before the base, with the base's frame (tangent = the axis).
  CentrelineFrame shaft_frame(const PoseFrames& f, double back_mm) const noexcept;
  // The limb points of the shaft's circle there, with the same rules.
  CircleLimbs shaft_limbs(const CameraModel& camera, const PoseFrames& f, double back_mm) const noexcept;
  // The grasper (model.md: a rigid cylinder of grasper_radius_mm along the
  // tip tangent from s = L to the TCP): its axis point `beyond_mm` past the
  // end of the bending section, with the tip's frame (tangent = the axis).
  CentrelineFrame grasper_frame(const PoseFrames& f, double beyond_mm) const noexcept;
  // The limb points of the grasper's circle there, with the same rules.
  CircleLimbs grasper_limbs(const CameraModel& camera, const PoseFrames& f, double beyond_mm) const noexcept;
  // The apparent corners of model.md (and the TCP). With `jacobians`, also
  // their derivatives with respect to r (the limb points slide on the tube).
  void corners(const CameraModel& camera, const PoseVector& r, CornerSet& out,
               CornerJacobians* jacobians = nullptr) const noexcept;

 private:
  InstrumentGeometry g_{};
};

}  // namespace solver
}  // namespace tcpest
