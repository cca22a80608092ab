#include "tcpest/solver/instrument.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace tcpest {
namespace solver {
namespace {

CameraModel vectors_camera() {
  CameraIntrinsics k = default_pal_camera();
  k.p1 = 0.001;
  k.p2 = -0.0005;
  k.k3 = -0.01;
  return CameraModel::create(k).value();
}

PoseVector random_pose(std::mt19937& rng) {
  std::normal_distribution<double> play_mm(0.0, 1.5);
  std::normal_distribution<double> play_rad(0.0, deg_to_rad(3.0));
  std::uniform_real_distribution<double> lambda(10.0, 40.0);
  std::uniform_real_distribution<double> phi(-kPi, kPi);
  std::uniform_real_distribution<double> theta(-1.8, 1.8);
  PoseVector r;
  r << -13.3 + play_mm(rng), 6.2 + play_mm(rng), deg_to_rad(10.0) + play_rad(rng), play_rad(rng), lambda(rng),
      phi(rng), theta(rng);
  return r;
}

// The analytic corner Jacobians (limb points sliding on the tube) against
// central differences, over many random configurations, including nearly
// straight ones where the series take over.
// Verifies: REQ-MODEL-002
TEST(Instrument, CornerJacobiansMatchCentralDifferences) {
  const CameraModel cam = vectors_camera();
  const auto model = InstrumentModel::create(InstrumentGeometry{});
  ASSERT_TRUE(model.ok());
  std::mt19937 rng(42);
  int checked = 0;
  for (int trial = 0; trial < 400; ++trial) {
    PoseVector r = random_pose(rng);
    if (trial % 10 == 0) {
      r[kTheta] = (trial % 20 == 0) ? 0.0 : 1e-5;
    }
    CornerSet base;
    CornerJacobians jac;
    model.value().corners(cam, r, base, &jac);
    for (int q = 0; q < kNumParams; ++q) {
      const double h = (q == kPsi || q == kMu || q == kPhi || q == kTheta) ? 1e-7 : 1e-6;
      PoseVector lo = r;
      PoseVector hi = r;
      lo[q] -= h;
      hi[q] += h;
      CornerSet a;
      CornerSet b;
      model.value().corners(cam, lo, a);
      model.value().corners(cam, hi, b);
      for (int k = 0; k < kNumCorners; ++k) {
        if (!base.present[k] || !a.present[k] || !b.present[k]) {
          continue;
        }
        const Vec2 numeric = (b.pixel[k] - a.pixel[k]) / (2.0 * h);
        const double tol = 2e-4 * (1.0 + numeric.norm());
        EXPECT_NEAR(jac[k](0, q), numeric.x(), tol) << "trial " << trial << " k " << k << " q " << q;
        EXPECT_NEAR(jac[k](1, q), numeric.y(), tol) << "trial " << trial << " k " << k << " q " << q;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 10000);
}

TEST(Instrument, CornersAreOnTheLimb) {
  const CameraModel cam = vectors_camera();
  const auto model = InstrumentModel::create(InstrumentGeometry{});
  std::mt19937 rng(3);
  for (int trial = 0; trial < 50; ++trial) {
    const PoseVector r = random_pose(rng);
    CornerSet out;
    model.value().corners(cam, r, out);
    const PoseFrames f = model.value().frames(r);
    for (int k = 0; k < kNumCorners; ++k) {
      if (!out.present[k]) {
        continue;
      }
      const CentrelineFrame c = model.value().centreline(f, InstrumentGeometry{}.boundaries_mm[k / 2]);
      const Vec3 m = (out.point[k] - c.position) / 1.81;
      EXPECT_NEAR(m.norm(), 1.0, 1e-12);
      EXPECT_NEAR(m.dot(out.point[k]), 0.0, 1e-9);  // the viewing ray grazes the tube
      EXPECT_NEAR(m.dot(c.tangent), 0.0, 1e-12);
    }
  }
}

// (phi + pi, -theta) and phi + 2 pi n are the same instrument: corners
// (labels included, the sides being the image's) and TCP. The pair returned
// is the one nearest the reference, whatever turn the solve ended on.
// Verifies: REQ-MODEL-004
TEST(Instrument, EquivalentJointsNearestTheReference) {
  const CameraModel cam = vectors_camera();
  const auto model = InstrumentModel::create(InstrumentGeometry{});
  ASSERT_TRUE(model.ok());
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> turns(-12, 12);
  std::normal_distribution<double> encoder_error_rad(0.0, 0.2);
  for (int trial = 0; trial < 200; ++trial) {
    const PoseVector truth = random_pose(rng);
    PoseVector reference = truth;
    reference[kPhi] += encoder_error_rad(rng);
    reference[kTheta] += encoder_error_rad(rng);
    for (int mirrored = 0; mirrored < 2; ++mirrored) {
      PoseVector solved = truth;  // as a solve may end: another turn, the other way round
      solved[kPhi] += 2.0 * kPi * static_cast<double>(turns(rng)) + (mirrored == 1 ? kPi : 0.0);
      solved[kTheta] = mirrored == 1 ? -truth[kTheta] : truth[kTheta];
      CornerSet expected;
      CornerSet got;
      model.value().corners(cam, truth, expected);
      model.value().corners(cam, solved, got);
      for (int k = 0; k < kNumCorners; ++k) {
        ASSERT_EQ(got.present[k], expected.present[k]) << k;
        if (expected.present[k]) {
          EXPECT_NEAR((got.pixel[k] - expected.pixel[k]).norm(), 0.0, 1e-7) << k;
        }
      }
      EXPECT_NEAR((model.value().tcp(solved) - model.value().tcp(truth)).norm(), 0.0, 1e-9);

      const PoseVector out = nearest_equivalent_joints(solved, reference);
      for (int i = 0; i < kNumParams; ++i) {
        if (i != kPhi && i != kTheta) {
          EXPECT_EQ(out[i], solved[i]);
        }
      }
      EXPECT_LE(std::fabs(out[kPhi] - reference[kPhi]), kPi + 1e-12);
      if (std::fabs(truth[kTheta]) > 0.5) {  // the encoders' 0.2 rad cannot hide the bend's sign
        EXPECT_NEAR(out[kPhi], truth[kPhi], 1e-9);
        EXPECT_NEAR(out[kTheta], truth[kTheta], 1e-12);
      }
      EXPECT_NEAR((model.value().tcp(out) - model.value().tcp(truth)).norm(), 0.0, 1e-9);
    }
  }
}

// Verifies: REQ-MODEL-004
TEST(Instrument, EquivalentJointsEdgeCases) {
  PoseVector reference = InstrumentGeometry{}.nominal_pose(20.0, 0.0, 0.0);
  // The generic reference (phi = theta = 0): phi within a quarter turn of 0.
  PoseVector r = InstrumentGeometry{}.nominal_pose(20.0, -58.1369437134, 0.383);
  PoseVector out = nearest_equivalent_joints(r, reference);
  EXPECT_NEAR(out[kPhi], std::remainder(-58.1369437134, 2.0 * kPi) + kPi, 1e-9);  // -1.588 + pi
  EXPECT_LE(std::fabs(out[kPhi]), kPi / 2.0);
  EXPECT_EQ(out[kTheta], -0.383);
  r[kPhi] = 2.5;
  out = nearest_equivalent_joints(r, reference);
  EXPECT_NEAR(out[kPhi], 2.5 - kPi, 1e-12);
  EXPECT_EQ(out[kTheta], -0.383);
  // A reference beyond pi (the robot's own count) keeps its turn.
  reference[kPhi] = 3.0;
  reference[kTheta] = 0.4;
  r[kPhi] = 3.3 - 2.0 * kPi;
  r[kTheta] = 0.38;
  out = nearest_equivalent_joints(r, reference);
  EXPECT_NEAR(out[kPhi], 3.3, 1e-12);
  EXPECT_EQ(out[kTheta], 0.38);
  // Non-finite: returned as is.
  r[kPhi] = std::numeric_limits<double>::quiet_NaN();
  out = nearest_equivalent_joints(r, reference);
  EXPECT_TRUE(std::isnan(out[kPhi]));
  r[kPhi] = 1.0;
  reference[kTheta] = std::numeric_limits<double>::infinity();
  out = nearest_equivalent_joints(r, reference);
  EXPECT_EQ(out[kPhi], 1.0);
  EXPECT_EQ(out[kTheta], 0.38);
}

// The limb points at an arbitrary arc length are the corners at s = s_j.
TEST(Instrument, LimbsAtABoundaryAreItsCorners) {
  const CameraModel camera = vectors_camera();
  const InstrumentModel model = InstrumentModel::create(InstrumentGeometry{}).value();
  std::mt19937 rng(17);
  int compared = 0;
  for (int i = 0; i < 200; ++i) {
    const PoseVector r = random_pose(rng);
    CornerSet corners;
    model.corners(camera, r, corners);
    const PoseFrames f = model.frames(r);
    for (int j = 0; j < kNumBoundaries; ++j) {
      const CircleLimbs limbs = model.limbs(camera, f, model.geometry().boundaries_mm[static_cast<std::size_t>(j)]);
      for (std::size_t side = 0U; side < 2U; ++side) {
        const std::size_t k = 2U * static_cast<std::size_t>(j) + side;
        ASSERT_EQ(limbs.present[side], corners.present[k]) << "pose " << i << " k " << k;
        if (limbs.present[side]) {
          EXPECT_LT((limbs.pixel[side] - corners.pixel[k]).norm(), 1e-9);
          EXPECT_LT((limbs.point[side] - corners.point[k]).norm(), 1e-9);
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 1500);
}

// Limb points `same` of a part's circle whose radius was set to the tube's
// are those of the tube's circle `tube` (the same circle, the same rule):
// how many sides were compared.
int expect_same_limbs(const CircleLimbs& same, const CircleLimbs& tube) {
  int compared = 0;
  for (std::size_t side = 0U; side < 2U; ++side) {
    EXPECT_EQ(same.present[side], tube.present[side]);
    if (same.present[side] && tube.present[side]) {
      EXPECT_LT((same.pixel[side] - tube.pixel[side]).norm(), 1e-9);
      ++compared;
    }
  }
  return compared;
}

// The limb points of a part's circle of radius_mm at cf are on its limb: the
// surface normal there is a unit radius, perpendicular to the line of sight
// and to the axis.
void expect_on_limb(const CircleLimbs& limbs, const CentrelineFrame& cf, double radius_mm) {
  for (std::size_t side = 0U; side < 2U; ++side) {
    if (limbs.present[side]) {
      const Vec3 normal = (limbs.point[side] - cf.position) / radius_mm;
      EXPECT_NEAR(normal.norm(), 1.0, 1e-9);
      EXPECT_NEAR(normal.dot(limbs.point[side]), 0.0, 1e-9);
      EXPECT_NEAR(normal.dot(cf.tangent), 0.0, 1e-9);
    }
  }
}

// The shaft: its axis points lie on the channel axis, lambda - back from the
// channel exit; at the base, with the shaft's radius set to the tube's, its
// limb points are boundary 0's corners (the same circle, the same rule); its
// limb points are on the shaft's limb (the surface normal is perpendicular
// to the line of sight).
TEST(Instrument, ShaftFrameAndLimbs) {
  const CameraModel camera = vectors_camera();
  InstrumentGeometry same_radius;
  same_radius.shaft_radius_mm = same_radius.radius_mm;
  const InstrumentModel model = InstrumentModel::create(same_radius).value();
  const InstrumentModel shipped = InstrumentModel::create(InstrumentGeometry{}).value();
  std::mt19937 rng(23);
  int compared = 0;
  for (int i = 0; i < 100; ++i) {
    const PoseVector r = random_pose(rng);
    const PoseFrames f = model.frames(r);
    const Vec3 axis = f.channel_rotation.col(2);
    const CentrelineFrame cf = model.shaft_frame(f, 4.0);
    EXPECT_LT((cf.position - (f.channel_origin + (r[kLambda] - 4.0) * axis)).norm(), 1e-9);
    EXPECT_LT((cf.tangent - axis).norm(), 1e-12);
    compared += expect_same_limbs(model.shaft_limbs(camera, f, 0.0), model.limbs(camera, f, 0.0));
    expect_on_limb(shipped.shaft_limbs(camera, shipped.frames(r), 3.0), shipped.shaft_frame(shipped.frames(r), 3.0),
                   shipped.geometry().shaft_radius_mm);
  }
  EXPECT_GT(compared, 100);
}

// The grasper: its axis runs along the tip's tangent from the end of the
// bending section to the TCP; with its radius set to the tube's, its limb
// points at the tip are boundary 5's corners; its limb points are on the
// grasper's limb.
TEST(Instrument, GrasperFrameAndLimbs) {
  const CameraModel camera = vectors_camera();
  InstrumentGeometry same_radius;
  same_radius.grasper_radius_mm = same_radius.radius_mm;
  const InstrumentModel model = InstrumentModel::create(same_radius).value();
  const InstrumentModel shipped = InstrumentModel::create(InstrumentGeometry{}).value();
  const double length = model.geometry().bend_length_mm;
  std::mt19937 rng(29);
  int compared = 0;
  for (int i = 0; i < 100; ++i) {
    const PoseVector r = random_pose(rng);
    const PoseFrames f = model.frames(r);
    const CentrelineFrame end = model.centreline(f, length);
    const CentrelineFrame at_tcp = model.grasper_frame(f, model.geometry().tcp_offset_mm);
    EXPECT_LT((at_tcp.position - model.tcp(r)).norm(), 1e-9);
    EXPECT_LT((at_tcp.tangent - end.tangent).norm(), 1e-12);
    compared += expect_same_limbs(model.grasper_limbs(camera, f, 0.0), model.limbs(camera, f, length));
    expect_on_limb(shipped.grasper_limbs(camera, shipped.frames(r), 5.0),
                   shipped.grasper_frame(shipped.frames(r), 5.0), shipped.geometry().grasper_radius_mm);
  }
  EXPECT_GT(compared, 100);
}

// Verifies: REQ-MODEL-003
TEST(Instrument, NothingBehindTheCamera) {
  const CameraModel cam = vectors_camera();
  const auto model = InstrumentModel::create(InstrumentGeometry{});
  PoseVector r = InstrumentGeometry{}.nominal_pose(20.0, 0.0, 0.0);
  r[kPsi] = kPi;  // channel pointing backwards
  CornerSet out;
  model.value().corners(cam, r, out);
  EXPECT_EQ(out.count_present(), 0);
}

// Verifies: REQ-MODEL-005
TEST(Instrument, RefusesAbsurdGeometry) {
  InstrumentGeometry g;
  g.bend_length_mm = -1.0;
  EXPECT_FALSE(validate(g).ok());
  g = InstrumentGeometry{};
  g.radius_mm = 9.0;  // L / theta_max = 18.5 / 2.36 = 7.85 mm
  EXPECT_EQ(validate(g).error(), GeometryError::RadiusTooLarge);
  g = InstrumentGeometry{};
  g.boundaries_mm[2] = 2.0;
  EXPECT_EQ(validate(g).error(), GeometryError::BadBoundaries);
  g = InstrumentGeometry{};
  g.tcp_offset_mm = std::numeric_limits<double>::infinity();
  EXPECT_EQ(validate(g).error(), GeometryError::NonFiniteValue);
  g = InstrumentGeometry{};
  g.penalty.position_scale_mm = 0.0;
  EXPECT_EQ(validate(g).error(), GeometryError::BadPenalty);
  EXPECT_TRUE(validate(InstrumentGeometry{}).ok());
}

// Finite values no instrument has are refused by validate() itself, not
// only by the file loader.
// Verifies: REQ-MODEL-005
TEST(Instrument, RefusesAbsurdButFiniteGeometry) {
  InstrumentGeometry g;
  g.lambda_max_mm = 1e300;
  EXPECT_EQ(validate(g).error(), GeometryError::OutOfRange);
  g = InstrumentGeometry{};
  g.lambda_min_mm = -1.0;
  EXPECT_EQ(validate(g).error(), GeometryError::OutOfRange);
  g = InstrumentGeometry{};
  g.nominal_x_ch_mm = -1e6;
  EXPECT_EQ(validate(g).error(), GeometryError::OutOfRange);
  g = InstrumentGeometry{};
  g.nominal_psi_rad = 1e308;
  EXPECT_EQ(validate(g).error(), GeometryError::OutOfRange);
  g = InstrumentGeometry{};
  g.penalty.angle_k = 1e9;
  EXPECT_EQ(validate(g).error(), GeometryError::OutOfRange);
  g = InstrumentGeometry{};
  g.tcp_offset_mm = 1001.0;
  EXPECT_EQ(validate(g).error(), GeometryError::OutOfRange);
  g = InstrumentGeometry{};
  g.lambda_max_mm = kMaxGeometryLengthMm;
  g.nominal_mu_rad = -kMaxGeometryAngleRad;
  EXPECT_TRUE(validate(g).ok());
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
