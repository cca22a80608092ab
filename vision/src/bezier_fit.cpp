// The IRLS fit of a quadratic Bezier curve (bezier_fit.hpp).
#include "bezier_fit.hpp"
#include "tcpest/common/dmath.hpp"
#include "robust_scale.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace tcpest {
namespace vision {
namespace detail {
namespace {

// Median of the first n values (n <= kMaxSkeletonSamples), on a copy.
double median(const double* values, std::size_t n) noexcept {
  std::array<double, kMaxSkeletonSamples> copy{};
  if (n == 0U) {
    return 0.0;
  }
  for (std::size_t i = 0U; i < n; ++i) {
    copy[i] = values[i];
  }
  const auto mid = static_cast<std::ptrdiff_t>(n / 2U);
  std::nth_element(copy.begin(), copy.begin() + mid, copy.begin() + static_cast<std::ptrdiff_t>(n));
  return copy[static_cast<std::size_t>(mid)];
}

}  // namespace

double tukey_weight(double u) noexcept {
  if (std::fabs(u) >= 1.0) {
    return 0.0;
  }
  const double v = 1.0 - u * u;
  return v * v;
}

bool solve3(double m[3][3], double rhs[3][2], double x[3][2]) noexcept {
  for (int c = 0; c < 3; ++c) {
    int pivot = c;
    for (int r = c + 1; r < 3; ++r) {
      if (std::fabs(m[r][c]) > std::fabs(m[pivot][c])) {
        pivot = r;
      }
    }
    if (std::fabs(m[pivot][c]) < 1e-12) {
      return false;
    }
    if (pivot != c) {
      for (int k = 0; k < 3; ++k) {
        std::swap(m[c][k], m[pivot][k]);
      }
      std::swap(rhs[c][0], rhs[pivot][0]);
      std::swap(rhs[c][1], rhs[pivot][1]);
    }
    for (int r = c + 1; r < 3; ++r) {
      const double f = m[r][c] / m[c][c];
      for (int k = c; k < 3; ++k) {
        m[r][k] -= f * m[c][k];
      }
      rhs[r][0] -= f * rhs[c][0];
      rhs[r][1] -= f * rhs[c][1];
    }
  }
  for (int c = 2; c >= 0; --c) {
    for (int d = 0; d < 2; ++d) {
      double s = rhs[c][d];
      for (int k = c + 1; k < 3; ++k) {
        s -= m[c][k] * x[k][d];
      }
      x[c][d] = s / m[c][c];
    }
  }
  return true;
}

bool fit_bezier(Border& border, double c, int iterations, int scale_iterations) noexcept {
  const std::size_t n = border.points.size();
  if (n < 5U || iterations < 1 || scale_iterations < 1 || !(c > 0.0)) {
    return false;  // without a first scale every weight would divide by zero
  }
  // Chord-length parameters.
  double total = 0.0;
  border.points[0].t = 0.0;
  for (std::size_t i = 1U; i < n; ++i) {
    total += dmath::hypot(border.points[i].pixel.x - border.points[i - 1U].pixel.x,
                        border.points[i].pixel.y - border.points[i - 1U].pixel.y);
    border.points[i].t = total;
  }
  if (!(total > 0.0)) {
    return false;
  }
  for (std::size_t i = 0U; i < n; ++i) {
    border.points[i].t /= total;
    border.points[i].weight = 1.0;
  }
  std::array<double, kMaxSkeletonSamples> residual{};
  double scale = 0.0;
  Bezier curve{};
  int it = 0;
  for (; it < iterations; ++it) {
    double m[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    double rhs[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    for (std::size_t i = 0U; i < n; ++i) {
      const double t = border.points[i].t;
      const double basis[3] = {(1.0 - t) * (1.0 - t), 2.0 * (1.0 - t) * t, t * t};
      const double w = border.points[i].weight;
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
          m[r][k] += w * basis[r] * basis[k];
        }
        rhs[r][0] += w * basis[r] * border.points[i].pixel.x;
        rhs[r][1] += w * basis[r] * border.points[i].pixel.y;
      }
    }
    double x[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    if (!solve3(m, rhs, x)) {
      return false;
    }
    const Bezier next{Point{x[0][0], x[0][1]}, Point{x[1][0], x[1][1]}, Point{x[2][0], x[2][1]}};
    double change = 0.0;
    if (it > 0) {
      change = std::max({dmath::hypot(next.p0.x - curve.p0.x, next.p0.y - curve.p0.y),
                         dmath::hypot(next.p1.x - curve.p1.x, next.p1.y - curve.p1.y),
                         dmath::hypot(next.p2.x - curve.p2.x, next.p2.y - curve.p2.y)});
    }
    curve = next;
    for (std::size_t i = 0U; i < n; ++i) {
      const Point p = curve.at(border.points[i].t);
      residual[i] = dmath::hypot(border.points[i].pixel.x - p.x, border.points[i].pixel.y - p.y);
    }
    if (it < scale_iterations) {
      // MAD scale (residuals are distances, already >= 0), floored so that a
      // near-perfect fit does not reject every point.
      scale = detail::kMadToSigma * median(residual.data(), n);
      if (scale < 0.15) {
        scale = 0.15;
      }
    }
    for (std::size_t i = 0U; i < n; ++i) {
      border.points[i].weight = tukey_weight(residual[i] / (c * scale));
    }
    if (it > 0 && change < 1e-4) {
      ++it;
      break;
    }
  }
  double weight_sum = 0.0;
  for (std::size_t i = 0U; i < n; ++i) {
    weight_sum += border.points[i].weight;
  }
  border.curve = curve;
  border.scale_px = scale;
  border.iterations = it;
  border.valid = weight_sum >= 4.0;
  return border.valid;
}

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
