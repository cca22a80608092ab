#include "tcpest/solver/camera.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace tcpest {
namespace solver {
namespace {

CameraIntrinsics vectors_camera() {
  CameraIntrinsics k = default_pal_camera();
  k.p1 = 0.001;
  k.p2 = -0.0005;
  k.k3 = -0.01;
  return k;
}

// Verifies: REQ-MODEL-003
TEST(Camera, DefaultPalNeverFolds) {
  const auto cam = CameraModel::create(default_pal_camera());
  ASSERT_TRUE(cam.ok());
  // 1 - 0.96 s + 0.55 s^2 has no real root.
  EXPECT_FALSE(std::isfinite(cam.value().max_r2()));
}

// Verifies: REQ-MODEL-003
TEST(Camera, FoldingCalibrationLimitsProjection) {
  CameraIntrinsics k = default_pal_camera();
  k.k2 = 0.0;  // 1 - 0.96 s = 0 at s = 1/0.96
  const auto cam = CameraModel::create(k);
  ASSERT_TRUE(cam.ok());
  EXPECT_NEAR(cam.value().max_r2(), 1.0 / 0.96, 1e-12);
  Vec2 px;
  EXPECT_TRUE(cam.value().project(Vec3(0.9, 0.0, 1.0), px));   // r^2 = 0.81
  EXPECT_FALSE(cam.value().project(Vec3(1.1, 0.0, 1.0), px));  // r^2 = 1.21
  EXPECT_FALSE(cam.value().project(Vec3(0.0, 0.0, 0.0), px));
  EXPECT_FALSE(cam.value().project(Vec3(0.0, 0.0, -1.0), px));
  // A pixel beyond the largest distorted radius has no ray.
  Vec2 n;
  EXPECT_FALSE(cam.value().undistort(Vec2(k.cx + 0.99 * k.fx, k.cy), n));
}

// Verifies: REQ-MODEL-005
TEST(Camera, RefusesBadIntrinsics) {
  CameraIntrinsics k = default_pal_camera();
  k.fx = 0.0;
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadFocalLength);
  k = default_pal_camera();
  k.k1 = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::NonFiniteValue);
  k = default_pal_camera();
  k.width = 0;
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadImageSize);
}

// Finite but absurd intrinsics are refused by the model itself, not only by
// the file loader.
// Verifies: REQ-MODEL-005
TEST(Camera, RefusesAbsurdButFiniteIntrinsics) {
  const double focal[] = {1e308, 1e-300, 0.5, 1.0001e5};
  for (double f : focal) {
    CameraIntrinsics k = default_pal_camera();
    k.fx = f;
    EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadFocalLength) << f;
    k = default_pal_camera();
    k.fy = f;
    EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadFocalLength) << f;
  }
  CameraIntrinsics k = default_pal_camera();
  k.k1 = 1e10;
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadDistortion);
  k = default_pal_camera();
  k.k3 = -100.5;
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadDistortion);
  k = default_pal_camera();
  k.p2 = 1.5;
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadDistortion);
  k = default_pal_camera();
  k.cx = 1e308;
  EXPECT_EQ(CameraModel::create(k).error(), CameraError::BadPrincipalPoint);
  k = default_pal_camera();
  k.fx = 1.0;
  k.fy = kMaxFocalPx;
  EXPECT_TRUE(CameraModel::create(k).ok());
}

// Verifies: REQ-MODEL-002
TEST(Camera, JacobianMatchesCentralDifferences) {
  const auto cam = CameraModel::create(vectors_camera());
  ASSERT_TRUE(cam.ok());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-30.0, 30.0);
  std::uniform_real_distribution<double> z(10.0, 80.0);
  for (int i = 0; i < 200; ++i) {
    const Vec3 p(xy(rng), xy(rng), z(rng));
    if ((p.x() * p.x() + p.y() * p.y()) / (p.z() * p.z()) > 0.8 * cam.value().max_r2()) {
      continue;  // keep clear of the fold, where differences straddle it
    }
    Vec2 px;
    Eigen::Matrix<double, 2, 3> j;
    ASSERT_TRUE(cam.value().project(p, px, j));
    for (int a = 0; a < 3; ++a) {
      const double h = 1e-6;
      Vec3 lo = p;
      Vec3 hi = p;
      lo[a] -= h;
      hi[a] += h;
      Vec2 plo;
      Vec2 phi;
      ASSERT_TRUE(cam.value().project(lo, plo));
      ASSERT_TRUE(cam.value().project(hi, phi));
      const Vec2 numeric = (phi - plo) / (2 * h);
      EXPECT_NEAR(j(0, a), numeric.x(), 1e-5 * (1.0 + std::fabs(numeric.x())));
      EXPECT_NEAR(j(1, a), numeric.y(), 1e-5 * (1.0 + std::fabs(numeric.y())));
    }
  }
}

TEST(Camera, UndistortInvertsDistortEverywhereInTheImage) {
  const auto cam = CameraModel::create(vectors_camera());
  ASSERT_TRUE(cam.ok());
  for (int v = 0; v < 576; v += 23) {
    for (int u = 0; u < 720; u += 29) {
      Vec2 n;
      ASSERT_TRUE(cam.value().undistort(Vec2(u, v), n)) << u << "," << v;
      Vec2 back;
      ASSERT_TRUE(cam.value().distort(n, back));
      EXPECT_NEAR(back.x(), u, 1e-8);
      EXPECT_NEAR(back.y(), v, 1e-8);
    }
  }
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
