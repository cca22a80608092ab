// Stage 3 (borders) and stage 4 (corners).
#include <algorithm>
#include <cmath>

#include <Eigen/Dense>


#include "sampling.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

using detail::Rgb;
using detail::sample;
using detail::to_byte;

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
    double reach = config_.skeleton_extension * first.extent_along(dx / d, dy / d);
    poly[0] = Point{poly[1].x - dx / d * reach, poly[1].y - dy / d * reach};
    dx = poly[count].x - poly[count - 1U].x;
    dy = poly[count].y - poly[count - 1U].y;
    d = std::hypot(dx, dy);
    reach = config_.skeleton_extension * last.extent_along(dx / d, dy / d);
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
      const int region_steps = static_cast<int>(r_max);
      for (int step = 0; step <= region_steps; ++step) {
        const double r = static_cast<double>(step);
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
      // Near the labelled region's boundary when there is one, else the
      // whole window.
      double r0 = config_.edge_search_min * w;
      double r1 = r_max;
      if (region_edge >= 0.0) {
        r0 = std::max(r0, region_edge - 3.5);
        r1 = std::min(r1, region_edge + 3.5);
      }
      const int edge_steps = r1 >= r0 ? static_cast<int>((r1 - r0) / kStep) : -1;
      for (int step = 0; step <= edge_steps; ++step) {
        const double r = r0 + kStep * static_cast<double>(step);
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
      const double r_edge = best_r + offset * kStep + config_.edge_offset_px;
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

namespace {

// Parameter of the point of `curve` nearest to p, from t (Newton, bounded).
double nearest_t(const Bezier& curve, const Point& p, double t) noexcept {
  const double ddx = 2.0 * ((curve.p2.x - curve.p1.x) - (curve.p1.x - curve.p0.x));
  const double ddy = 2.0 * ((curve.p2.y - curve.p1.y) - (curve.p1.y - curve.p0.y));
  for (int it = 0; it < 8; ++it) {
    const Point q = curve.at(t);
    const Point d = curve.derivative(t);
    const double f = (q.x - p.x) * d.x + (q.y - p.y) * d.y;
    const double df = d.x * d.x + d.y * d.y + (q.x - p.x) * ddx + (q.y - p.y) * ddy;
    if (!(std::fabs(df) > 1e-12)) {
      break;
    }
    const double step = f / df;
    t -= step > 0.2 ? 0.2 : (step < -0.2 ? -0.2 : step);
  }
  return t;
}

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;

// The visible arc of a marker boundary is half of an ellipse (the projected
// circle) tangent to both borders at the two corners. A projective map H that
// sends the intersection of the two borders' tangent lines to infinity makes
// the lines parallel (v = v_mid -/+ w) and keeps the conic tangent to them;
// such an ellipse is u = u_c + alpha cos(phi) + beta sin(phi),
// v = v_mid + w sin(phi), which touches the lines at u = u_c -/+ beta. With
// sin(phi) from each arc point's v, u is linear in (u_c, alpha, beta): least
// squares, then the two tangency points mapped back. The tangent lines are
// taken at the current corner estimates, so the fit is repeated (bounded).
bool fit_boundary_arc(const std::array<Border, 2>& borders, const Point* arc, std::size_t count,
                      std::array<double, 2>& t_corner) noexcept {
  constexpr int kRounds = 4;
  for (int round = 0; round < kRounds; ++round) {
    std::array<Vec3, 2> line{};
    std::array<Point, 2> c{};
    for (std::size_t side = 0U; side < 2U; ++side) {
      c[side] = borders[side].curve.at(t_corner[side]);
      const Point d = borders[side].curve.derivative(t_corner[side]);
      const Vec3 a(c[side].x, c[side].y, 1.0);
      const Vec3 b(c[side].x + d.x, c[side].y + d.y, 1.0);
      line[side] = a.cross(b);
    }
    const Point mid{0.5 * (c[0].x + c[1].x), 0.5 * (c[0].y + c[1].y)};
    Mat3 h = Mat3::Identity();
    const Vec3 x = line[0].cross(line[1]);
    if (std::fabs(x.z()) > 1e-12) {
      const double xx = x.x() / x.z();
      const double xy = x.y() / x.z();
      // Line through X perpendicular to (mid - X), scaled to 1 at mid.
      const double dx = mid.x - xx;
      const double dy = mid.y - xy;
      Vec3 h3(dx, dy, -(dx * xx + dy * xy));
      const double at_mid = h3.x() * mid.x + h3.y() * mid.y + h3.z();
      if (!(std::fabs(at_mid) > 1e-12)) {
        return false;
      }
      h3 /= at_mid;
      h.row(2) = h3.transpose();
    }
    const auto map = [&h](const Point& p) noexcept {
      const Vec3 q = h * Vec3(p.x, p.y, 1.0);
      return Point{q.x() / q.z(), q.y() / q.z()};
    };
    // Mapped tangent lines are parallel: a common unit normal n.
    const Mat3 h_inv_t = h.inverse().transpose();
    const Vec3 l0 = h_inv_t * line[0];
    const Vec3 l1 = h_inv_t * line[1];
    const double n0 = std::hypot(l0.x(), l0.y());
    const double n1 = std::hypot(l1.x(), l1.y());
    if (!(n0 > 1e-12) || !(n1 > 1e-12)) {
      return false;
    }
    double nx = l0.x() / n0;
    double ny = l0.y() / n0;
    const Point m0 = map(c[0]);
    const Point m1 = map(c[1]);
    double v0 = nx * m0.x + ny * m0.y;
    double v1 = nx * m1.x + ny * m1.y;
    if (v1 < v0) {  // orient v from side 0 to side 1
      nx = -nx;
      ny = -ny;
      v0 = -v0;
      v1 = -v1;
    }
    const double w = 0.5 * (v1 - v0);
    const double v_mid = 0.5 * (v1 + v0);
    if (!(w > 0.5)) {
      return false;
    }
    const double ux = -ny;
    const double uy = nx;
    double m[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    double rhs[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    for (std::size_t i = 0U; i < count; ++i) {
      const Point q = map(arc[i]);
      double sn = (nx * q.x + ny * q.y - v_mid) / w;
      sn = sn > 1.0 ? 1.0 : (sn < -1.0 ? -1.0 : sn);
      const double basis[3] = {1.0, std::sqrt(1.0 - sn * sn), sn};
      const double u = ux * q.x + uy * q.y;
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
          m[r][k] += basis[r] * basis[k];
        }
        rhs[r][0] += basis[r] * u;
      }
    }
    double sol[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    if (!solve3(m, rhs, sol)) {
      return false;
    }
    const Mat3 h_inv = h.inverse();
    for (std::size_t side = 0U; side < 2U; ++side) {
      const double sgn = side == 1U ? 1.0 : -1.0;
      const double u = sol[0][0] + sgn * sol[2][0];
      const double v = v_mid + sgn * w;
      const Vec3 q = h_inv * Vec3(u * ux + v * nx, u * uy + v * ny, 1.0);
      if (!(std::fabs(q.z()) > 1e-12)) {
        return false;
      }
      const Point p{q.x() / q.z(), q.y() / q.z()};
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
        return false;
      }
      t_corner[side] = nearest_t(borders[side].curve, p, t_corner[side]);
    }
  }
  return true;
}

}  // namespace

Status<VisionError> FeatureExtractor::find_corners(const ImageView& image) noexcept {
  Extraction& e = result_;
  for (auto& c : e.corners) {
    c = Corner{};
  }
  e.corner_count = 0;
  e.refined = false;
  const Interpretation& in = e.interpretation;
  if (in.found_count < 2 || (!e.borders[0].valid && !e.borders[1].valid)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  const int samples = config_.profile_samples;
  constexpr double kT0 = -0.08;
  constexpr double kT1 = 1.08;
  const double dt = (kT1 - kT0) / static_cast<double>(samples - 1);
  // Insets: from just inside the border to a little past the tube's middle,
  // so that the two sides together trace each boundary's visible arc.
  double half_width = 0.0;
  int width_count = 0;
  for (int m = in.first_marker; m <= in.last_marker; ++m) {
    const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
    if (obs.found) {
      half_width += obs.region.half_minor * 0.866;
      ++width_count;
    }
  }
  half_width = width_count > 0 ? half_width / width_count : 5.0;
  std::array<double, kProfileInsets> insets{};
  const double first_inset = config_.profile_min_inset_px;
  const double last_inset = std::max(first_inset + 1.0, config_.profile_max_inset * half_width);
  for (std::size_t q = 0U; q < kProfileInsets; ++q) {
    insets[q] = first_inset + (last_inset - first_inset) * static_cast<double>(q) / static_cast<double>(kProfileInsets - 1U);
  }
  // Profiles per side and inset.
  std::array<double, kNumMarkers> marker_t_side[2]{};
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Border& border = e.borders[side];
    if (!border.valid) {
      continue;
    }
    for (int i = 0; i < samples; ++i) {
      const double t = kT0 + dt * static_cast<double>(i);
      const Point p = border.curve.at(t);
      const Point d = border.curve.derivative(t);
      const double dl = std::hypot(d.x, d.y);
      // Outward normal: side 1's is (-dy, dx), side 0's the opposite.
      const double sign = side == 1U ? 1.0 : -1.0;
      const double nx = dl > 0.0 ? sign * (-d.y / dl) : 0.0;
      const double ny = dl > 0.0 ? sign * (d.x / dl) : 0.0;
      for (std::size_t q = 0U; q < kProfileInsets; ++q) {
        const auto at = static_cast<std::size_t>(i);
        profile_valid_[side][q][at] = false;
        Rgb px;
        if (!(dl > 0.0) || !sample(image, p.x - insets[q] * nx, p.y - insets[q] * ny, px)) {
          continue;
        }
        const std::uint8_t r8 = to_byte(px.r), g8 = to_byte(px.g), b8 = to_byte(px.b);
        profile_score_[side][q][at] = colors_.yellow_minus_blue(r8, g8, b8);
        profile_margin_[side][q][at] = colors_.blue_margin(r8, g8, b8);
        profile_valid_[side][q][at] = true;
      }
    }
    for (int m = in.first_marker; m <= in.last_marker; ++m) {
      const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
      double best = 1e30;
      for (int i = 0; i < samples; ++i) {
        const double t = kT0 + dt * static_cast<double>(i);
        const Point p = border.curve.at(t);
        const double dd = std::hypot(p.x - obs.region.centroid.x, p.y - obs.region.centroid.y);
        if (dd < best) {
          best = dd;
          marker_t_side[side][static_cast<std::size_t>(m)] = t;
        }
      }
    }
  }
  // Boundary j lies between markers j-1 and j (0-based markers).
  for (int j = in.first_marker; j <= in.last_marker + 1; ++j) {
    const bool internal = j > in.first_marker && j <= in.last_marker;
    bool use_margin = false;
    double want_sign = 0.0;  // sign of the profile's change from base to tip
    if (internal) {
      want_sign = config_.marker_classes[static_cast<std::size_t>(j - 1)] == PixelClass::Blue ? 1.0 : -1.0;
    } else {
      const int m = (j == in.first_marker) ? j : j - 1;
      if (config_.marker_classes[static_cast<std::size_t>(m)] != PixelClass::Blue) {
        continue;  // only blue end markers have a margin profile
      }
      use_margin = true;
      want_sign = (j == in.first_marker) ? 1.0 : -1.0;
    }
    std::array<Point, 2U * kProfileInsets> arc{};
    std::size_t arc_count = 0U;
    std::array<std::array<double, kProfileInsets>, 2> crossing_t{};
    std::array<std::array<bool, kProfileInsets>, 2> crossing_ok{};
    std::array<double, 2> strength{{0.0, 0.0}};
    for (std::size_t side = 0U; side < 2U; ++side) {
      const Border& border = e.borders[side];
      if (!border.valid) {
        continue;
      }
      const auto& mt = marker_t_side[side];
      double span = 0.3;
      if (in.last_marker > in.first_marker) {
        span = std::fabs(mt[static_cast<std::size_t>(in.last_marker)] - mt[static_cast<std::size_t>(in.first_marker)]) /
               static_cast<double>(in.last_marker - in.first_marker);
      }
      double t_lo = 0.0, t_hi = 0.0;
      if (internal) {
        t_lo = mt[static_cast<std::size_t>(j - 1)] - 0.25 * span;
        t_hi = mt[static_cast<std::size_t>(j)] + 0.25 * span;
      } else if (j == in.first_marker) {
        t_lo = mt[static_cast<std::size_t>(j)] - 1.2 * span;
        t_hi = mt[static_cast<std::size_t>(j)] + 0.25 * span;
      } else {
        t_lo = mt[static_cast<std::size_t>(j - 1)] - 0.25 * span;
        t_hi = mt[static_cast<std::size_t>(j - 1)] + 1.2 * span;
      }
      for (std::size_t q = 0U; q < kProfileInsets; ++q) {
        const double* profile = use_margin ? profile_margin_[side][q].data() : profile_score_[side][q].data();
        const bool* ok = profile_valid_[side][q].data();
        double best_slope = 0.0;
        for (int i = 0; i + 1 < samples; ++i) {
          const double t = kT0 + dt * static_cast<double>(i);
          if (t < t_lo || t + dt > t_hi) {
            continue;
          }
          const auto a = static_cast<std::size_t>(i);
          if (!ok[a] || !ok[a + 1U]) {
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
          if (!crossing_ok[side][q] || slope > best_slope) {
            crossing_t[side][q] = t + dt * fa / (fa - fb);
            crossing_ok[side][q] = true;
            best_slope = slope;
          }
        }
        if (crossing_ok[side][q]) {
          strength[side] += best_slope;
          const double tc = crossing_t[side][q];
          const Point p = border.curve.at(tc);
          const Point d = border.curve.derivative(tc);
          const double dl = std::hypot(d.x, d.y);
          const double sign = side == 1U ? 1.0 : -1.0;
          if (dl > 0.0) {
            arc[arc_count] = Point{p.x + insets[q] * sign * (d.y / dl), p.y - insets[q] * sign * (d.x / dl)};
            ++arc_count;
          }
        }
      }
    }
    // The boundary's visible arc is half of an ellipse (a projected circle)
    // tangent to both borders at the corners: see fit_boundary_arc().
    std::array<Point, 2> corner_px{};
    std::array<bool, 2> corner_ok{{false, false}};
    std::array<bool, 2> corner_fitted{{false, false}};
    std::array<int, 2> first_q{{-1, -1}};
    for (std::size_t side = 0U; side < 2U; ++side) {
      for (std::size_t q = 0U; q < kProfileInsets; ++q) {
        if (crossing_ok[side][q]) {
          first_q[side] = static_cast<int>(q);
          break;
        }
      }
    }
    if (e.borders[0].valid && e.borders[1].valid && first_q[0] >= 0 && first_q[1] >= 0 && arc_count >= 5U) {
      std::array<double, 2> t_corner{{crossing_t[0][static_cast<std::size_t>(first_q[0])],
                                      crossing_t[1][static_cast<std::size_t>(first_q[1])]}};
      // Local borders: the edge points around the boundary, fitted again (one
      // quadratic over the whole tube is too coarse at a corner's scale).
      std::array<Border, 2>& local = local_borders_;
      bool local_ok = true;
      for (std::size_t side = 0U; side < 2U; ++side) {
        const Border& global = e.borders[side];
        local[side] = Border{};
        const Point approx = global.curve.at(t_corner[side]);
        const double window = config_.local_border_window * 2.0 * half_width;
        // At an end boundary only the marker's side: beyond it the shaft or
        // the grasper has another radius.
        const Point dir = global.curve.derivative(t_corner[side]);
        const double dir_len = std::hypot(dir.x, dir.y);
        const double end_sign = !internal ? (j == in.first_marker ? 1.0 : -1.0) : 0.0;
        for (const EdgePoint& ep : global.points) {
          const double along = dir_len > 0.0 ? ((ep.pixel.x - approx.x) * dir.x + (ep.pixel.y - approx.y) * dir.y) / dir_len : 0.0;
          if (end_sign * along < -config_.end_margin_px) {
            continue;
          }
          if (std::hypot(ep.pixel.x - approx.x, ep.pixel.y - approx.y) <= window) {
            static_cast<void>(local[side].points.push_back(ep));  // same capacity as the global border
          }
        }
        if (local[side].points.size() < 6U ||
            !fit_bezier(local[side], config_.tukey_c, config_.irls_iterations, config_.irls_scale_iterations)) {
          local[side] = global;
        } else {
          double best = 1e30;
          double start = 0.5;
          for (int i = -4; i <= 24; ++i) {
            const Point q = local[side].curve.at(i / 20.0);
            const double d = std::hypot(q.x - approx.x, q.y - approx.y);
            if (d < best) {
              best = d;
              start = i / 20.0;
            }
          }
          t_corner[side] = nearest_t(local[side].curve, approx, start);
        }
        local_ok = local_ok && local[side].valid;
      }
      if (local_ok && fit_boundary_arc(local, arc.data(), arc_count, t_corner)) {
        for (std::size_t side = 0U; side < 2U; ++side) {
          const Point p = local[side].curve.at(t_corner[side]);
          const Point near = e.borders[side].curve.at(crossing_t[side][static_cast<std::size_t>(first_q[side])]);
          if (std::hypot(p.x - near.x, p.y - near.y) < 3.0 * half_width + 3.0) {
            corner_px[side] = p;
            corner_ok[side] = true;
            corner_fitted[side] = true;
          }
        }
      }
    }
    for (std::size_t side = 0U; side < 2U; ++side) {
      const Border& border = e.borders[side];
      const int fq = first_q[side];
      if (!border.valid || fq < 0) {
        continue;
      }
      if (!corner_ok[side]) {
        // One border only: the innermost crossing, extrapolated with the
        // tangency law t(d) ~ t0 + a sqrt(d) when a second one exists.
        const double t_near = crossing_t[side][static_cast<std::size_t>(fq)];
        corner_px[side] = border.curve.at(t_near);
        if (fq + 1 < static_cast<int>(kProfileInsets) && crossing_ok[side][static_cast<std::size_t>(fq) + 1U]) {
          const double d0 = std::sqrt(insets[static_cast<std::size_t>(fq)]);
          const double d1 = std::sqrt(insets[static_cast<std::size_t>(fq) + 1U]);
          const double t1 = crossing_t[side][static_cast<std::size_t>(fq) + 1U];
          corner_px[side] = border.curve.at(t_near - (t1 - t_near) * d0 / (d1 - d0));
        }
        corner_ok[side] = true;
      }
      const double conf = (strength[side] / static_cast<double>(kProfileInsets)) / 2.0 * (corner_fitted[side] ? 1.0 : 0.5);
      const double confidence = conf > 1.0 ? 1.0 : (conf < 0.0 ? 0.0 : conf);
      if (confidence < config_.min_corner_confidence) {
        continue;  // weak or unfitted: more often misplaced than not
      }
      const int k = 2 * j + static_cast<int>(side);
      Corner& c = e.corners[static_cast<std::size_t>(k)];
      c.found = true;
      c.pixel = corner_px[side];
      c.confidence = confidence;
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
