// dmath: accuracy against a wider reference, C's special values, and the
// same bits on every machine (checksums pinned here hold on x86-64 and on
// ARM64: the ARM64 build runs this test too, tests/aarch64/README.md).
#include "tcpest/common/dmath.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "tcpest/common/splitmix64.hpp"

namespace tcpest {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

std::uint64_t bits_of(double x) {
  std::uint64_t b = 0U;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// A uniform double in [lo, hi) from sample i of stream `seed`.
double uniform(std::uint64_t seed, std::uint64_t i, double lo, double hi) {
  const std::uint64_t r = splitmix64(seed * 0x100000000ULL + i);
  return lo + (hi - lo) * static_cast<double>(r >> 11U) * 0x1p-53;
}

// The error of `value` against the long double reference, in units of the
// last place of the double nearest the reference.
double ulp_error(double value, long double reference) {
  const double nearest = static_cast<double>(reference);
  if (nearest == 0.0) {
    return value == 0.0 ? 0.0 : kInf;
  }
  const double ulp = std::nextafter(std::fabs(nearest), kInf) - std::fabs(nearest);
  return static_cast<double>(std::fabs(static_cast<long double>(value) - reference) / static_cast<long double>(ulp));
}

constexpr std::uint64_t kSamples = 200000U;

template <typename F, typename R>
double max_ulp_error(std::uint64_t seed, double lo, double hi, F f, R reference) {
  double worst = 0.0;
  for (std::uint64_t i = 0U; i < kSamples; ++i) {
    const double x = uniform(seed, i, lo, hi);
    worst = std::max(worst, ulp_error(f(x), reference(static_cast<long double>(x))));
  }
  return worst;
}

// The same for a function of two arguments, each drawn in [lo, hi).
template <typename F, typename R>
double max_ulp_error2(std::uint64_t seed, double lo, double hi, F f, R reference) {
  double worst = 0.0;
  for (std::uint64_t i = 0U; i < kSamples; ++i) {
    const double a = uniform(seed, i, lo, hi);
    const double b = uniform(seed + 1U, i, lo, hi);
    worst = std::max(worst, ulp_error(f(a, b), reference(static_cast<long double>(a), static_cast<long double>(b))));
  }
  return worst;
}

// Verifies: REQ-MODEL-006
TEST(Dmath, SinAndCosWithinOneUlpOverTheAnglesUsedAndBeyond) {
  EXPECT_LT(max_ulp_error(1U, -7.0, 7.0, dmath::sin, [](long double x) { return std::sin(x); }), 1.0);
  EXPECT_LT(max_ulp_error(2U, -7.0, 7.0, dmath::cos, [](long double x) { return std::cos(x); }), 1.0);
  EXPECT_LT(max_ulp_error(3U, -1000.0, 1000.0, dmath::sin, [](long double x) { return std::sin(x); }), 1.0);
  EXPECT_LT(max_ulp_error(4U, -1e-3, 1e-3, dmath::cos, [](long double x) { return std::cos(x); }), 1.0);
  // Next to multiples of pi/2, where the reduction cancels deeply.
  for (int k = -8; k <= 8; ++k) {
    const double near = static_cast<double>(k) * 1.5707963267948966;
    for (int step = -3; step <= 3; ++step) {
      const double x = near + static_cast<double>(step) * 1e-12;
      EXPECT_LT(ulp_error(dmath::sin(x), std::sin(static_cast<long double>(x))), 1.0) << x;
      EXPECT_LT(ulp_error(dmath::cos(x), std::cos(static_cast<long double>(x))), 1.0) << x;
    }
  }
}

// Beyond the accurate range the reduction is only deterministic: still a
// sine's value, the same on every machine (the checksum below covers it).
// Verifies: REQ-MODEL-006
TEST(Dmath, HugeAnglesStayWithinTheSinesRange) {
  for (const double x : {1e7, -3.5e9, 1e300}) {
    EXPECT_LE(std::fabs(dmath::sin(x)), 1.0) << x;
    EXPECT_LE(std::fabs(dmath::cos(x)), 1.0) << x;
  }
}

// Verifies: REQ-MODEL-006
TEST(Dmath, ExpAndLogWithinOneUlp) {
  EXPECT_LT(max_ulp_error(5U, -700.0, 700.0, dmath::exp, [](long double x) { return std::exp(x); }), 1.0);
  EXPECT_LT(max_ulp_error(6U, -2.0, 2.0, dmath::exp, [](long double x) { return std::exp(x); }), 1.0);
  EXPECT_LT(max_ulp_error(7U, 1e-300, 1e300, dmath::log, [](long double x) { return std::log(x); }), 1.0);
  EXPECT_LT(max_ulp_error(8U, 0.5, 2.0, dmath::log, [](long double x) { return std::log(x); }), 1.0);
  EXPECT_LT(max_ulp_error(9U, 1e-6, 1.0, dmath::log, [](long double x) { return std::log(x); }), 1.0);
}

// Verifies: REQ-MODEL-006
TEST(Dmath, ArcFunctionsWithinTwoUlp) {
  EXPECT_LT(max_ulp_error(10U, -3.0, 3.0, dmath::atan, [](long double x) { return std::atan(x); }), 1.0);
  EXPECT_LT(max_ulp_error(11U, -1e6, 1e6, dmath::atan, [](long double x) { return std::atan(x); }), 1.0);
  EXPECT_LT(max_ulp_error(12U, -1.0, 1.0, dmath::asin, [](long double x) { return std::asin(x); }), 2.0);
  EXPECT_LT(max_ulp_error(13U, -1.0, 1.0, dmath::acos, [](long double x) { return std::acos(x); }), 2.0);
  EXPECT_LT(max_ulp_error2(14U, -100.0, 100.0, dmath::atan2,
                           [](long double y, long double x) { return std::atan2(y, x); }),
            2.0);
}

// Verifies: REQ-MODEL-006
TEST(Dmath, HypotAndPowWithinTheirStatedErrors) {
  EXPECT_LT(max_ulp_error2(16U, -2000.0, 2000.0, dmath::hypot,
                           [](long double x, long double y) { return std::hypot(x, y); }),
            1.5);
  // Far from 1, where x^2 would overflow or underflow.
  EXPECT_LT(ulp_error(dmath::hypot(3e300, 4e300), 5e300L), 1.0);
  EXPECT_LT(ulp_error(dmath::hypot(3e-300, 4e-300), 5e-300L), 1.0);
  EXPECT_EQ(dmath::hypot(1e300, 1e-300), 1e300);
  double worst_relative = 0.0;
  for (std::uint64_t i = 0U; i < kSamples; ++i) {
    const double x = uniform(18U, i, 1e-3, 10.0);
    const double y = uniform(19U, i, -5.0, 5.0);
    const long double reference = std::pow(static_cast<long double>(x), static_cast<long double>(y));
    const auto value = static_cast<long double>(dmath::pow_positive(x, y));
    worst_relative = std::max(worst_relative, static_cast<double>(std::fabs((value - reference) / reference)));
  }
  EXPECT_LT(worst_relative, 2e-14);
}

// Verifies: REQ-MODEL-006
TEST(Dmath, SpecialValuesFollowC) {
  EXPECT_TRUE(std::isnan(dmath::sin(kInf)));
  EXPECT_TRUE(std::isnan(dmath::cos(kNaN)));
  EXPECT_EQ(bits_of(dmath::sin(-0.0)), bits_of(-0.0));
  EXPECT_EQ(dmath::cos(0.0), 1.0);
  EXPECT_EQ(dmath::exp(0.0), 1.0);
  EXPECT_EQ(dmath::exp(800.0), kInf);
  EXPECT_EQ(dmath::exp(-800.0), 0.0);
  EXPECT_GT(dmath::exp(-740.0), 0.0);  // subnormal, not flushed
  EXPECT_TRUE(std::isnan(dmath::exp(kNaN)));
  EXPECT_EQ(dmath::log(1.0), 0.0);
  EXPECT_EQ(dmath::log(0.0), -kInf);
  EXPECT_EQ(dmath::log(kInf), kInf);
  EXPECT_TRUE(std::isnan(dmath::log(-1.0)));
  EXPECT_LT(ulp_error(dmath::log(4.9406564584124654e-324), std::log(4.9406564584124654e-324L)), 1.0);
  EXPECT_EQ(dmath::pow_positive(0.0, 2.0), 0.0);
  EXPECT_EQ(dmath::pow_positive(0.0, 0.0), 1.0);
  EXPECT_EQ(dmath::pow_positive(0.0, -1.0), kInf);
  EXPECT_EQ(dmath::pow_positive(7.0, 0.0), 1.0);
  EXPECT_TRUE(std::isnan(dmath::pow_positive(-2.0, 2.0)));
  EXPECT_EQ(dmath::atan(kInf), 1.5707963267948966);
  EXPECT_EQ(dmath::atan(-kInf), -1.5707963267948966);
  EXPECT_EQ(bits_of(dmath::atan2(0.0, 1.0)), bits_of(0.0));
  EXPECT_EQ(bits_of(dmath::atan2(-0.0, 1.0)), bits_of(-0.0));
  EXPECT_EQ(dmath::atan2(0.0, -1.0), 3.141592653589793);
  EXPECT_EQ(dmath::atan2(-0.0, -1.0), -3.141592653589793);
  EXPECT_EQ(dmath::atan2(0.0, -0.0), 3.141592653589793);
  EXPECT_EQ(dmath::atan2(2.0, 0.0), 1.5707963267948966);
  EXPECT_EQ(dmath::atan2(-2.0, 0.0), -1.5707963267948966);
  EXPECT_EQ(dmath::atan2(kInf, kInf), 0.7853981633974483);
  EXPECT_EQ(dmath::atan2(-kInf, -kInf), -2.356194490192345);
  EXPECT_EQ(dmath::atan2(1.0, -kInf), 3.141592653589793);
  EXPECT_EQ(dmath::atan2(kInf, 3.0), 1.5707963267948966);
  EXPECT_EQ(dmath::atan2(1e300, 1e-300), 1.5707963267948966);
  EXPECT_EQ(dmath::atan2(-1e-300, -1e300), -3.141592653589793);
  EXPECT_TRUE(std::isnan(dmath::atan2(kNaN, 1.0)));
  EXPECT_EQ(dmath::asin(1.0), 1.5707963267948966);
  EXPECT_EQ(dmath::acos(-1.0), 3.141592653589793);
  EXPECT_EQ(dmath::acos(1.0), 0.0);
  EXPECT_TRUE(std::isnan(dmath::asin(1.0000000000000002)));
  EXPECT_TRUE(std::isnan(dmath::acos(kNaN)));
  EXPECT_EQ(dmath::hypot(kNaN, kInf), kInf);
  EXPECT_TRUE(std::isnan(dmath::hypot(kNaN, 1.0)));
  EXPECT_EQ(dmath::hypot(-3.0, 0.0), 3.0);
  EXPECT_EQ(dmath::hypot(3.0, 4.0), 5.0);
}

// A checksum of each function's bits over many arguments. The values were
// taken on x86-64; the ARM64 build must give the same (that is the point of
// the unit), as must any CPU, whatever its features.
std::uint64_t checksum(std::uint64_t seed, double lo, double hi, double (*f)(double)) {
  std::uint64_t sum = 0U;
  for (std::uint64_t i = 0U; i < kSamples; ++i) {
    sum = splitmix64(sum ^ bits_of(f(uniform(seed, i, lo, hi))));
  }
  return sum;
}
std::uint64_t checksum2(std::uint64_t seed, double lo, double hi, double (*f)(double, double)) {
  std::uint64_t sum = 0U;
  for (std::uint64_t i = 0U; i < kSamples; ++i) {
    sum = splitmix64(sum ^ bits_of(f(uniform(seed, i, lo, hi), uniform(seed + 1U, i, lo, hi))));
  }
  return sum;
}

// Verifies: REQ-MODEL-006
TEST(Dmath, TheSameBitsOnEveryMachine) {
  EXPECT_EQ(checksum(21U, -10.0, 10.0, dmath::sin), 0x5634DD9B0F11B449ULL);
  EXPECT_EQ(checksum(22U, -10.0, 10.0, dmath::cos), 0x4D9D8316CCAA4158ULL);
  EXPECT_EQ(checksum(33U, -1e9, 1e9, dmath::sin), 0xBB339CF08F898F00ULL);  // beyond the accurate range
  EXPECT_EQ(checksum(23U, -20.0, 20.0, dmath::exp), 0xD3B8EF4F4B5A1A84ULL);
  EXPECT_EQ(checksum(24U, 1e-6, 1e6, dmath::log), 0xA20523E147AF0CA3ULL);
  EXPECT_EQ(checksum(25U, -50.0, 50.0, dmath::atan), 0x7C518C05672483EAULL);
  EXPECT_EQ(checksum(26U, -1.0, 1.0, dmath::asin), 0xAFCA0AE547E556AAULL);
  EXPECT_EQ(checksum(27U, -1.0, 1.0, dmath::acos), 0x3E6CD675116FBC31ULL);
  EXPECT_EQ(checksum2(28U, -100.0, 100.0, dmath::atan2), 0xC851D0F1136B8F44ULL);
  EXPECT_EQ(checksum2(30U, -100.0, 100.0, dmath::hypot), 0x4727CC65E2903C32ULL);
  EXPECT_EQ(checksum2(32U, 0.0, 4.0, dmath::pow_positive), 0xB26FE6B113E71E02ULL);
}

}  // namespace
}  // namespace tcpest
