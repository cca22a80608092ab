// Reproducible elementary functions: the same bits on every machine.
//
// glibc picks its sin, cos, exp, log, pow and atan variants at load time by
// the CPU's features (an FMA build on CPUs that have FMA, another without),
// and its hypot takes another path on ARM64. Each is accurate to about one
// unit in the last place, but they do not agree to the bit, and the pipeline
// amplifies one bit into a different decision on a marginal frame. These
// functions use only +, -, *, / and sqrt, which IEEE 754 rounds exactly, so
// with contraction off (-ffp-contract=off, set for every target) they give
// the same result on x86-64 and ARM64, whatever the CPU. A frame recorded on
// the robot's ARM64 computer replays to the same estimate on a developer's
// x86-64 machine. The algorithms are fdlibm's (Sun Microsystems, 1993, freely
// redistributable), as musl carries them; errors are stated per function and
// measured against glibc in common/test/dmath_test.cpp.
//
// Pure functions: no state, no errno, no exceptions, no allocation.
#ifndef TCPEST_COMMON_DMATH_HPP
#define TCPEST_COMMON_DMATH_HPP

namespace tcpest::dmath {

// Sine and cosine of x (rad). Under 1 ulp for |x| <= 2^19 pi (far beyond any
// angle here); larger arguments give a deterministic, less accurate value.
// NaN or infinite x gives NaN.
double sin(double x) noexcept;
double cos(double x) noexcept;

// e^x, under 1 ulp. Overflow gives +inf, underflow 0.
double exp(double x) noexcept;

// Natural logarithm, under 1 ulp. 0 gives -inf, a negative x NaN.
double log(double x) noexcept;

// x^y for x > 0 as exp(y log x): relative error under 1e-14 for
// |y log x| <= 50 (x = 0 gives 0 for y > 0; x < 0 gives NaN).
double pow_positive(double x, double y) noexcept;

// Arc tangent (rad, [-pi/2, pi/2]), under 1 ulp.
double atan(double x) noexcept;

// Angle of (x, y) (rad, [-pi, pi]) with C's conventions for zeros and
// infinities, under 2 ulp.
double atan2(double y, double x) noexcept;

// Arc sine and cosine (rad) through atan2, under 2 ulp; |x| > 1 gives NaN.
double asin(double x) noexcept;
double acos(double x) noexcept;

// sqrt(x^2 + y^2) without intermediate overflow or underflow, under 1.5 ulp.
double hypot(double x, double y) noexcept;

}  // namespace tcpest::dmath

#endif  // TCPEST_COMMON_DMATH_HPP
