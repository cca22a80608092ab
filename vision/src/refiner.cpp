// The model-guided readings' geometry and the Refiner's image probes
// (refiner.hpp).
#include "refiner.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "robust_step.hpp"
#include "sampling.hpp"
#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

constexpr int kMaxArcSamples = 32;
constexpr int kMaxProfile = 96;       // along-tube profile points (1 px apart)
constexpr int kEdgeOffsets = 8;
constexpr double kEdgeOffsetsMm[kEdgeOffsets] = {-2.0, -1.5, -1.0, -0.5, 0.5, 1.0, 1.5, 2.0};
constexpr int kMaxEdgeProfile = 64;   // across profile points (0.5 px apart)
// The base's rim (Refiner::ridge): a ridge stands out against the samples
// kRimSidePx away (the rim is 1-3 px wide); the window reaches kRimReachMm
// along the tube, at least kRimMinReachPx, at most kRimMaxReachPx.
constexpr int kRimSidePx = 3;
constexpr double kRimReachMm = 0.3;
constexpr double kRimMinReachPx = 6.0;
constexpr int kRimMaxReachPx = 40;
constexpr int kRimMaxProfile = 2 * (kRimMaxReachPx + kRimSidePx) + 1;
// The silhouette's reading under a streak (Refiner::edge_across): the outer
// end of the gradient plateau, where it falls below kOuterEndShare of its
// peak, moved in by half the smear across (docs/vision.md).
constexpr double kOuterEndShare = 0.3;
constexpr double kOuterEndMarginPx = 2.0;  // the profile runs this far past window + smear / 2
constexpr int kMaxOuterEndProfile = 161;   // 0.5 px apart: +/- 40 px
// Or by the blurred edge's model (refine_streak_edge_model): its profile
// runs this far past the window and half the smear, so that both levels
// (the tube's shading inside, the tissue outside) are seen.
constexpr double kBlurredEdgeMarginPx = 4.0;

// The silhouette point of `side` from the limb points of two neighbouring
// circles (`at`, and `next` a little towards the tip) and the image of
// `at`'s centre: the point and its outward image normal (away from the
// centre). False when a limb point is missing.
bool silhouette_from(const solver::CircleLimbs& at, const solver::CircleLimbs& next, bool centre_ok,
                     const solver::Vec2& centre, std::size_t side, solver::Vec2& point, solver::Vec2& normal) noexcept {
  if (!at.present[side] || !next.present[side] || !centre_ok) {
    return false;
  }
  solver::Vec2 tangent = next.pixel[side] - at.pixel[side];
  if (!(tangent.norm() > 0.0)) {
    return false;
  }
  tangent.normalize();
  normal = solver::Vec2(-tangent.y(), tangent.x());
  if (normal.dot(at.pixel[side] - centre) < 0.0) {
    normal = -normal;
  }
  point = at.pixel[side];
  return true;
}

}  // namespace

int ceil_within(double v, int lo, int hi) noexcept {
  if (!(v > static_cast<double>(lo))) {
    return lo;
  }
  return v >= static_cast<double>(hi) ? hi : static_cast<int>(std::ceil(v));
}

BoundaryColours colours_of(const ExtractorConfig& config, int j) noexcept {
  BoundaryColours c;
  if (j > 0 && j < kNumBoundaries - 1) {
    c.usable = config.interpretation.marker_classes[static_cast<std::size_t>(j - 1)] !=
               config.interpretation.marker_classes[static_cast<std::size_t>(j)];
    c.want = config.interpretation.marker_classes[static_cast<std::size_t>(j - 1)] == PixelClass::Blue ? 1.0 : -1.0;
    return c;
  }
  const std::size_t m = (j == 0) ? 0U : static_cast<std::size_t>(kNumMarkers - 1);
  c.usable = config.interpretation.marker_classes[m] == PixelClass::Blue;  // only a blue end has a margin profile
  c.margin = true;
  c.want = (j == 0) ? 1.0 : -1.0;
  return c;
}

bool tip_face_visible(const solver::InstrumentModel& model, const solver::PoseFrames& f) noexcept {
  const solver::CentrelineFrame end = model.centreline(f, model.geometry().bend_length_mm);
  return -end.position.dot(end.tangent) > 0.0;  // the camera (origin) in front of the face
}

bool base_face_visible(const solver::InstrumentModel& model, const solver::PoseFrames& f) noexcept {
  const solver::CentrelineFrame base = model.centreline(f, 0.0);
  return base.position.dot(base.tangent) > 0.0;
}

bool silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                   const solver::PoseFrames& f, double s_mm, std::size_t side, solver::Vec2& point,
                   solver::Vec2& normal) noexcept {
  solver::Vec2 centre;
  const bool centre_ok = camera.project(model.centreline(f, s_mm).position, centre);
  return silhouette_from(model.limbs(camera, f, s_mm), model.limbs(camera, f, s_mm + kDsMm), centre_ok, centre, side,
                         point, normal);
}

bool grasper_silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const solver::PoseFrames& f, double beyond_mm, std::size_t side, solver::Vec2& point,
                           solver::Vec2& normal) noexcept {
  solver::Vec2 centre;
  const bool centre_ok = camera.project(model.grasper_frame(f, beyond_mm).position, centre);
  return silhouette_from(model.grasper_limbs(camera, f, beyond_mm), model.grasper_limbs(camera, f, beyond_mm + kDsMm),
                         centre_ok, centre, side, point, normal);
}

bool behind_tube_end(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                     const solver::PoseFrames& f, const solver::Vec2& p) noexcept {
  if (tip_face_visible(model, f)) {
    return false;  // the grasper runs towards the camera, in front of the tube
  }
  const solver::CentrelineFrame end = model.centreline(f, model.geometry().bend_length_mm);
  const double radius_mm = model.geometry().radius_mm;
  solver::Vec2 centre;
  solver::Vec2 along_normal;
  solver::Vec2 along_binormal;
  if (!camera.project(end.position, centre) || !camera.project(end.position + radius_mm * end.normal, along_normal) ||
      !camera.project(end.position + radius_mm * end.binormal, along_binormal)) {
    return true;  // not projectable: take it as hidden
  }
  const double radius_px = std::max((along_normal - centre).norm(), (along_binormal - centre).norm());
  return (p - centre).norm() < radius_px + 1.0;
}

bool shaft_silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                         const solver::PoseFrames& f, double back_mm, std::size_t side, solver::Vec2& point,
                         solver::Vec2& normal) noexcept {
  solver::Vec2 centre;
  const bool centre_ok = camera.project(model.shaft_frame(f, back_mm).position, centre);
  return silhouette_from(model.shaft_limbs(camera, f, back_mm), model.shaft_limbs(camera, f, back_mm - kDsMm),
                         centre_ok, centre, side, point, normal);
}

template <typename Read>
bool Refiner::median_arc_shift(double s_mm, double radius, double max_spread_mm, Read read, double& shift_mm) noexcept {
  const solver::CentrelineFrame cf = model_.centreline(frames_, s_mm);
  const solver::CentrelineFrame cf2 = model_.centreline(frames_, s_mm + kDsMm);
  double base = 0.0;
  double limb_half = 0.0;
  if (!solver::circle_limb_angles(cf, model_.geometry().radius_mm, base, limb_half)) {
    return false;
  }
  const double half = solver::kPi - limb_half;  // half the visible arc (facing the camera)
  const int n = std::min(std::max(config_.refiner.refine_arc_samples, 3), kMaxArcSamples);
  std::array<double, kMaxArcSamples> shifts{};
  int count = 0;
  for (int i = 0; i < n; ++i) {
    const double u = -config_.refiner.refine_arc_span + 2.0 * config_.refiner.refine_arc_span * i / static_cast<double>(n - 1);
    const double a = base + solver::kPi + u * half;
    const double ca = dmath::cos(a);
    const double sa = dmath::sin(a);
    const solver::Vec3 x = cf.position + radius * (ca * cf.normal + sa * cf.binormal);
    const solver::Vec3 x2 = cf2.position + radius * (ca * cf2.normal + sa * cf2.binormal);
    solver::Vec2 p;
    solver::Vec2 p2;
    if (!camera_.project(x, p) || !camera_.project(x2, p2)) {
      continue;
    }
    const solver::Vec2 d = (p2 - p) / kDsMm;  // px per mm along the tube
    const double px_per_mm = d.norm();
    if (!(px_per_mm > 0.5)) {
      continue;  // the tube seen end-on here
    }
    double tau_px = 0.0;
    if (read(p, solver::Vec2(d / px_per_mm), px_per_mm, tau_px)) {
      shifts[static_cast<std::size_t>(count++)] = tau_px / px_per_mm;
    }
  }
  if (count < 3 || count < config_.refiner.refine_min_arc_share * n) {
    return false;
  }
  const double mid = median_of(shifts.data(), count);
  std::array<double, kMaxArcSamples> dev{};
  for (int i = 0; i < count; ++i) {
    dev[static_cast<std::size_t>(i)] = std::fabs(shifts[static_cast<std::size_t>(i)] - mid);
  }
  if (median_of(dev.data(), count) > max_spread_mm) {
    return false;
  }
  shift_mm = mid;
  return true;
}

bool Refiner::arc_shift(double s_mm, const BoundaryColours& colours, double window_mm, double& shift_mm) noexcept {
  return median_arc_shift(
      s_mm, model_.geometry().radius_mm, config_.refiner.refine_max_spread_mm,
      [&](const solver::Vec2& p, const solver::Vec2& dir, double px_per_mm, double& tau_px) noexcept {
        return crossing(p, dir, window_mm * px_per_mm, colours, 1, tau_px) == Crossing::kSharp;
      },
      shift_mm);
}

bool Refiner::rim_shift(double radius, double& shift_mm) noexcept {
  return median_arc_shift(
      0.0, radius, config_.refiner.refine_base_rim_max_spread_mm,
      [&](const solver::Vec2& p, const solver::Vec2& dir, double px_per_mm, double& tau_px) noexcept {
        // The pose fitted to the image puts the base within a few pixels,
        // or 0.3 mm at a large scale.
        return ridge(p, dir, std::max(kRimMinReachPx, kRimReachMm * px_per_mm), tau_px);
      },
      shift_mm);
}

bool Refiner::silhouette_offset(double s_mm, std::size_t side, int j, double& offset_px) noexcept {
  const double length = model_.geometry().bend_length_mm;
  std::array<double, kEdgeOffsets> os{};
  std::array<double, kEdgeOffsets> es{};
  int count = 0;
  for (double o : kEdgeOffsetsMm) {
    const double s = s_mm + o;
    // The silhouette of the striped tube only: the shaft and the grasper
    // have other radii.
    if ((j == 0 && o < 0.0) || (j == kNumBoundaries - 1 && o > 0.0) || s < 0.0 || s > length) {
      continue;
    }
    solver::Vec2 point;
    solver::Vec2 normal;
    if (!silhouette_at(camera_, model_, frames_, s, side, point, normal)) {
      continue;
    }
    // Smeared across by the streak: the peak's centre is pulled towards
    // the darker side (docs/vision.md "The smear across the tube").
    if (std::fabs(streak_px_.dot(normal)) >= config_.refiner.refine_streak_across_px) {
      continue;
    }
    double e = 0.0;
    if (edge(point, normal, config_.refiner.refine_edge_search_px, e)) {
      os[static_cast<std::size_t>(count)] = o;
      es[static_cast<std::size_t>(count)] = e;
      ++count;
    }
  }
  if (count < config_.refiner.refine_min_edge_points) {
    return false;
  }
  // Line e = e0 + e1 o by least squares, once more without the points far
  // from the first line (a vessel's edge taken for the silhouette).
  double e0 = 0.0;
  double e1 = 0.0;
  std::array<bool, kEdgeOffsets> keep{};
  keep.fill(true);
  for (int pass = 0; pass < 2; ++pass) {
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, t0 = 0.0, t1 = 0.0;
    for (int i = 0; i < count; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (keep[k]) {
        s0 += 1.0;
        s1 += os[k];
        s2 += os[k] * os[k];
        t0 += es[k];
        t1 += os[k] * es[k];
      }
    }
    const double det = s0 * s2 - s1 * s1;
    if (s0 < static_cast<double>(config_.refiner.refine_min_edge_points) || !(std::fabs(det) > 1e-9)) {
      return false;
    }
    e0 = (t0 * s2 - t1 * s1) / det;
    e1 = (s0 * t1 - s1 * t0) / det;
    if (pass == 0) {
      for (int i = 0; i < count; ++i) {
        const auto k = static_cast<std::size_t>(i);
        keep[k] = std::fabs(es[k] - (e0 + e1 * os[k])) <= 1.0;
      }
    }
  }
  offset_px = e0;
  return std::fabs(offset_px) <= config_.refiner.refine_edge_search_px;
}

double Refiner::score(double x, double y, bool margin, bool& ok) const noexcept {
  Rgb px;
  ok = sample(image_, x, y, px);
  if (!ok) {
    return 0.0;
  }
  const std::uint8_t r8 = to_byte(px.r), g8 = to_byte(px.g), b8 = to_byte(px.b);
  return margin ? colors_.blue_margin(r8, g8, b8) : colors_.yellow_minus_blue(r8, g8, b8);
}

Crossing Refiner::crossing(const solver::Vec2& p, const solver::Vec2& dir, double window_px, const BoundaryColours& colours,
                           int clear_reach, double& tau_px) const noexcept {
  const int half = ceil_within(window_px, 3, (kMaxProfile - 1) / 2);
  const int n = 2 * half + 1;
  std::array<double, kMaxProfile> v{};
  for (int i = 0; i < n; ++i) {
    const double t = static_cast<double>(i - half);
    bool ok = false;
    v[static_cast<std::size_t>(i)] = colours.want * score(p.x() + t * dir.x(), p.y() + t * dir.y(), colours.margin, ok);
    if (!ok) {
      return Crossing::kNone;
    }
  }
  constexpr double kClear = 0.15;  // |profile| of a reading clearly on one side
  const int reach = std::min(std::max(clear_reach, 1), kMaxClearReach);
  double best_sharp = 0.0;
  double best_smeared = 0.0;
  bool found_sharp = false;
  bool found_smeared = false;
  for (int i = 2; i + 1 < n; ++i) {
    const double a = v[static_cast<std::size_t>(i - 1)];
    const double b = v[static_cast<std::size_t>(i)];
    if (!(a < 0.0 && b >= 0.0)) {
      continue;
    }
    bool clear_before = false;
    bool clear_after = false;
    bool sharp = false;
    for (int r = 1; r <= reach; ++r) {
      const int before = i - 1 - r;  // the pair (before, before + 1) ahead of the crossing
      const int after = i + r;       // the pair (after - 1, after) beyond it
      if (before >= 0) {
        const auto k = static_cast<std::size_t>(before);
        clear_before = clear_before || 0.5 * (v[k] + v[k + 1U]) < -kClear;
      }
      if (after < n) {
        const auto k = static_cast<std::size_t>(after);
        clear_after = clear_after || 0.5 * (v[k - 1U] + v[k]) > kClear;
      }
      sharp = sharp || (r == 1 && clear_before && clear_after);
    }
    if (!(clear_before && clear_after)) {
      continue;
    }
    const double t = static_cast<double>(i - 1 - half) + a / (a - b);
    double& best = sharp ? best_sharp : best_smeared;
    bool& found = sharp ? found_sharp : found_smeared;
    if (!found || std::fabs(t) < std::fabs(best)) {
      best = t;
      found = true;
    }
  }
  tau_px = found_sharp ? best_sharp : best_smeared;
  return found_sharp ? Crossing::kSharp : (found_smeared ? Crossing::kSmeared : Crossing::kNone);
}

bool Refiner::ridge(const solver::Vec2& p, const solver::Vec2& dir, double reach_px, double& tau_px) const noexcept {
  const int reach = ceil_within(reach_px, 0, kRimMaxReachPx);
  const int n = 2 * (reach + kRimSidePx) + 1;
  std::array<double, kRimMaxProfile> v{};
  for (int i = 0; i < n; ++i) {
    const double t = static_cast<double>(i - reach - kRimSidePx);
    Rgb px;
    if (!sample(image_, p.x() + t * dir.x(), p.y() + t * dir.y(), px)) {
      return false;
    }
    v[static_cast<std::size_t>(i)] = (0.299 * px.r + 0.587 * px.g + 0.114 * px.b) / 255.0;  // Rec. 601 luma
  }
  int best = -1;
  for (int i = kRimSidePx; i < n - kRimSidePx; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const double c = v[k];
    if (c < v[k - 1U] || c < v[k + 1U] ||
        c - std::max(v[k - static_cast<std::size_t>(kRimSidePx)], v[k + static_cast<std::size_t>(kRimSidePx)]) <
            config_.refiner.refine_base_rim_contrast) {
      continue;
    }
    if (best < 0 || std::abs(i - reach - kRimSidePx) < std::abs(best - reach - kRimSidePx)) {
      best = i;
    }
  }
  if (best < 0) {
    return false;
  }
  // The parabola's vertex through the maximum and its two neighbours.
  const auto k = static_cast<std::size_t>(best);
  const double curvature = v[k - 1U] - 2.0 * v[k] + v[k + 1U];
  const double vertex = std::fabs(curvature) > 1e-12 ? 0.5 * (v[k - 1U] - v[k + 1U]) / curvature : 0.0;
  tau_px = static_cast<double>(best - reach - kRimSidePx) + std::max(-0.5, std::min(0.5, vertex));
  return true;
}

bool Refiner::edge(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double& offset_px) const noexcept {
  constexpr double kStep = 0.5;
  const int half = std::min(ceil_within(window_px / kStep, 0, (kMaxEdgeProfile - 1) / 2) + 1,
                            (kMaxEdgeProfile - 1) / 2);
  const int n = 2 * half + 1;
  std::array<Rgb, kMaxEdgeProfile> c{};
  for (int i = 0; i < n; ++i) {
    const double t = kStep * static_cast<double>(i - half);
    if (!sample(image_, p.x() + t * normal.x(), p.y() + t * normal.y(), c[static_cast<std::size_t>(i)])) {
      return false;
    }
  }
  std::array<double, kMaxEdgeProfile> g{};
  int best = -1;
  for (int i = 1; i + 1 < n; ++i) {
    const Rgb& a = c[static_cast<std::size_t>(i - 1)];
    const Rgb& b = c[static_cast<std::size_t>(i) + 1U];
    g[static_cast<std::size_t>(i)] = (a.r - b.r) * (a.r - b.r) + (a.g - b.g) * (a.g - b.g) + (a.b - b.b) * (a.b - b.b);
    if (best < 0 || g[static_cast<std::size_t>(i)] > g[static_cast<std::size_t>(best)]) {
      best = i;
    }
  }
  if (best < 2 || best > n - 3) {
    return false;  // at the window's end: no maximum inside it
  }
  // The centre of the gradient's peak, not its maximum: the centroid of the
  // contiguous samples above kPeakShare of the maximum (g is the squared
  // colour difference: 0.3 is about 55 % of the peak's amplitude; 0.1 to
  // 0.7 measured on the lab and hard sets, docs/vision.md). On a sharp edge
  // it is the parabola's vertex within a few hundredths of a pixel; on an
  // edge smeared by motion blur (a box over 5-14 px: a flat gradient
  // plateau) the maximum falls anywhere on the plateau, its centre is the
  // edge at mid-exposure.
  constexpr double kPeakShare = 0.3;
  const double floor_g = kPeakShare * g[static_cast<std::size_t>(best)];
  int lo = best;
  int hi = best;
  while (lo > 1 && g[static_cast<std::size_t>(lo - 1)] >= floor_g) {
    --lo;
  }
  while (hi < n - 2 && g[static_cast<std::size_t>(hi) + 1U] >= floor_g) {
    ++hi;
  }
  if (lo <= 1 || hi >= n - 2) {
    return false;  // the peak runs into the window's end: its centre is unknown
  }
  double sum_w = 0.0;
  double sum_wi = 0.0;
  for (int i = lo; i <= hi; ++i) {
    const double w = g[static_cast<std::size_t>(i)] - floor_g;
    sum_w += w;
    sum_wi += w * static_cast<double>(i);
  }
  const double centre = sum_w > 0.0 ? sum_wi / sum_w : static_cast<double>(best);
  offset_px = kStep * (centre - static_cast<double>(half)) + config_.borders.edge_offset_px;
  return true;
}

bool Refiner::edge_across(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double half_width_px,
                          double& offset_px, bool& outer_end) const noexcept {
  const double across_px = std::fabs(streak_px_.dot(normal));
  outer_end = across_px > 0.0 && across_px >= config_.refiner.refine_streak_across_px;
  if (!outer_end) {
    return edge(p, normal, window_px, offset_px);
  }
  if (config_.refiner.refine_streak_edge_model && edge_scratch_ != nullptr && half_width_px > 1.0) {
    return edge_blurred(p, normal, window_px, across_px, half_width_px, offset_px);
  }
  return edge_outer_end(p, normal, window_px, across_px, offset_px);
}

bool Refiner::edge_blurred(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double across_px,
                           double half_width_px, double& offset_px) const noexcept {
  const double window = std::min(window_px, detail::kMaxBlurredEdgeWindowPx);
  const double reach_px = window + 0.5 * across_px + kBlurredEdgeMarginPx;
  detail::BlurredEdgeProfile profile;
  profile.half = ceil_within(reach_px / detail::kBlurredEdgeSampleStepPx, 2, (detail::kMaxBlurredEdgeSamples - 1) / 2);
  const detail::LinearLight& linear = detail::linear_light();
  for (int i = 0; i <= 2 * profile.half; ++i) {
    const double t = detail::kBlurredEdgeSampleStepPx * static_cast<double>(i - profile.half);
    Rgb q;
    if (!sample(image_, p.x() + t * normal.x(), p.y() + t * normal.y(), q)) {
      return false;
    }
    profile.rgb[static_cast<std::size_t>(i)] = {linear(q.r), linear(q.g), linear(q.b)};
  }
  detail::BlurredEdgeFit fit;
  if (!detail::fit_blurred_edge_and_smear(profile, across_px, config_.refiner.refine_streak_edge_smear_search_px,
                                          half_width_px, window, *edge_scratch_, fit)) {
    return false;
  }
  offset_px = fit.edge_px;
  return true;
}

bool Refiner::edge_outer_end(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double across_px,
                             double& offset_px) const noexcept {
  constexpr double kStep = 0.5;
  const double peak_reach_px = window_px + 0.5 * across_px;
  const int half = ceil_within((peak_reach_px + kOuterEndMarginPx) / kStep, 2, (kMaxOuterEndProfile - 1) / 2);
  const int n = 2 * half + 1;
  const detail::LinearLight& linear = detail::linear_light();
  std::array<std::array<double, 3>, kMaxOuterEndProfile> c{};
  for (int i = 0; i < n; ++i) {
    const double t = kStep * static_cast<double>(i - half);
    Rgb q;
    if (!sample(image_, p.x() + t * normal.x(), p.y() + t * normal.y(), q)) {
      return false;
    }
    c[static_cast<std::size_t>(i)] = {linear(q.r), linear(q.g), linear(q.b)};
  }
  std::array<double, kMaxOuterEndProfile> g{};
  int best = -1;
  for (int i = 1; i + 1 < n; ++i) {
    const auto& a = c[static_cast<std::size_t>(i - 1)];
    const auto& b = c[static_cast<std::size_t>(i) + 1U];
    const double dr = a[0] - b[0];
    const double dg = a[1] - b[1];
    const double db = a[2] - b[2];
    const auto k = static_cast<std::size_t>(i);
    g[k] = std::sqrt(dr * dr + dg * dg + db * db);
    if (std::fabs(kStep * static_cast<double>(i - half)) <= peak_reach_px &&
        (best < 0 || g[k] > g[static_cast<std::size_t>(best)])) {
      best = i;
    }
  }
  if (best < 0 || !(g[static_cast<std::size_t>(best)] > 0.0)) {
    return false;
  }
  const double level = kOuterEndShare * g[static_cast<std::size_t>(best)];
  int i = best;
  while (i + 2 < n && g[static_cast<std::size_t>(i) + 1U] >= level) {
    ++i;
  }
  if (i + 2 >= n) {
    return false;  // the plateau runs to the profile's end
  }
  const double above = g[static_cast<std::size_t>(i)];
  const double below = g[static_cast<std::size_t>(i) + 1U];
  const double end = static_cast<double>(i) + (above - level) / (above - below);
  offset_px = kStep * (end - static_cast<double>(half)) - 0.5 * across_px;
  return std::fabs(offset_px) <= window_px;
}

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
