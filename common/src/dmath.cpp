// Reproducible elementary functions (dmath.hpp): fdlibm's algorithms and
// coefficients, as musl carries them, written with only IEEE-exact
// operations. Compiled, like everything here, with -ffp-contract=off: a fused
// multiply-add would round differently on ARM64 than on x86-64.
#include "tcpest/common/dmath.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace tcpest::dmath {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- sin, cos ---------------------------------------------------------------

// pi/2 in three 33-bit pieces with their tails: n * piece is exact for
// |n| < 2^20, so x - n pi/2 keeps 118 bits (151 when it cancels deeply).
constexpr double kInvPio2 = 6.36619772367581382433e-01;
constexpr double kPio2Part1 = 1.57079632673412561417e+00;
constexpr double kPio2Part1Tail = 6.07710050650619224932e-11;
constexpr double kPio2Part2 = 6.07710050630396597660e-11;
constexpr double kPio2Part2Tail = 2.02226624879595063154e-21;
constexpr double kPio2Part3 = 2.02226624871116645580e-21;
constexpr double kPio2Part3Tail = 8.47842766036889956997e-32;
constexpr double kPio4 = 7.85398163397448278999e-01;
constexpr double kTwoPi = 6.28318530717958623200e+00;
// Beyond this |x| the quotient by pi/2 no longer fits the exact products.
constexpr double kMediumReductionLimit = 1.0e6;

// x = n pi/2 + (y0 + y1), |y0 + y1| <= pi/4; quadrant = n mod 4.
struct Reduced {
  double y0;
  double y1;
  int quadrant;
};

// std::ilogb of a nonzero finite x, read from its bits: the same value,
// without a library call on the sin/cos path. Subnormals take the call.
int binary_exponent(double x) noexcept {
  std::uint64_t bits = 0U;
  std::memcpy(&bits, &x, sizeof bits);
  const int biased = static_cast<int>((bits >> 52U) & 0x7ffU);
  return biased == 0 ? std::ilogb(x) : biased - 1023;
}

// How many binary orders of magnitude y lies below x (both nonzero finite);
// a zero y counts as a total cancellation.
int exponent_drop(double x, double y) noexcept {
  if (y == 0.0) {
    return 1000;
  }
  return binary_exponent(x) - binary_exponent(y);
}

// std::nearbyint(v) for |v| < 2^51 in the default rounding mode (to
// nearest, ties to even), with two exact additions instead of a library
// call: adding 1.5 * 2^52 leaves no fraction bits. A zero may lose its sign,
// which no use below sees.
double round_to_nearest(double v) noexcept {
  constexpr double kShift = 0x1.8p52;
  return (v + kShift) - kShift;
}

Reduced reduce_pio2(double x) noexcept {
  if (std::fabs(x) > kMediumReductionLimit) {
    // Deterministic, not accurate: fmod is exact, but against the double
    // nearest 2 pi. No angle in this program comes near.
    x = std::fmod(x, kTwoPi);
  }
  const double n = round_to_nearest(x * kInvPio2);  // |x| <= 1e6: |n| < 2^20
  double r = x - n * kPio2Part1;  // exact
  double w = n * kPio2Part1Tail;
  double y0 = r - w;
  if (exponent_drop(x, y0) > 16) {
    // Cancellation: the next 33 bits of pi/2 (fdlibm's second round).
    double t = r;
    w = n * kPio2Part2;
    r = t - w;
    w = n * kPio2Part2Tail - ((t - r) - w);
    y0 = r - w;
    if (exponent_drop(x, y0) > 49) {
      t = r;
      w = n * kPio2Part3;
      r = t - w;
      w = n * kPio2Part3Tail - ((t - r) - w);
      y0 = r - w;
    }
  }
  const double y1 = (r - y0) - w;
  // |n| < 2^21 here: the conversion is exact and & 3 is n mod 4 also for
  // a negative n (two's complement).
  const int quadrant = static_cast<int>(static_cast<long>(n) & 3L);
  return Reduced{y0, y1, quadrant};
}

// sin(x + y) on [-pi/4, pi/4], y a tail of x (fdlibm __kernel_sin).
double kernel_sin(double x, double y) noexcept {
  constexpr double kS1 = -1.66666666666666324348e-01;
  constexpr double kS2 = 8.33333333332248946124e-03;
  constexpr double kS3 = -1.98412698298579493134e-04;
  constexpr double kS4 = 2.75573137070700676789e-06;
  constexpr double kS5 = -2.50507602534068634195e-08;
  constexpr double kS6 = 1.58969099521155010221e-10;
  const double z = x * x;
  const double w = z * z;
  const double r = kS2 + z * (kS3 + z * kS4) + z * w * (kS5 + z * kS6);
  const double v = z * x;
  return x - ((z * (0.5 * y - v * r) - y) - v * kS1);
}

// cos(x + y) on [-pi/4, pi/4] (fdlibm __kernel_cos, musl's form).
double kernel_cos(double x, double y) noexcept {
  constexpr double kC1 = 4.16666666666666019037e-02;
  constexpr double kC2 = -1.38888888888741095749e-03;
  constexpr double kC3 = 2.48015872894767294178e-05;
  constexpr double kC4 = -2.75573143513906633035e-07;
  constexpr double kC5 = 2.08757232129817482790e-09;
  constexpr double kC6 = -1.13596475577881948265e-11;
  const double z = x * x;
  double w = z * z;
  const double r = z * (kC1 + z * (kC2 + z * kC3)) + w * w * (kC4 + z * (kC5 + z * kC6));
  const double hz = 0.5 * z;
  w = 1.0 - hz;
  return w + (((1.0 - w) - hz) + (z * r - x * y));
}

// ---- atan -------------------------------------------------------------------

constexpr double kPi = 3.1415926535897931160e+00;
constexpr double kPiLo = 1.2246467991473531772e-16;
constexpr double kPio2 = 1.5707963267948965580e+00;
constexpr double kThreePio4 = 2.3561944901923448370e+00;

}  // namespace

double sin(double x) noexcept {
  if (!std::isfinite(x)) {
    return kNaN;
  }
  if (std::fabs(x) <= kPio4) {
    return std::fabs(x) < 0x1p-26 ? x : kernel_sin(x, 0.0);
  }
  const Reduced r = reduce_pio2(x);
  switch (r.quadrant) {
    case 0: return kernel_sin(r.y0, r.y1);
    case 1: return kernel_cos(r.y0, r.y1);
    case 2: return -kernel_sin(r.y0, r.y1);
    default: return -kernel_cos(r.y0, r.y1);
  }
}

double cos(double x) noexcept {
  if (!std::isfinite(x)) {
    return kNaN;
  }
  if (std::fabs(x) <= kPio4) {
    return std::fabs(x) < 0x1p-27 ? 1.0 : kernel_cos(x, 0.0);
  }
  const Reduced r = reduce_pio2(x);
  switch (r.quadrant) {
    case 0: return kernel_cos(r.y0, r.y1);
    case 1: return -kernel_sin(r.y0, r.y1);
    case 2: return -kernel_cos(r.y0, r.y1);
    default: return kernel_sin(r.y0, r.y1);
  }
}

double exp(double x) noexcept {
  constexpr double kOverflow = 7.09782712893383973096e+02;
  constexpr double kUnderflow = -7.45133219101941108420e+02;
  constexpr double kLn2Hi = 6.93147180369123816490e-01;
  constexpr double kLn2Lo = 1.90821492927058770002e-10;
  constexpr double kInvLn2 = 1.44269504088896338700e+00;
  constexpr double kP1 = 1.66666666666666019037e-01;
  constexpr double kP2 = -2.77777777770155933842e-03;
  constexpr double kP3 = 6.61375632143793436117e-05;
  constexpr double kP4 = -1.65339022054652515390e-06;
  constexpr double kP5 = 4.13813679705723846039e-08;
  if (std::isnan(x)) {
    return x;
  }
  if (x > kOverflow) {
    return kInf;
  }
  if (x < kUnderflow) {
    return 0.0;
  }
  // x = k ln2 + (hi - lo), |hi - lo| <= ln2 / 2.
  int k = 0;
  double hi = x;
  double lo = 0.0;
  if (std::fabs(x) > 0.5 * kLn2Hi) {
    k = static_cast<int>(kInvLn2 * x + (x < 0.0 ? -0.5 : 0.5));  // |k| <= 1075
    const double kd = static_cast<double>(k);
    hi = x - kd * kLn2Hi;  // exact: kLn2Hi has 32 bits
    lo = kd * kLn2Lo;
  } else if (std::fabs(x) < 0x1p-28) {
    return 1.0 + x;
  }
  const double reduced = hi - lo;
  const double t = reduced * reduced;
  const double c = reduced - t * (kP1 + t * (kP2 + t * (kP3 + t * (kP4 + t * kP5))));
  if (k == 0) {
    return 1.0 - ((reduced * c) / (c - 2.0) - reduced);
  }
  const double y = 1.0 - ((lo - (reduced * c) / (2.0 - c)) - hi);
  return std::ldexp(y, k);  // exact scaling (one rounding when subnormal)
}

double log(double x) noexcept {
  constexpr double kLn2Hi = 6.93147180369123816490e-01;
  constexpr double kLn2Lo = 1.90821492927058770002e-10;
  constexpr double kLg1 = 6.666666666666735130e-01;
  constexpr double kLg2 = 3.999999999940941908e-01;
  constexpr double kLg3 = 2.857142874366239149e-01;
  constexpr double kLg4 = 2.222219843214978396e-01;
  constexpr double kLg5 = 1.818357216161805012e-01;
  constexpr double kLg6 = 1.531383769920937332e-01;
  constexpr double kLg7 = 1.479819860511658591e-01;
  constexpr double kSqrtHalf = 7.07106781186547524401e-01;
  if (std::isnan(x) || x < 0.0) {
    return kNaN;
  }
  if (x == 0.0) {
    return -kInf;
  }
  if (std::isinf(x)) {
    return x;
  }
  // x = m 2^e with m in [sqrt(2)/2, sqrt(2)); f = m - 1 exactly.
  int e = 0;
  double m = std::frexp(x, &e);  // m in [0.5, 1)
  if (m < kSqrtHalf) {
    m *= 2.0;
    e -= 1;
  }
  const double f = m - 1.0;
  const double hfsq = 0.5 * f * f;
  const double s = f / (2.0 + f);
  const double z = s * s;
  const double w = z * z;
  const double t1 = w * (kLg2 + w * (kLg4 + w * kLg6));
  const double t2 = z * (kLg1 + w * (kLg3 + w * (kLg5 + w * kLg7)));
  const double r = t2 + t1;
  const double dk = static_cast<double>(e);
  return s * (hfsq + r) + dk * kLn2Lo - hfsq + f + dk * kLn2Hi;
}

double pow_positive(double x, double y) noexcept {
  if (std::isnan(x) || std::isnan(y) || x < 0.0) {
    return kNaN;
  }
  if (x == 0.0) {
    return y > 0.0 ? 0.0 : (y == 0.0 ? 1.0 : kInf);
  }
  if (y == 0.0) {
    return 1.0;
  }
  return exp(y * log(x));
}

double atan(double x) noexcept {
  constexpr double kAtanHi[] = {4.63647609000806093515e-01, 7.85398163397448278999e-01, 9.82793723247329054082e-01,
                                1.57079632679489655800e+00};
  constexpr double kAtanLo[] = {2.26987774529616870924e-17, 3.06161699786838301793e-17, 1.39033110312309984516e-17,
                                6.12323399573676603587e-17};
  constexpr double kAt[] = {3.33333333333329318027e-01,  -1.99999999998764832476e-01, 1.42857142725034663711e-01,
                            -1.11111104054623557880e-01, 9.09088713343650656196e-02,  -7.69187620504482999495e-02,
                            6.66107313738753120669e-02,  -5.83357013379057348645e-02, 4.97687799461593236017e-02,
                            -3.65315727442169155270e-02, 1.62858201153657823623e-02};
  if (std::isnan(x)) {
    return x;
  }
  const bool negative = std::signbit(x);
  double a = std::fabs(x);
  if (a >= 0x1p66) {
    const double z = kAtanHi[3] + kAtanLo[3];
    return negative ? -z : z;
  }
  int id = -1;
  if (a < 0.4375) {
    if (a < 0x1p-27) {
      return x;
    }
    a = x;  // the polynomial is odd: keep the sign
  } else if (a < 1.1875) {
    if (a < 0.6875) {
      id = 0;
      a = (2.0 * a - 1.0) / (2.0 + a);
    } else {
      id = 1;
      a = (a - 1.0) / (a + 1.0);
    }
  } else if (a < 2.4375) {
    id = 2;
    a = (a - 1.5) / (1.0 + 1.5 * a);
  } else {
    id = 3;
    a = -1.0 / a;
  }
  const double z = a * a;
  const double w = z * z;
  const double s1 = z * (kAt[0] + w * (kAt[2] + w * (kAt[4] + w * (kAt[6] + w * (kAt[8] + w * kAt[10])))));
  const double s2 = w * (kAt[1] + w * (kAt[3] + w * (kAt[5] + w * (kAt[7] + w * kAt[9]))));
  if (id < 0) {
    return a - a * (s1 + s2);
  }
  const auto i = static_cast<unsigned>(id);
  const double result = kAtanHi[i] - ((a * (s1 + s2) - kAtanLo[i]) - a);
  return negative ? -result : result;
}

double atan2(double y, double x) noexcept {
  if (std::isnan(x) || std::isnan(y)) {
    return kNaN;
  }
  if (x == 1.0) {
    return atan(y);
  }
  const bool y_negative = std::signbit(y);
  const bool x_negative = std::signbit(x);
  if (y == 0.0) {
    return x_negative ? (y_negative ? -kPi : kPi) : y;  // y keeps its zero's sign
  }
  if (x == 0.0) {
    return y_negative ? -kPio2 : kPio2;
  }
  if (std::isinf(x)) {
    double z = 0.0;
    if (std::isinf(y)) {
      z = x_negative ? kThreePio4 : 0.5 * kPio2;
    } else {
      z = x_negative ? kPi : 0.0;
    }
    return y_negative ? -z : z;
  }
  if (std::isinf(y)) {
    return y_negative ? -kPio2 : kPio2;
  }
  const int k = binary_exponent(y) - binary_exponent(x);
  double z = 0.0;
  if (k > 60) {
    z = kPio2 + 0.5 * kPiLo;  // |y/x| > 2^60
    return y_negative ? -z : z;
  }
  if (x_negative && k < -60) {
    z = 0.0;  // |y/x| < 2^-60 behind: pi, from the correction below
  } else {
    z = atan(std::fabs(y / x));
  }
  if (!x_negative) {
    return y_negative ? -z : z;
  }
  return y_negative ? (z - kPiLo) - kPi : kPi - (z - kPiLo);
}

double asin(double x) noexcept {
  if (!(std::fabs(x) <= 1.0)) {
    return kNaN;
  }
  return atan2(x, std::sqrt((1.0 - x) * (1.0 + x)));
}

double acos(double x) noexcept {
  if (!(std::fabs(x) <= 1.0)) {
    return kNaN;
  }
  return atan2(std::sqrt((1.0 - x) * (1.0 + x)), x);
}

double hypot(double x, double y) noexcept {
  if (std::isinf(x) || std::isinf(y)) {
    return kInf;
  }
  if (std::isnan(x) || std::isnan(y)) {
    return kNaN;
  }
  double a = std::fabs(x);
  double b = std::fabs(y);
  if (a < b) {
    const double t = a;
    a = b;
    b = t;
  }
  if (b <= a * 0x1p-30) {
    return a;  // b^2 / a^2 < 2^-60: sqrt(a^2 + b^2) rounds to a
  }
  // a / b <= 2^30: one power-of-two scale keeps a^2 and b^2 normal.
  double scale = 1.0;
  if (a > 0x1p500) {
    a *= 0x1p-600;
    b *= 0x1p-600;
    scale = 0x1p600;
  } else if (a < 0x1p-450) {
    a *= 0x1p600;
    b *= 0x1p600;
    scale = 0x1p-600;
  }
  return std::sqrt(a * a + b * b) * scale;
}

}  // namespace tcpest::dmath
