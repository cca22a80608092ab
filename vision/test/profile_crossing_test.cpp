// Stage 4's reading of one colour profile on its own
// (src/profile_crossing.hpp): the steepest sign change of the wanted
// direction within a window, to a fraction of a sample, never reading a
// point that had no image to sample.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>

#include "../src/profile_crossing.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

constexpr int kSamples = 21;
constexpr double kT0 = -0.1;
constexpr double kDt = 0.06;  // t from -0.1 to 1.1

struct Profile {
  std::array<double, kSamples> value{};
  std::array<bool, kSamples> ok{};
  Profile() { ok.fill(true); }
  double t(int i) const { return kT0 + kDt * static_cast<double>(i); }
};

// A ramp through zero at t_zero with `slope` per unit of t.
Profile ramp(double t_zero, double slope) {
  Profile p;
  for (int i = 0; i < kSamples; ++i) {
    p.value[static_cast<std::size_t>(i)] = slope * (p.t(i) - t_zero);
  }
  return p;
}

bool read(const Profile& p, double t_lo, double t_hi, double want_sign, double& t_cross, double& slope) {
  return best_crossing(p.value.data(), p.ok.data(), kSamples, kT0, kDt, t_lo, t_hi, want_sign, t_cross, slope);
}

TEST(ProfileCrossing, ALinearChangeIsReadWhereItCrossesZero) {
  const Profile p = ramp(0.437, 3.0);
  double t = 0.0, slope = 0.0;
  ASSERT_TRUE(read(p, 0.0, 1.0, +1.0, t, slope));
  EXPECT_NEAR(t, 0.437, 1e-12);
  EXPECT_NEAR(slope, 3.0 * 5.0 * kDt, 1e-12);  // over 5 samples
}

TEST(ProfileCrossing, OnlyTheWantedDirectionCounts) {
  const Profile p = ramp(0.437, -3.0);  // yellow to blue
  double t = 0.0, slope = 0.0;
  EXPECT_FALSE(read(p, 0.0, 1.0, +1.0, t, slope));
  ASSERT_TRUE(read(p, 0.0, 1.0, -1.0, t, slope));
  EXPECT_NEAR(t, 0.437, 1e-12);
  EXPECT_GT(slope, 0.0);
}

TEST(ProfileCrossing, OnlyCrossingsWholeWithinTheWindowCount) {
  const Profile p = ramp(0.437, 3.0);
  double t = 0.0, slope = 0.0;
  // The crossing lies between the points at t = 0.38 and 0.44.
  EXPECT_FALSE(read(p, 0.39, 1.0, +1.0, t, slope));
  EXPECT_FALSE(read(p, 0.0, 0.43, +1.0, t, slope));
  EXPECT_TRUE(read(p, 0.37, 0.45, +1.0, t, slope));
}

TEST(ProfileCrossing, TheSteepestOfTwoCrossingsIsRead) {
  // Up at 0.2 gently, down at 0.5, up at 0.8 steeply.
  Profile p;
  for (int i = 0; i < kSamples; ++i) {
    const double t = p.t(i);
    p.value[static_cast<std::size_t>(i)] = t < 0.5 ? 1.0 * (t - 0.2) : 8.0 * (t - 0.8);
  }
  double t = 0.0, slope = 0.0;
  ASSERT_TRUE(read(p, 0.0, 1.0, +1.0, t, slope));
  EXPECT_NEAR(t, 0.8, 1e-12);
}

TEST(ProfileCrossing, APointWithoutASampleIsNeverRead) {
  // Two rising crossings; the gentle one lies next to the image's end,
  // where the points hold whatever a previous border left there.
  Profile p;
  for (int i = 0; i < kSamples; ++i) {
    const double t = p.t(i);
    p.value[static_cast<std::size_t>(i)] = t < 0.5 ? 1.0 * (t - 0.05) : 2.0 * (t - 0.8);
  }
  // t = -0.1 and -0.04: within 2 points of the gentle crossing (between
  // t = 0.02 and 0.08).
  const std::array<int, 2> unsampled{{0, 1}};
  double t_clean = 0.0, slope_clean = 0.0;
  for (int i : unsampled) {
    p.ok[static_cast<std::size_t>(i)] = false;
    p.value[static_cast<std::size_t>(i)] = 0.0;
  }
  ASSERT_TRUE(read(p, -0.2, 1.2, +1.0, t_clean, slope_clean));
  EXPECT_NEAR(t_clean, 0.8, 1e-12);
  for (double stale : {-1e6, 1e6, std::numeric_limits<double>::quiet_NaN()}) {
    for (int i : unsampled) {
      p.value[static_cast<std::size_t>(i)] = stale;
    }
    double t = 0.0, slope = 0.0;
    ASSERT_TRUE(read(p, -0.2, 1.2, +1.0, t, slope)) << stale;
    EXPECT_EQ(t, t_clean) << stale;
    EXPECT_EQ(slope, slope_clean) << stale;
  }
}

TEST(ProfileCrossing, NoCrossingOverAPointWithoutASample) {
  Profile p = ramp(0.437, 3.0);
  // The two points around the crossing: t = 0.38 and 0.44.
  p.ok[8] = false;
  double t = 0.0, slope = 0.0;
  EXPECT_FALSE(read(p, 0.0, 1.0, +1.0, t, slope));
}

TEST(ProfileCrossing, NoProfileNoCrossing) {
  double t = 0.0, slope = 0.0;
  const std::array<bool, kSamples> ok{};
  const std::array<double, kSamples> value{};
  EXPECT_FALSE(best_crossing(nullptr, ok.data(), kSamples, kT0, kDt, 0.0, 1.0, 1.0, t, slope));
  EXPECT_FALSE(best_crossing(value.data(), nullptr, kSamples, kT0, kDt, 0.0, 1.0, 1.0, t, slope));
  EXPECT_FALSE(best_crossing(value.data(), ok.data(), 1, kT0, kDt, 0.0, 1.0, 1.0, t, slope));
}

}  // namespace
}  // namespace detail
}  // namespace vision
}  // namespace tcpest
