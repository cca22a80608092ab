// The shared data types' own functions (extraction.hpp): the errors' texts,
// a region's moments, a Bezier curve's evaluation, the corners for the
// solver.
#include "tcpest/vision/extraction.hpp"

#include <cmath>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {

const char* to_string(VisionError e) noexcept {
  switch (e) {
    case VisionError::BadImage: return "bad image (null, empty or bad stride)";
    case VisionError::ImageTooLarge: return "image larger than the extractor was configured for";
    case VisionError::TooManyRuns: return "too many colour regions (image too fragmented)";
    case VisionError::NoInstrument: return "no chain of marker regions found";
    case VisionError::BorderFitFailed: return "too few edge points to fit the borders";
    case VisionError::BadParameter: return "invalid extractor configuration";
    case VisionError::OutOfMemory: return "not enough memory for the extractor's buffers";
  }
  return "unknown vision error";
}

void Region::merge(const Region& other) noexcept {
  const double n0 = static_cast<double>(area);
  const double n1 = static_cast<double>(other.area);
  const double n = n0 + n1;
  if (!(n > 0.0)) {
    return;
  }
  const Point c{(n0 * centroid.x + n1 * other.centroid.x) / n, (n0 * centroid.y + n1 * other.centroid.y) / n};
  // Parallel-axis theorem: second moments about the joint centroid.
  const auto shifted = [&c](const Region& r, double& xx, double& xy, double& yy) noexcept {
    const double dx = r.centroid.x - c.x;
    const double dy = r.centroid.y - c.y;
    xx = r.cov_xx + dx * dx;
    xy = r.cov_xy + dx * dy;
    yy = r.cov_yy + dy * dy;
  };
  double xx0 = 0.0, xy0 = 0.0, yy0 = 0.0, xx1 = 0.0, xy1 = 0.0, yy1 = 0.0;
  shifted(*this, xx0, xy0, yy0);
  shifted(other, xx1, xy1, yy1);
  cov_xx = (n0 * xx0 + n1 * xx1) / n;
  cov_xy = (n0 * xy0 + n1 * xy1) / n;
  cov_yy = (n0 * yy0 + n1 * yy1) / n;
  centroid = c;
  area += other.area;
  x_min = x_min < other.x_min ? x_min : other.x_min;
  y_min = y_min < other.y_min ? y_min : other.y_min;
  x_max = x_max > other.x_max ? x_max : other.x_max;
  y_max = y_max > other.y_max ? y_max : other.y_max;
  update_shape();
}

void Region::update_shape() noexcept {
  const double mean = 0.5 * (cov_xx + cov_yy);
  const double diff = 0.5 * (cov_xx - cov_yy);
  const double root = std::sqrt(diff * diff + cov_xy * cov_xy);
  const double l1 = mean + root;
  const double l2 = mean - root;
  // Uniform ellipse: variance along a half axis h is h^2 / 4.
  half_major = 2.0 * std::sqrt(l1 > 0.0 ? l1 : 0.0);
  half_minor = 2.0 * std::sqrt(l2 > 0.0 ? l2 : 0.0);
  orientation_rad = 0.5 * dmath::atan2(2.0 * cov_xy, cov_xx - cov_yy);
}

double Region::extent_along(double dx, double dy) const noexcept {
  // Support function of the equivalent ellipse: sqrt(4 u^T C u).
  const double v = cov_xx * dx * dx + 2.0 * cov_xy * dx * dy + cov_yy * dy * dy;
  return 2.0 * std::sqrt(v > 0.0 ? v : 0.0);
}

Point Bezier::at(double t) const noexcept {
  const double a = (1.0 - t) * (1.0 - t);
  const double b = 2.0 * (1.0 - t) * t;
  const double c = t * t;
  return Point{a * p0.x + b * p1.x + c * p2.x, a * p0.y + b * p1.y + c * p2.y};
}

Point Bezier::derivative(double t) const noexcept {
  return Point{2.0 * (1.0 - t) * (p1.x - p0.x) + 2.0 * t * (p2.x - p1.x),
               2.0 * (1.0 - t) * (p1.y - p0.y) + 2.0 * t * (p2.y - p1.y)};
}

void corners_to_arrays(const Extraction& e, std::array<solver::Vec2, kNumCorners>& pixels,
                       std::array<bool, kNumCorners>& present) noexcept {
  for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
    present[k] = e.corners[k].found;
    pixels[k] = solver::Vec2(e.corners[k].pixel.x, e.corners[k].pixel.y);
  }
}

}  // namespace vision
}  // namespace tcpest
