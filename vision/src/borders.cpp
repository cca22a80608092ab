// Stage 3: the borders (borders.hpp; the paper's section 2.3).
#include <algorithm>
#include <cmath>
#include <new>

#include "bezier_fit.hpp"
#include "sampling.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/vision/borders.hpp"

namespace tcpest {
namespace vision {
namespace {

using detail::fit_bezier;
using detail::Rgb;
using detail::sample;

double dist2(const Rgb& a, const Rgb& b) noexcept {
  return (a.r - b.r) * (a.r - b.r) + (a.g - b.g) * (a.g - b.g) + (a.b - b.b) * (a.b - b.b);
}

// Stage 3's skeleton: the found markers' centroids in order, extended past
// both ends to cover the end boundaries, with the tube's half width (px)
// and the arc length (px) at each vertex.
struct Skeleton {
  std::array<Point, kNumMarkers + 2> poly{};
  std::array<double, kNumMarkers + 2> half_width{};
  std::array<double, kNumMarkers + 2> arc{};
  std::size_t markers = 0U;   // found markers: the vertices between the two ends
  std::size_t vertices = 0U;  // markers + 2
  double length = 0.0;

  // The point and the half width at arc length s (clamped to the skeleton).
  void point_at(double s, Point& p, double& w) const noexcept {
    s = s < 0.0 ? 0.0 : (s > length ? length : s);
    std::size_t seg = 0U;
    while (seg + 2U < vertices && arc[seg + 1U] < s) {
      ++seg;
    }
    const double span = arc[seg + 1U] - arc[seg];
    const double f = span > 0.0 ? (s - arc[seg]) / span : 0.0;
    p = Point{poly[seg].x + f * (poly[seg + 1U].x - poly[seg].x), poly[seg].y + f * (poly[seg + 1U].y - poly[seg].y)};
    w = half_width[seg] + f * (half_width[seg + 1U] - half_width[seg]);
  }
};

// The skeleton of the interpretation's found markers (Skeleton), each end
// extended by `extension` x its marker's extent along the skeleton. False
// with fewer than 2 found markers.
bool build_skeleton(const Interpretation& in, double extension, Skeleton& sk) noexcept {
  std::size_t count = 0U;
  for (int m = in.first_marker; m <= in.last_marker; ++m) {
    const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
    if (!obs.found) {
      continue;
    }
    sk.poly[count + 1U] = obs.region.centroid;
    ++count;
  }
  if (count < 2U) {
    return false;
  }
  auto& poly = sk.poly;
  const Region& first = in.markers[static_cast<std::size_t>(in.first_marker)].region;
  const Region& last = in.markers[static_cast<std::size_t>(in.last_marker)].region;
  double dx = poly[2].x - poly[1].x;
  double dy = poly[2].y - poly[1].y;
  double d = dmath::hypot(dx, dy);
  double reach = extension * first.extent_along(dx / d, dy / d);
  poly[0] = Point{poly[1].x - dx / d * reach, poly[1].y - dy / d * reach};
  dx = poly[count].x - poly[count - 1U].x;
  dy = poly[count].y - poly[count - 1U].y;
  d = dmath::hypot(dx, dy);
  reach = extension * last.extent_along(dx / d, dy / d);
  poly[count + 1U] = Point{poly[count].x + dx / d * reach, poly[count].y + dy / d * reach};
  sk.markers = count;
  sk.vertices = count + 2U;
  // Half width of the tube at each vertex: the marker region's extent across
  // the skeleton.
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
    const double tl = dmath::hypot(tx, ty);
    tx /= tl;
    ty /= tl;
    // The equivalent ellipse's extent understates a rectangle's half width
    // by sqrt(3)/2.
    sk.half_width[v] = obs.region.extent_along(-ty, tx) * 0.866;
    ++v;
  }
  sk.half_width[0] = sk.half_width[1];
  sk.half_width[sk.vertices - 1U] = sk.half_width[sk.vertices - 2U];
  for (std::size_t i = 1U; i < sk.vertices; ++i) {
    sk.arc[i] = sk.arc[i - 1U] + dmath::hypot(poly[i].x - poly[i - 1U].x, poly[i].y - poly[i - 1U].y);
  }
  sk.length = sk.arc[sk.vertices - 1U];
  return true;
}

// The labelled region's boundary from p along the unit normal (nx, ny): the
// last classified pixel before the background, searched outwards up to
// r_max px (-1: none).
double region_edge_along(const std::uint8_t* classes, int width, int height, const Point& p, double nx, double ny,
                         double r_max) noexcept {
  double region_edge = -1.0;
  const int region_steps = static_cast<int>(r_max);
  for (int step = 0; step <= region_steps; ++step) {
    const double r = static_cast<double>(step);
    const int xi = static_cast<int>(std::lround(p.x + r * nx));
    const int yi = static_cast<int>(std::lround(p.y + r * ny));
    if (xi < 0 || yi < 0 || xi >= width || yi >= height) {
      break;
    }
    if (classes[static_cast<std::size_t>(yi) * static_cast<std::size_t>(width) + static_cast<std::size_t>(xi)] != 0U) {
      region_edge = r;
    } else if (region_edge >= 0.0 && r > region_edge + 2.0) {
      break;
    }
  }
  return region_edge;
}

// The border's distance (px) from p along the unit normal n = (nx, ny) (t =
// (tx, ty) along the skeleton): the strongest local maximum of the colour
// gradient's magnitude along n within [r0, r1], sampled 0.5 px apart, where
// the gradient agrees with n (3 times its square across) and lies within 3
// px of region_edge (when >= 0); refined to a sub-sample by a parabola.
// False when there is none of magnitude 8 or more.
bool gradient_edge(const ImageView& image, const Point& p, double nx, double ny, double tx, double ty, double r0,
                   double r1, double region_edge, double& r_edge) noexcept {
  constexpr double kStep = 0.5;
  double best = 0.0;
  double best_r = -1.0;
  double prev_g = 0.0, prev_prev_g = 0.0;
  double peak_left = 0.0, peak_right = 0.0;
  bool have_prev = false;
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
    return false;
  }
  const double denom = peak_left - 2.0 * best + peak_right;
  double offset = 0.0;
  if (denom < 0.0) {
    offset = 0.5 * (peak_left - peak_right) / denom;
    offset = offset > 0.5 ? 0.5 : (offset < -0.5 ? -0.5 : offset);
  }
  r_edge = best_r + offset * kStep;
  return true;
}

}  // namespace

Result<std::unique_ptr<BorderFitter>, VisionError> BorderFitter::create(const BordersConfig& config) noexcept {
  using R = Result<std::unique_ptr<BorderFitter>, VisionError>;
  if (config.skeleton_samples < 8 || config.skeleton_samples > static_cast<int>(kMaxSkeletonSamples) ||
      config.irls_iterations < 1 || config.irls_iterations > 50 || config.irls_scale_iterations < 1 ||
      config.irls_scale_iterations > config.irls_iterations || !(config.tukey_c > 0.0)) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<BorderFitter> fitter(new (std::nothrow) BorderFitter());
  if (fitter == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  fitter->config_ = config;
  return R::success(std::move(fitter));
}

Status<VisionError> BorderFitter::fit(const ImageView& image, const ClassImage& classes, const Interpretation& in,
                                      std::array<Border, 2>& borders, std::array<Point, kMaxSkeletonSamples>& skeleton,
                                      int& skeleton_count) const noexcept {
  skeleton_count = 0;
  borders[0] = Border{};
  borders[1] = Border{};
  if (in.found_count < 2 || !image.valid() || classes.data == nullptr || image.width != classes.width ||
      image.height != classes.height) {
    return Status<VisionError>::failure(VisionError::BorderFitFailed);
  }
  const int width = classes.width;
  const int height = classes.height;
  Skeleton sk;
  if (!build_skeleton(in, config_.skeleton_extension, sk)) {
    return Status<VisionError>::failure(VisionError::BorderFitFailed);
  }
  const int samples = config_.skeleton_samples;
  const double smoothing = 0.5 * sk.length / static_cast<double>(sk.markers + 1U);
  for (int i = 0; i < samples; ++i) {
    const double s = (static_cast<double>(i) + 0.5) * sk.length / static_cast<double>(samples);
    Point p, pa, pb;
    double w = 0.0, wa = 0.0, wb = 0.0;
    sk.point_at(s, p, w);
    sk.point_at(s - smoothing, pa, wa);
    sk.point_at(s + smoothing, pb, wb);
    double tx = pb.x - pa.x;
    double ty = pb.y - pa.y;
    const double tl = dmath::hypot(tx, ty);
    if (!(tl > 0.0) || !(w > 0.5)) {
      continue;
    }
    tx /= tl;
    ty /= tl;
    if (skeleton_count < static_cast<int>(kMaxSkeletonSamples)) {
      skeleton[static_cast<std::size_t>(skeleton_count)] = p;
      ++skeleton_count;
    }
    // Side 1 (right, model.md) lies along (-ty, tx) in pixel coordinates.
    for (int side = 0; side < 2; ++side) {
      const double nx = side == 1 ? -ty : ty;
      const double ny = side == 1 ? tx : -tx;
      const double r_max = config_.edge_search_max * w + 2.0;
      const double region_edge = region_edge_along(classes.data, width, height, p, nx, ny, r_max);
      // Near the labelled region's boundary when there is one, else the
      // whole window.
      double r0 = config_.edge_search_min * w;
      double r1 = r_max;
      if (region_edge >= 0.0) {
        r0 = std::max(r0, region_edge - 3.5);
        r1 = std::min(r1, region_edge + 3.5);
      }
      double r_edge = 0.0;
      if (!gradient_edge(image, p, nx, ny, tx, ty, r0, r1, region_edge, r_edge)) {
        continue;
      }
      r_edge += config_.edge_offset_px;
      static_cast<void>(borders[static_cast<std::size_t>(side)].points.push_back(
          EdgePoint{Point{p.x + r_edge * nx, p.y + r_edge * ny}, 1.0, 0.0}));  // capacity = max samples
    }
  }
  bool ok = true;
  for (std::size_t side = 0U; side < 2U; ++side) {
    if (!fit_bezier(borders[side], config_.tukey_c, config_.irls_iterations, config_.irls_scale_iterations)) {
      ok = false;
    }
  }
  if (!ok && !borders[0].valid && !borders[1].valid) {
    return Status<VisionError>::failure(VisionError::BorderFitFailed);
  }
  return ok_status<VisionError>();
}

}  // namespace vision
}  // namespace tcpest
