// Stage 3 (borders) and stage 4 (corners).
#include <algorithm>
#include <cmath>

#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

struct Rgb {
  double r = 0.0, g = 0.0, b = 0.0;
};

// Bilinear RGB at a sub-pixel position; false outside the image.
bool sample(const ImageView& image, double x, double y, Rgb& out) noexcept {
  if (!(x >= 0.0) || !(y >= 0.0) || x > static_cast<double>(image.width - 1) ||
      y > static_cast<double>(image.height - 1)) {
    return false;
  }
  int x0 = static_cast<int>(x);
  int y0 = static_cast<int>(y);
  if (x0 >= image.width - 1) {
    x0 = image.width - 2;
  }
  if (y0 >= image.height - 1) {
    y0 = image.height - 2;
  }
  if (x0 < 0 || y0 < 0) {
    return false;  // a one-pixel-wide image
  }
  const double fx = x - static_cast<double>(x0);
  const double fy = y - static_cast<double>(y0);
  const std::uint8_t* a = image.row(y0) + 3 * x0;
  const std::uint8_t* b = image.row(y0 + 1) + 3 * x0;
  const double w00 = (1.0 - fx) * (1.0 - fy);
  const double w10 = fx * (1.0 - fy);
  const double w01 = (1.0 - fx) * fy;
  const double w11 = fx * fy;
  out.r = w00 * a[0] + w10 * a[3] + w01 * b[0] + w11 * b[3];
  out.g = w00 * a[1] + w10 * a[4] + w01 * b[1] + w11 * b[4];
  out.b = w00 * a[2] + w10 * a[5] + w01 * b[2] + w11 * b[5];
  return true;
}

std::uint8_t to_byte(double v) noexcept {
  const double c = v < 0.0 ? 0.0 : (v > 255.0 ? 255.0 : v);
  return static_cast<std::uint8_t>(c + 0.5);
}

double dist2(const Rgb& a, const Rgb& b) noexcept {
  return (a.r - b.r) * (a.r - b.r) + (a.g - b.g) * (a.g - b.g) + (a.b - b.b) * (a.b - b.b);
}

double tukey(double u) noexcept {
  if (std::fabs(u) >= 1.0) {
    return 0.0;
  }
  const double v = 1.0 - u * u;
  return v * v;
}

// Solves the 3x3 system m x = rhs by Gaussian elimination with partial
// pivoting; false when singular.
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

// IRLS fit of a quadratic Bezier with Tukey's biweight (c in MAD units).
bool fit_bezier(Border& border, double c, int iterations, int scale_iterations) noexcept {
  const std::size_t n = border.points.size();
  if (n < 5U) {
    return false;
  }
  // Chord-length parameters.
  double total = 0.0;
  border.points[0].t = 0.0;
  for (std::size_t i = 1U; i < n; ++i) {
    total += std::hypot(border.points[i].pixel.x - border.points[i - 1U].pixel.x,
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
      change = std::max({std::hypot(next.p0.x - curve.p0.x, next.p0.y - curve.p0.y),
                         std::hypot(next.p1.x - curve.p1.x, next.p1.y - curve.p1.y),
                         std::hypot(next.p2.x - curve.p2.x, next.p2.y - curve.p2.y)});
    }
    curve = next;
    for (std::size_t i = 0U; i < n; ++i) {
      const Point p = curve.at(border.points[i].t);
      residual[i] = std::hypot(border.points[i].pixel.x - p.x, border.points[i].pixel.y - p.y);
    }
    if (it < scale_iterations) {
      // MAD scale (residuals are distances, already >= 0), floored so that a
      // near-perfect fit does not reject every point.
      scale = 1.4826 * median(residual.data(), n);
      if (scale < 0.15) {
        scale = 0.15;
      }
    }
    for (std::size_t i = 0U; i < n; ++i) {
      border.points[i].weight = tukey(residual[i] / (c * scale));
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

}  // namespace

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

Status<VisionError> FeatureExtractor::fit_borders(const ImageView& image) noexcept {
  Extraction& e = result_;
  e.skeleton_count = 0;
  e.borders[0] = Border{};
  e.borders[1] = Border{};
  const Interpretation& in = e.interpretation;
  if (in.found_count < 2 || !image.valid() || image.width != width_ || image.height != height_) {
    return Status<VisionError>::failure(VisionError::BorderFitFailed);
  }
  // Ordered centroids, extended past both ends to cover the end boundaries.
  std::array<Point, kNumMarkers + 2> poly{};
  std::array<double, kNumMarkers + 2> half_width{};
  std::size_t count = 0U;
  for (int m = in.first_marker; m <= in.last_marker; ++m) {
    const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
    if (!obs.found) {
      continue;
    }
    poly[count + 1U] = obs.region.centroid;
    ++count;
  }
  if (count < 2U) {
    return Status<VisionError>::failure(VisionError::BorderFitFailed);
  }
  {
    const Region& first = in.markers[static_cast<std::size_t>(in.first_marker)].region;
    const Region& last = in.markers[static_cast<std::size_t>(in.last_marker)].region;
    double dx = poly[2].x - poly[1].x;
    double dy = poly[2].y - poly[1].y;
    double d = std::hypot(dx, dy);
    double reach = 1.3 * first.extent_along(dx / d, dy / d);
    poly[0] = Point{poly[1].x - dx / d * reach, poly[1].y - dy / d * reach};
    dx = poly[count].x - poly[count - 1U].x;
    dy = poly[count].y - poly[count - 1U].y;
    d = std::hypot(dx, dy);
    reach = 1.3 * last.extent_along(dx / d, dy / d);
    poly[count + 1U] = Point{poly[count].x + dx / d * reach, poly[count].y + dy / d * reach};
  }
  const std::size_t vertices = count + 2U;
  // Half width of the tube at each vertex: the marker region's extent across
  // the skeleton.
  {
    std::size_t v = 1U;
    for (int m = in.first_marker; m <= in.last_marker; ++m) {
      const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
      if (!obs.found) {
        continue;
      }
      const Point a = poly[v - 1U];
      const Point b = poly[v + 1U];
      double tx = b.x - a.x;
      double ty = b.y - a.y;
      const double tl = std::hypot(tx, ty);
      tx /= tl;
      ty /= tl;
      // The equivalent ellipse's extent understates a rectangle's half width
      // by sqrt(3)/2.
      half_width[v] = obs.region.extent_along(-ty, tx) * 0.866;
      ++v;
    }
    half_width[0] = half_width[1];
    half_width[vertices - 1U] = half_width[vertices - 2U];
  }
  std::array<double, kNumMarkers + 2> arc{};
  for (std::size_t i = 1U; i < vertices; ++i) {
    arc[i] = arc[i - 1U] + std::hypot(poly[i].x - poly[i - 1U].x, poly[i].y - poly[i - 1U].y);
  }
  const double length = arc[vertices - 1U];
  const int samples = config_.skeleton_samples;
  const auto point_at = [&](double s, Point& p, double& w) noexcept {
    s = s < 0.0 ? 0.0 : (s > length ? length : s);
    std::size_t seg = 0U;
    while (seg + 2U < vertices && arc[seg + 1U] < s) {
      ++seg;
    }
    const double span = arc[seg + 1U] - arc[seg];
    const double f = span > 0.0 ? (s - arc[seg]) / span : 0.0;
    p = Point{poly[seg].x + f * (poly[seg + 1U].x - poly[seg].x), poly[seg].y + f * (poly[seg + 1U].y - poly[seg].y)};
    w = half_width[seg] + f * (half_width[seg + 1U] - half_width[seg]);
  };
  const double smoothing = 0.5 * length / static_cast<double>(count + 1U);
  const std::uint8_t* classes = classes_.get();
  for (int i = 0; i < samples; ++i) {
    const double s = (static_cast<double>(i) + 0.5) * length / static_cast<double>(samples);
    Point p, pa, pb;
    double w = 0.0, wa = 0.0, wb = 0.0;
    point_at(s, p, w);
    point_at(s - smoothing, pa, wa);
    point_at(s + smoothing, pb, wb);
    double tx = pb.x - pa.x;
    double ty = pb.y - pa.y;
    const double tl = std::hypot(tx, ty);
    if (!(tl > 0.0) || !(w > 0.5)) {
      continue;
    }
    tx /= tl;
    ty /= tl;
    if (e.skeleton_count < static_cast<int>(kMaxSkeletonSamples)) {
      e.skeleton[static_cast<std::size_t>(e.skeleton_count)] = p;
      ++e.skeleton_count;
    }
    // Side 1 (right, model.md) lies along (-ty, tx) in pixel coordinates.
    for (int side = 0; side < 2; ++side) {
      const double nx = side == 1 ? -ty : ty;
      const double ny = side == 1 ? tx : -tx;
      // The labelled region's boundary along this normal: the last classified
      // pixel before the background, searched outwards.
      double region_edge = -1.0;
      const double r_max = config_.edge_search_max * w + 2.0;
      for (double r = 0.0; r <= r_max; r += 1.0) {
        const int xi = static_cast<int>(std::lround(p.x + r * nx));
        const int yi = static_cast<int>(std::lround(p.y + r * ny));
        if (xi < 0 || yi < 0 || xi >= width_ || yi >= height_) {
          break;
        }
        if (classes[static_cast<std::size_t>(yi) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(xi)] !=
            0U) {
          region_edge = r;
        } else if (region_edge >= 0.0 && r > region_edge + 2.0) {
          break;
        }
      }
      // Gradient magnitude along the normal, with its direction checked
      // against the tangential gradient.
      constexpr double kStep = 0.5;
      double best = 0.0;
      double best_r = -1.0;
      double prev_g = 0.0, prev_prev_g = 0.0;
      double peak_left = 0.0, peak_right = 0.0;
      bool have_prev = false;
      const double r0 = config_.edge_search_min * w;
      for (double r = r0; r <= r_max; r += kStep) {
        const double cx = p.x + r * nx;
        const double cy = p.y + r * ny;
        Rgb in_px, out_px, left_px, right_px;
        if (!sample(image, cx - 0.5 * nx, cy - 0.5 * ny, in_px) || !sample(image, cx + 0.5 * nx, cy + 0.5 * ny, out_px) ||
            !sample(image, cx - 0.5 * tx, cy - 0.5 * ty, left_px) || !sample(image, cx + 0.5 * tx, cy + 0.5 * ty, right_px)) {
          break;
        }
        const double g_normal = dist2(in_px, out_px);
        const double g_tangent = dist2(left_px, right_px);
        const double g = std::sqrt(g_normal);
        const bool agrees = g_normal > 3.0 * g_tangent;
        const bool near_region = region_edge < 0.0 || std::fabs(r - region_edge) <= 3.0;
        if (have_prev && prev_g > best && prev_g >= prev_prev_g && prev_g >= g && near_region) {
          // prev sample is a local maximum
          best = prev_g;
          best_r = r - kStep;
          peak_left = prev_prev_g;
          peak_right = g;
        }
        prev_prev_g = prev_g;
        prev_g = agrees ? g : 0.0;
        have_prev = true;
      }
      if (best_r < 0.0 || best < 8.0) {
        continue;
      }
      const double denom = peak_left - 2.0 * best + peak_right;
      double offset = 0.0;
      if (denom < 0.0) {
        offset = 0.5 * (peak_left - peak_right) / denom;
        offset = offset > 0.5 ? 0.5 : (offset < -0.5 ? -0.5 : offset);
      }
      const double r_edge = best_r + offset * kStep;
      static_cast<void>(e.borders[static_cast<std::size_t>(side)].points.push_back(
          EdgePoint{Point{p.x + r_edge * nx, p.y + r_edge * ny}, 1.0, 0.0}));  // capacity = max samples
    }
  }
  bool ok = true;
  for (std::size_t side = 0U; side < 2U; ++side) {
    if (!fit_bezier(e.borders[side], config_.tukey_c, config_.irls_iterations, config_.irls_scale_iterations)) {
      ok = false;
    }
  }
  if (!ok && !e.borders[0].valid && !e.borders[1].valid) {
    return Status<VisionError>::failure(VisionError::BorderFitFailed);
  }
  return ok_status<VisionError>();
}

// --- stage 4 ----------------------------------------------------------------

Status<VisionError> FeatureExtractor::find_corners(const ImageView& image) noexcept {
  Extraction& e = result_;
  for (auto& c : e.corners) {
    c = Corner{};
  }
  e.corner_count = 0;
  const Interpretation& in = e.interpretation;
  if (in.found_count < 2) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  constexpr std::size_t kInsets = 5U;
  const int samples = config_.profile_samples;
  std::array<std::array<double, 1024>, kInsets> score{};   // yellow - blue
  std::array<std::array<double, 1024>, kInsets> margin{};  // blue margin (end boundaries)
  std::array<std::array<bool, 1024>, kInsets> valid{};
  constexpr double kT0 = -0.08;
  constexpr double kT1 = 1.08;
  const double dt = (kT1 - kT0) / static_cast<double>(samples - 1);
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Border& border = e.borders[side];
    if (!border.valid) {
      continue;
    }
    // Profiles along curves parallel to the border, at several insets.
    for (int i = 0; i < samples; ++i) {
      const double t = kT0 + dt * static_cast<double>(i);
      const Point p = border.curve.at(t);
      const Point d = border.curve.derivative(t);
      const double dl = std::hypot(d.x, d.y);
      // Outward normal: side 1's is (-dy, dx), side 0's the opposite.
      const double sign = side == 1U ? 1.0 : -1.0;
      const double nx = dl > 0.0 ? sign * (-d.y / dl) : 0.0;
      const double ny = dl > 0.0 ? sign * (d.x / dl) : 0.0;
      for (std::size_t q = 0U; q < kInsets; ++q) {
        const auto at = static_cast<std::size_t>(i);
        valid[q][at] = false;
        Rgb px;
        const double inset = config_.profile_insets_px[q];
        if (!(dl > 0.0) || !sample(image, p.x - inset * nx, p.y - inset * ny, px)) {
          continue;
        }
        const std::uint8_t r8 = to_byte(px.r), g8 = to_byte(px.g), b8 = to_byte(px.b);
        score[q][at] = colors_.yellow_minus_blue(r8, g8, b8);
        margin[q][at] = colors_.blue_margin(r8, g8, b8);
        valid[q][at] = true;
      }
    }
    // Parameter of each marker's centroid on this border (nearest sample).
    std::array<double, kNumMarkers> marker_t{};
    for (int m = in.first_marker; m <= in.last_marker; ++m) {
      const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
      double best = 1e30;
      for (int i = 0; i < samples; ++i) {
        const double t = kT0 + dt * static_cast<double>(i);
        const Point p = border.curve.at(t);
        const double dd = std::hypot(p.x - obs.region.centroid.x, p.y - obs.region.centroid.y);
        if (dd < best) {
          best = dd;
          marker_t[static_cast<std::size_t>(m)] = t;
        }
      }
    }
    double marker_span = 0.3;
    if (in.last_marker > in.first_marker) {
      marker_span = std::fabs(marker_t[static_cast<std::size_t>(in.last_marker)] -
                              marker_t[static_cast<std::size_t>(in.first_marker)]) /
                    static_cast<double>(in.last_marker - in.first_marker);
    }
    // Boundary j lies between markers j-1 and j (0-based markers).
    for (int j = in.first_marker; j <= in.last_marker + 1; ++j) {
      const bool internal = j > in.first_marker && j <= in.last_marker;
      double t_lo = 0.0, t_hi = 0.0;
      double want_sign = 0.0;  // sign of the profile's change from base to tip
      bool use_margin = false;
      if (internal) {
        t_lo = marker_t[static_cast<std::size_t>(j - 1)];
        t_hi = marker_t[static_cast<std::size_t>(j)];
        const bool from_blue = config_.marker_classes[static_cast<std::size_t>(j - 1)] == PixelClass::Blue;
        want_sign = from_blue ? 1.0 : -1.0;
      } else {
        // End boundary: the end marker's colour margin crosses zero.
        const int m = (j == in.first_marker) ? j : j - 1;
        if (config_.marker_classes[static_cast<std::size_t>(m)] != PixelClass::Blue) {
          continue;  // only blue end markers have a margin profile
        }
        use_margin = true;
        const double tm = marker_t[static_cast<std::size_t>(m)];
        if (j == in.first_marker) {
          t_lo = tm - marker_span;
          t_hi = tm;
          want_sign = 1.0;
        } else {
          t_lo = tm;
          t_hi = tm + marker_span;
          want_sign = -1.0;
        }
      }
      // Per inset: the strongest crossing of the right direction in (t_lo, t_hi).
      std::array<double, kInsets> crossing_t{};
      std::array<bool, kInsets> crossing_ok{};
      double strength = 0.0;
      int crossings = 0;
      for (std::size_t q = 0U; q < kInsets; ++q) {
        const double* profile = use_margin ? margin[q].data() : score[q].data();
        double best_slope = 0.0;
        for (int i = 0; i + 1 < samples; ++i) {
          const double t = kT0 + dt * static_cast<double>(i);
          if (t < t_lo || t + dt > t_hi) {
            continue;
          }
          const auto a = static_cast<std::size_t>(i);
          if (!valid[q][a] || !valid[q][a + 1U]) {
            continue;
          }
          const double fa = profile[a];
          const double fb = profile[a + 1U];
          if (!((fa < 0.0 && fb >= 0.0) || (fa >= 0.0 && fb < 0.0)) || (fb - fa) * want_sign <= 0.0) {
            continue;
          }
          const std::size_t lo = a >= 2U ? a - 2U : 0U;
          const std::size_t hi =
              a + 3U < static_cast<std::size_t>(samples) ? a + 3U : static_cast<std::size_t>(samples - 1);
          const double slope = (profile[hi] - profile[lo]) * want_sign;
          if (!crossing_ok[q] || slope > best_slope) {
            crossing_t[q] = t + dt * fa / (fa - fb);
            crossing_ok[q] = true;
            best_slope = slope;
          }
        }
        if (crossing_ok[q]) {
          strength += best_slope;
          ++crossings;
        }
      }
      if (crossings == 0) {
        continue;
      }
      // Extrapolate the crossing to inset 0: near the border the boundary
      // curve is tangent to it, t(d) = t0 + a sqrt(d) + c d^1.5.
      double t0 = 0.0;
      if (crossings >= 3) {
        double m[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
        double rhs[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
        for (std::size_t q = 0U; q < kInsets; ++q) {
          if (!crossing_ok[q]) {
            continue;
          }
          const double d = config_.profile_insets_px[q];
          const double basis[3] = {1.0, std::sqrt(d), d * std::sqrt(d)};
          for (int r = 0; r < 3; ++r) {
            for (int k = 0; k < 3; ++k) {
              m[r][k] += basis[r] * basis[k];
            }
            rhs[r][0] += basis[r] * crossing_t[q];
          }
        }
        double x[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
        if (!solve3(m, rhs, x)) {
          continue;
        }
        t0 = x[0][0];
      } else {
        for (std::size_t q = 0U; q < kInsets; ++q) {
          if (crossing_ok[q]) {
            t0 = crossing_t[q];
            break;
          }
        }
      }
      const int k = 2 * j + static_cast<int>(side);
      Corner& c = e.corners[static_cast<std::size_t>(k)];
      c.found = true;
      c.pixel = border.curve.at(t0);
      const double conf = (strength / static_cast<double>(kInsets)) / 8.0;
      c.confidence = conf > 1.0 ? 1.0 : (conf < 0.0 ? 0.0 : conf);
      ++e.corner_count;
    }
  }
  return ok_status<VisionError>();
}

Status<VisionError> FeatureExtractor::extract(const ImageView& image, const MarkerPriors& priors) noexcept {
  const auto s1 = find_regions(image);
  if (!s1.ok()) {
    return s1;
  }
  const auto s2 = interpret(priors);
  if (!s2.ok()) {
    return s2;
  }
  const auto s3 = fit_borders(image);
  if (!s3.ok()) {
    return s3;
  }
  return find_corners(image);
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
