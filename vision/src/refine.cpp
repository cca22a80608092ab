// Model-guided corners: the apparent corners re-measured around a first pose.
//
// Stage 4 reads each corner from the image alone, where the boundary's
// ellipse touches the silhouette, often with a flat contact: the position
// along the border is ill-conditioned there, and at the two end boundaries
// (shaft, grasper) the chroma change is weak. Given a first pose, the model
// predicts the shape of every boundary's image (an ellipse arc) and of the
// silhouette next to it; two quantities remain to be read from the image,
// each where it is well conditioned:
// - along the tube: the shift of the boundary's circle that puts its visible
//   arc on the colour change. Every arc point gives one reading, across a
//   strong colour edge (the median of up to refine_arc_samples readings);
// - across: the silhouette's offset, read on the colour-gradient maximum
//   along its normal at 8 points beside the corner (a line fitted to the
//   offsets against the arc length, taken at the corner).
// The corner is the limb point of the shifted circle, moved by that offset.
#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "blurred_edge.hpp"
#include "robust_step.hpp"
#include "sampling.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

using detail::Rgb;
using detail::sample;
using detail::to_byte;
using detail::median_of;
using detail::RobustNormalEquations;
using detail::tukey_cut_px;

constexpr double kDsMm = 1e-3;        // finite difference along the tube
constexpr int kMaxArcSamples = 32;
constexpr int kMaxProfile = 96;       // along-tube profile points (1 px apart)
constexpr int kMaxClearReach = 8;     // a crossing's clear colours at most this many samples away
// refine_streak_arc_retry widens an arc's reading where the smear along its
// normal is this long or longer (shorter: the sharp reading's reach holds).
constexpr double kStreakArcMinAlongPx = 3.0;
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

// Motion blur's streak from the boundary arcs (read_streak, docs/vision.md
// "The smear from the arcs"). Each stripe boundary is a sharp colour change
// between surfaces shaded alike, so the width of its change along an arc
// point's image normal n is the streak's length along n: w^2 = (b . n)^2 +
// kStreakSharpWidthPx^2 (the width of a sharp change: JPEG chroma and
// optics). The normals turn along a visible arc, so the arcs of the four
// stripe boundaries give b b^T by linear least squares.
constexpr int kStreakArcPoints = 16;         // per boundary, over kStreakArcSpan of the visible half arc
constexpr double kStreakArcSpan = 0.9;
constexpr int kStreakReachPx = 22;           // profile along the normal, +/- (a 14 px streak's change fits)
constexpr int kStreakProfile = 2 * kStreakReachPx + 3;
constexpr int kStreakPeakSearchPx = 6;       // the change's peak within +/- this of the model's arc
constexpr double kStreakMinPeak = 0.01;      // linear-light contrast per px below which no width is read
constexpr double kStreakLobeShare = 0.1;     // the peak's main lobe: contiguous samples above this share
constexpr double kStreakSharpWidthPx = 5.8;  // measured on the sharp hard frames (docs/vision.md)
// A smear across the tube shows in the silhouette's width instead: across
// the middle of each blue stripe, where the tube's linear red is near 0
// whatever its shading and the tissue's is high, the red step's width is
// the smear along the silhouette's normal. Its width on a sharp frame
// (the JPEG's luma is full resolution) is the median over the sharp hard
// frames' blue stripes (docs/vision.md "The smear across the tube").
constexpr double kStreakSilhouetteSharpWidthPx = 2.7;
constexpr int kMaxStreakArcWidths = (kNumBoundaries - 2) * kStreakArcPoints;
constexpr int kMaxStreakWidths = kMaxStreakArcWidths + 2 * kNumMarkers;
constexpr int kMinStreakWidths = 8;
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

// ceil(v) as an int within [lo, hi]: clamped before the cast (a window
// from a projection next to the camera can be huge, or NaN: lo).
int ceil_within(double v, int lo, int hi) noexcept {
  if (!(v > static_cast<double>(lo))) {
    return lo;
  }
  return v >= static_cast<double>(hi) ? hi : static_cast<int>(std::ceil(v));
}

// What a colour-change reading found (Refiner::crossing).
enum class Crossing : std::uint8_t { kNone, kSharp, kSmeared };

// How the colour changes across boundary j, base -> tip.
struct BoundaryColours {
  bool usable = false;
  bool margin = false;    // blue against neutral (shaft, grasper) instead of yellow - blue
  double want = 0.0;      // sign of the profile's change from base to tip
};

BoundaryColours colours_of(const ExtractorConfig& config, int j) noexcept {
  BoundaryColours c;
  if (j > 0 && j < kNumBoundaries - 1) {
    c.usable = config.marker_classes[static_cast<std::size_t>(j - 1)] !=
               config.marker_classes[static_cast<std::size_t>(j)];
    c.want = config.marker_classes[static_cast<std::size_t>(j - 1)] == PixelClass::Blue ? 1.0 : -1.0;
    return c;
  }
  const std::size_t m = (j == 0) ? 0U : static_cast<std::size_t>(kNumMarkers - 1);
  c.usable = config.marker_classes[m] == PixelClass::Blue;  // only a blue end has a margin profile
  c.margin = true;
  c.want = (j == 0) ? 1.0 : -1.0;
  return c;
}

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

// True when the tip's end face (the last stripe's, between the grasper's
// radius and the tube's, facing along the tube) is turned towards the
// camera: the colour change at the tip boundary is then the grasper's
// outline on that face, not the boundary's circle.
bool tip_face_visible(const solver::InstrumentModel& model, const solver::PoseFrames& f) noexcept {
  const solver::CentrelineFrame end = model.centreline(f, model.geometry().bend_length_mm);
  return -end.position.dot(end.tangent) > 0.0;  // the camera (origin) in front of the face
}

// True when the base's end face (the first stripe's, between the shaft's
// radius and the tube's, facing back along the tube) is turned towards the
// camera: the camera behind the plane at s = 0.
bool base_face_visible(const solver::InstrumentModel& model, const solver::PoseFrames& f) noexcept {
  const solver::CentrelineFrame base = model.centreline(f, 0.0);
  return base.position.dot(base.tangent) > 0.0;
}

// The model's silhouette point of `side` at arc length s and its outward
// image normal; false when the model gives no limb point there.
bool silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                   const solver::PoseFrames& f, double s_mm, std::size_t side, solver::Vec2& point,
                   solver::Vec2& normal) noexcept {
  solver::Vec2 centre;
  const bool centre_ok = camera.project(model.centreline(f, s_mm).position, centre);
  return silhouette_from(model.limbs(camera, f, s_mm), model.limbs(camera, f, s_mm + kDsMm), centre_ok, centre, side,
                         point, normal);
}

// The same for the grasper's silhouette `beyond_mm` past the tip.
bool grasper_silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const solver::PoseFrames& f, double beyond_mm, std::size_t side, solver::Vec2& point,
                           solver::Vec2& normal) noexcept {
  solver::Vec2 centre;
  const bool centre_ok = camera.project(model.grasper_frame(f, beyond_mm).position, centre);
  return silhouette_from(model.grasper_limbs(camera, f, beyond_mm), model.grasper_limbs(camera, f, beyond_mm + kDsMm),
                         centre_ok, centre, side, point, normal);
}

// True when the image point p lies behind the tube's end: the tip's face
// turned away from the camera (the grasper runs away from it) and p within
// the image of the tube's circle at s = L (its centre's image and the
// larger image of a radius there, +1 px). The grasper's silhouette there is
// hidden by the tube; what lies there is the tube's own edge.
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

// The same for the shaft's silhouette `back_mm` before the base.
bool shaft_silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                         const solver::PoseFrames& f, double back_mm, std::size_t side, solver::Vec2& point,
                         solver::Vec2& normal) noexcept {
  solver::Vec2 centre;
  const bool centre_ok = camera.project(model.shaft_frame(f, back_mm).position, centre);
  return silhouette_from(model.shaft_limbs(camera, f, back_mm), model.shaft_limbs(camera, f, back_mm - kDsMm),
                         centre_ok, centre, side, point, normal);
}

class Refiner {
 public:
  // `edge_scratch`: the blurred edge's model's tables (the extractor's);
  // without them the silhouette under a streak is read at the outer end.
  Refiner(const ImageView& image, const ColorModel& colors, const ExtractorConfig& config,
          const solver::CameraModel& camera, const solver::InstrumentModel& model, const solver::PoseFrames& frames,
          detail::BlurredEdgeScratch* edge_scratch) noexcept
      : image_(image), colors_(colors), config_(config), camera_(camera), model_(model), frames_(frames),
        edge_scratch_(edge_scratch) {}

  const ImageView& image() const noexcept { return image_; }

  // The motion-blur streak (px, image; zero: none) under which the
  // silhouette is read by edge_across.
  void use_streak(const solver::Vec2& streak_px) noexcept { streak_px_ = streak_px; }
  bool has_streak() const noexcept { return streak_px_.squaredNorm() > 0.0; }

  // Median shift (mm along the tube) that puts the visible arc of the
  // circle at s on the colour change; false when too few arc points see it.
  bool arc_shift(double s_mm, const BoundaryColours& colours, double window_mm, double& shift_mm) noexcept {
    return median_arc_shift(
        s_mm, model_.geometry().radius_mm, config_.refine_max_spread_mm,
        [&](const solver::Vec2& p, const solver::Vec2& dir, double px_per_mm, double& tau_px) noexcept {
          return crossing(p, dir, window_mm * px_per_mm, colours, 1, tau_px) == Crossing::kSharp;
        },
        shift_mm);
  }

  // Shift (mm along the tube) of the base's rim (its end face, seen as a
  // thin bright ring: ExtractorConfig::refine_base_rim) from the model's,
  // read on the ring of `radius` at s = 0; false when too few arc points
  // see it or they spread.
  bool rim_shift(double radius, double& shift_mm) noexcept {
    return median_arc_shift(
        0.0, radius, config_.refine_base_rim_max_spread_mm,
        [&](const solver::Vec2& p, const solver::Vec2& dir, double px_per_mm, double& tau_px) noexcept {
          // The pose fitted to the image puts the base within a few pixels,
          // or 0.3 mm at a large scale.
          return ridge(p, dir, std::max(kRimMinReachPx, kRimReachMm * px_per_mm), tau_px);
        },
        shift_mm);
  }

  // The median over the visible arc of the tube's circle at s (the points
  // taken on the ring of `radius` there) of what `read(p, dir, px_per_mm,
  // tau_px)` finds along the tube (dir, unit) from each point p, as a shift
  // in mm; false when fewer than 3 or refine_min_arc_share of the points
  // read, or their MAD exceeds max_spread_mm.
  template <typename Read>
  bool median_arc_shift(double s_mm, double radius, double max_spread_mm, Read read, double& shift_mm) noexcept {
    const solver::CentrelineFrame cf = model_.centreline(frames_, s_mm);
    const solver::CentrelineFrame cf2 = model_.centreline(frames_, s_mm + kDsMm);
    double base = 0.0;
    double limb_half = 0.0;
    if (!solver::circle_limb_angles(cf, model_.geometry().radius_mm, base, limb_half)) {
      return false;
    }
    const double half = solver::kPi - limb_half;  // half the visible arc (facing the camera)
    const int n = std::min(std::max(config_.refine_arc_samples, 3), kMaxArcSamples);
    std::array<double, kMaxArcSamples> shifts{};
    int count = 0;
    for (int i = 0; i < n; ++i) {
      const double u = -config_.refine_arc_span + 2.0 * config_.refine_arc_span * i / static_cast<double>(n - 1);
      const double a = base + solver::kPi + u * half;
      const double ca = std::cos(a);
      const double sa = std::sin(a);
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
    if (count < 3 || count < config_.refine_min_arc_share * n) {
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

  // Offset (px, outwards) of the silhouette from the model's beside the
  // corner of `side` of the circle at s; false with too few readings.
  bool silhouette_offset(double s_mm, std::size_t side, int j, double& offset_px) noexcept {
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
      if (std::fabs(streak_px_.dot(normal)) >= config_.refine_streak_across_px) {
        continue;
      }
      double e = 0.0;
      if (edge(point, normal, config_.refine_edge_search_px, e)) {
        os[static_cast<std::size_t>(count)] = o;
        es[static_cast<std::size_t>(count)] = e;
        ++count;
      }
    }
    if (count < config_.refine_min_edge_points) {
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
      if (s0 < static_cast<double>(config_.refine_min_edge_points) || !(std::fabs(det) > 1e-9)) {
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
    return std::fabs(offset_px) <= config_.refine_edge_search_px;
  }

  // (public below: used by the pose fit)
  double score(double x, double y, bool margin, bool& ok) const noexcept {
    Rgb px;
    ok = sample(image_, x, y, px);
    if (!ok) {
      return 0.0;
    }
    const std::uint8_t r8 = to_byte(px.r), g8 = to_byte(px.g), b8 = to_byte(px.b);
    return margin ? colors_.blue_margin(r8, g8, b8) : colors_.yellow_minus_blue(r8, g8, b8);
  }

  // The colour change along `dir` through p nearest to p (px, signed),
  // between readings that are clearly on each side: the mean of two
  // neighbouring samples. A sharp change is clear at the very next pair on
  // each side; a smeared one only within `clear_reach` pairs (1: sharp
  // changes only). The nearest sharp change if there is one, else the
  // nearest smeared one.
  Crossing crossing(const solver::Vec2& p, const solver::Vec2& dir, double window_px, const BoundaryColours& colours,
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

  // The lightness ridge along `dir` through p nearest to p (px, signed,
  // sub-pixel), within reach_px: a local maximum standing
  // refine_base_rim_contrast above the samples kRimSidePx on either side.
  bool ridge(const solver::Vec2& p, const solver::Vec2& dir, double reach_px, double& tau_px) const noexcept {
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
              config_.refine_base_rim_contrast) {
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

  // The colour-gradient maximum along `normal` through p (px from p,
  // outwards positive), moved by the shading correction of stage 3.
  bool edge(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double& offset_px) const noexcept {
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
    offset_px = kStep * (centre - static_cast<double>(half)) + config_.edge_offset_px;
    return true;
  }

  // The silhouette's reading under the streak: where the smear across the
  // normal, |streak . normal|, reaches refine_streak_across_px, the outer
  // end of the gradient's plateau (outer_end); else edge(). A smear of 5 px
  // (the default) and more flattens the gradient's peak into a plateau as wide as the
  // smear, whose centre the tube's shading pulls inwards and whose ends
  // often lie beyond edge()'s window (docs/vision.md).
  bool edge_across(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double half_width_px,
                   double& offset_px, bool& outer_end) const noexcept {
    const double across_px = std::fabs(streak_px_.dot(normal));
    outer_end = across_px > 0.0 && across_px >= config_.refine_streak_across_px;
    if (!outer_end) {
      return edge(p, normal, window_px, offset_px);
    }
    if (config_.refine_streak_edge_model && edge_scratch_ != nullptr && half_width_px > 1.0) {
      return edge_blurred(p, normal, window_px, across_px, half_width_px, offset_px);
    }
    return edge_outer_end(p, normal, window_px, across_px, offset_px);
  }

  // The silhouette at mid-exposure by the blurred edge's model
  // (detail::fit_blurred_edge): the linear-light profile along `normal`
  // through p, over the window, half the smear across and a margin for the
  // levels on both sides; px from p, outwards positive.
  bool edge_blurred(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double across_px,
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
    if (!detail::fit_blurred_edge_and_smear(profile, across_px, config_.refine_streak_edge_smear_search_px,
                                            half_width_px, window, *edge_scratch_, fit)) {
      return false;
    }
    offset_px = fit.edge_px;
    return true;
  }

  // The outer end of the linear-light colour gradient's plateau along
  // `normal` through p (where it falls below kOuterEndShare of its peak on
  // the tissue's side, which the tube's shading does not reach), moved in
  // by half the smear across: the silhouette at mid-exposure, px from p,
  // outwards positive. The peak is looked for within window_px + half the
  // smear; false when the plateau runs to the profile's end or the result
  // lies beyond window_px.
  bool edge_outer_end(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double across_px,
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

 private:
  const ImageView& image_;
  const ColorModel& colors_;
  const ExtractorConfig& config_;
  const solver::CameraModel& camera_;
  const solver::InstrumentModel& model_;
  const solver::PoseFrames& frames_;
  solver::Vec2 streak_px_ = solver::Vec2::Zero();
  detail::BlurredEdgeScratch* edge_scratch_;
};


// Whose silhouette a pose-fit reading is on, and what its s_mm measures.
enum class Part : std::uint8_t {
  kTube,     // the striped section: arc length from the base
  kShaft,    // the shaft: distance before the base
  kGrasper,  // the grasper: distance past the tip
};

// The pose fit's readings: a point of the model (a boundary arc's point or
// a silhouette point), the image direction it is read along, and the offset
// (px) of the image's edge from it along that direction.
struct Reading {
  bool arc = false;
  int boundary = 0;
  double angle_rad = 0.0;   // arc: the point's angle on the circle
  Part part = Part::kTube;  // silhouette: whose
  double s_mm = 0.0;        // silhouette: where along that part (Part)
  std::size_t side = 0U;    // silhouette: side
  solver::Vec2 direction = solver::Vec2::Zero();
  double offset_px = 0.0;
};

constexpr int kFitArcSamples = 12;        // per boundary
constexpr int kFitSilhouetteSamples = 10; // per side
// The shaft's silhouette just before the base (1 to 8.5 mm): it fixes the
// channel axis in the image, which the base boundary's corners (never read
// directly: docs/vision.md) depend on.
constexpr int kFitShaftSamples = 6;
constexpr double kFitShaftFirstMm = 1.0;
constexpr double kFitShaftStepMm = 1.5;
// The grasper's silhouette 2 to 9.5 mm past the tip: it holds the tip's
// direction where an occluder or a smear hides the stripes. Not nearer:
// within 1-2 mm of the tip the wider tube's end beside it is read instead.
constexpr int kFitGrasperSamples = 6;
constexpr double kFitGrasperFirstMm = 2.0;
constexpr double kFitGrasperStepMm = 1.5;
constexpr int kMaxReadings = kNumBoundaries * kFitArcSamples + 2 * kFitSilhouetteSamples + 2 * kFitShaftSamples +
                             2 * kFitGrasperSamples;
constexpr int kMaxSmearedReadings = kNumBoundaries * kFitArcSamples;
constexpr int kMaxFitIterations = 20;
constexpr int kCoarseIterations = 3;  // wide-window iterations from a coarse start

// Where a reading's model point is at the frames f.
// `boundary_frames`: the centreline frame at every boundary for f.
bool predict(const solver::CameraModel& camera, const solver::InstrumentModel& model, const solver::PoseFrames& f,
             const std::array<solver::CentrelineFrame, kNumBoundaries>& boundary_frames, const Reading& reading,
             solver::Vec2& pixel) noexcept {
  if (reading.arc) {
    const solver::CentrelineFrame& cf = boundary_frames[static_cast<std::size_t>(reading.boundary)];
    const solver::Vec3 x = cf.position + model.geometry().radius_mm * (std::cos(reading.angle_rad) * cf.normal +
                                                                        std::sin(reading.angle_rad) * cf.binormal);
    return camera.project(x, pixel);
  }
  solver::CircleLimbs limbs;
  switch (reading.part) {
    case Part::kTube: limbs = model.limbs(camera, f, reading.s_mm); break;
    case Part::kShaft: limbs = model.shaft_limbs(camera, f, reading.s_mm); break;
    case Part::kGrasper: limbs = model.grasper_limbs(camera, f, reading.s_mm); break;
  }
  pixel = limbs.pixel[reading.side];
  return limbs.present[reading.side];
}

// The squared width (px^2) of the colour change across the arc point p
// along the unit image normal n: the linear-light blue minus the mean of red and green
// over +/- kStreakReachPx, its derivative's peak within kStreakPeakSearchPx
// of p and that peak's main lobe (the contiguous samples above
// kStreakLobeShare of it); the width of a box of the lobe's variance,
// sqrt(12 var). False when the change is faint, the lobe reaches the
// profile's end or a sample lies outside the image.
// What change_width reads along the normal: a stripe boundary's chroma
// change, or the red step at a blue stripe's silhouette.
enum class ChangeProfile : std::uint8_t { kStripeChroma, kRed };

bool change_width(const ImageView& image, const solver::Vec2& p, const solver::Vec2& n, ChangeProfile profile,
                  double& width_sq_px2) noexcept {
  const detail::LinearLight& linear = detail::linear_light();
  std::array<double, kStreakProfile> f{};
  for (int k = 0; k < kStreakProfile; ++k) {
    const double t = static_cast<double>(k - kStreakReachPx - 1);
    Rgb q;
    if (!sample(image, p.x() + t * n.x(), p.y() + t * n.y(), q)) {
      return false;
    }
    f[static_cast<std::size_t>(k)] =
        profile == ChangeProfile::kRed ? linear(q.r) : linear(q.b) - 0.5 * (linear(q.r) + linear(q.g));
  }
  constexpr int kSlopes = 2 * kStreakReachPx + 1;
  std::array<double, kSlopes> d{};  // d[k]: the slope at t = k - kStreakReachPx
  for (int k = 0; k < kSlopes; ++k) {
    d[static_cast<std::size_t>(k)] = 0.5 * (f[static_cast<std::size_t>(k) + 2U] - f[static_cast<std::size_t>(k)]);
  }
  int peak = kStreakReachPx;
  for (int k = kStreakReachPx - kStreakPeakSearchPx; k <= kStreakReachPx + kStreakPeakSearchPx; ++k) {
    if (std::fabs(d[static_cast<std::size_t>(k)]) > std::fabs(d[static_cast<std::size_t>(peak)])) {
      peak = k;
    }
  }
  const double sign = d[static_cast<std::size_t>(peak)] > 0.0 ? 1.0 : -1.0;
  const double top = sign * d[static_cast<std::size_t>(peak)];
  if (!(top >= kStreakMinPeak)) {
    return false;
  }
  const double floor_slope = kStreakLobeShare * top;
  int lo = peak;
  int hi = peak;
  while (lo > 0 && sign * d[static_cast<std::size_t>(lo) - 1U] >= floor_slope) {
    --lo;
  }
  while (hi < kSlopes - 1 && sign * d[static_cast<std::size_t>(hi) + 1U] >= floor_slope) {
    ++hi;
  }
  if (lo == 0 || hi == kSlopes - 1) {
    return false;
  }
  double sum = 0.0;
  double first = 0.0;
  for (int k = lo; k <= hi; ++k) {
    const double w = sign * d[static_cast<std::size_t>(k)];
    sum += w;
    first += w * static_cast<double>(k);
  }
  const double mean = first / sum;
  double second = 0.0;
  for (int k = lo; k <= hi; ++k) {
    const double off = static_cast<double>(k) - mean;
    second += sign * d[static_cast<std::size_t>(k)] * off * off;
  }
  width_sq_px2 = 12.0 * second / sum;
  return true;
}

// The widths the streak is read from: per width, the row (nx^2, 2 nx ny,
// ny^2) of its normal and its excess w^2 - the sharp width^2 (px^2).
struct StreakWidths {
  std::array<Eigen::Vector3d, kMaxStreakWidths> rows{};
  std::array<double, kMaxStreakWidths> excess{};
  int count = 0;

  void add(const solver::Vec2& n, double width_sq, double sharp_px) noexcept {
    const auto k = static_cast<std::size_t>(count++);
    rows[k] = Eigen::Vector3d(n.x() * n.x(), 2.0 * n.x() * n.y(), n.y() * n.y());
    excess[k] = width_sq - sharp_px * sharp_px;
  }
};

// The colour changes' widths across the inner boundaries' visible arcs
// (kStreakArcPoints per boundary).
void arc_widths(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                const solver::InstrumentModel& model, const solver::PoseFrames& f, StreakWidths& widths) noexcept {
  const auto& g = model.geometry();
  for (int j = 1; j < kNumBoundaries - 1; ++j) {
    if (!colours_of(config, j).usable) {
      continue;
    }
    const solver::CentrelineFrame cf = model.centreline(f, g.boundaries_mm[static_cast<std::size_t>(j)]);
    double base = 0.0;
    double limb_half = 0.0;
    if (!solver::circle_limb_angles(cf, g.radius_mm, base, limb_half)) {
      continue;
    }
    const double half = solver::kPi - limb_half;
    for (int i = 0; i < kStreakArcPoints && widths.count < kMaxStreakArcWidths; ++i) {
      const double u = -kStreakArcSpan + 2.0 * kStreakArcSpan * i / (kStreakArcPoints - 1.0);
      const double a = base + solver::kPi + u * half;
      const auto point_at = [&](double angle) noexcept {
        return solver::Vec3(cf.position + g.radius_mm * (std::cos(angle) * cf.normal + std::sin(angle) * cf.binormal));
      };
      solver::Vec2 p;
      solver::Vec2 p_a;
      if (!camera.project(point_at(a), p) || !camera.project(point_at(a + 1e-4), p_a)) {
        continue;
      }
      const solver::Vec2 tangent = p_a - p;
      if (!(tangent.norm() > 0.0)) {
        continue;
      }
      const solver::Vec2 n = solver::Vec2(-tangent.y(), tangent.x()).normalized();
      double width_sq = 0.0;
      if (!change_width(image, p, n, ChangeProfile::kStripeChroma, width_sq)) {
        continue;
      }
      widths.add(n, width_sq, kStreakSharpWidthPx);
    }
  }
}

// The silhouette's widths across each blue stripe's middle, both sides: the
// arcs' normals run along the tube, these across it.
void silhouette_widths(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                       const solver::InstrumentModel& model, const solver::PoseFrames& f,
                       StreakWidths& widths) noexcept {
  const auto& g = model.geometry();
  for (int m = 0; m < kNumMarkers; ++m) {
    const auto mm = static_cast<std::size_t>(m);
    if (config.marker_classes[mm] != PixelClass::Blue) {
      continue;
    }
    const double s_mid_mm = 0.5 * (g.boundaries_mm[mm] + g.boundaries_mm[mm + 1U]);
    for (std::size_t side = 0U; side < 2U && widths.count < kMaxStreakWidths; ++side) {
      solver::Vec2 point;
      solver::Vec2 normal;
      double width_sq = 0.0;
      if (!silhouette_at(camera, model, f, s_mid_mm, side, point, normal) ||
          !change_width(image, point, normal, ChangeProfile::kRed, width_sq)) {
        continue;
      }
      widths.add(normal, width_sq, kStreakSilhouetteSharpWidthPx);
    }
  }
}

// The symmetric 2 x 2 streak tensor M = b b^T (entries m00, m01, m11) in
// least squares over the widths' excesses, w^2 - sharp^2 = n^T M n: a
// second pass without the widths beyond 2.5 x the median residual + 1
// px^2. False when the normals do not turn enough (a straight arc).
bool fit_streak_tensor(const StreakWidths& widths, Eigen::Vector3d& m) noexcept {
  const int count = widths.count;
  std::array<bool, kMaxStreakWidths> keep{};
  keep.fill(true);
  std::array<double, kMaxStreakWidths> residual{};
  std::array<double, kMaxStreakWidths> work{};
  m = Eigen::Vector3d::Zero();
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (int i = 0; i < count; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (keep[k]) {
        normal += widths.rows[k] * widths.rows[k].transpose();
        rhs += widths.rows[k] * widths.excess[k];
      }
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(normal);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-9)) {
      return false;
    }
    m = ldlt.solve(rhs);
    if (!m.allFinite()) {
      return false;
    }
    if (pass == 0) {
      for (int i = 0; i < count; ++i) {
        const auto k = static_cast<std::size_t>(i);
        residual[k] = std::fabs(widths.rows[k].dot(m) - widths.excess[k]);
        work[k] = residual[k];
      }
      const double cut = 2.5 * median_of(work.data(), count) + 1.0;  // px^2
      for (int i = 0; i < count; ++i) {
        keep[static_cast<std::size_t>(i)] = residual[static_cast<std::size_t>(i)] <= cut;
      }
    }
  }
  return true;
}

// The motion-blur streak (px, image; its sign is arbitrary) read on the
// stripe boundaries' visible arcs at the frames f: at kStreakArcPoints of
// each arc the change's width w along the arc's image normal n, then
// M = b b^T from w^2 - kStreakSharpWidthPx^2 = n^T M n by linear least
// squares, once more without the widths far off the first fit (a vessel or
// a highlight beside the arc); the streak is M's main axis. False with
// fewer than kMinStreakWidths widths or a singular fit.
bool read_streak(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                 const solver::InstrumentModel& model, const solver::PoseFrames& f, solver::Vec2& streak_px) noexcept {
  StreakWidths widths;
  arc_widths(image, config, camera, model, f, widths);
  silhouette_widths(image, config, camera, model, f, widths);
  if (widths.count < kMinStreakWidths) {
    return false;
  }
  Eigen::Vector3d m;  // M's entries (m00, m01, m11)
  if (!fit_streak_tensor(widths, m)) {
    return false;
  }
  Eigen::Matrix2d bb;
  bb << m(0), m(1), m(1), m(2);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(bb);
  if (eigen.info() != Eigen::Success) {
    return false;
  }
  const double length_px = std::sqrt(std::max(0.0, eigen.eigenvalues()(1)));  // ascending: (1) is the largest
  streak_px = length_px * eigen.eigenvectors().col(1);
  return streak_px.allFinite();
}

// refine_streak_arc_retry: true when a fine iteration that read too few
// boundaries is to be read again with the arcs widened under the streak;
// the streak read at the frames f when none is held yet (a smear along the
// tube can hide every arc, so the arcs never read as smeared).
bool streak_for_arc_retry(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                          const solver::InstrumentModel& model, const solver::PoseFrames& f,
                          solver::Vec2& streak_px) noexcept {
  if (!config.refine_streak_arc_retry || !config.refine_streak) {
    return false;
  }
  if (streak_px.norm() > 0.0) {
    return true;
  }
  if (!read_streak(image, config, camera, model, f, streak_px) ||
      !(streak_px.norm() >= config.refine_streak_arc_retry_min_px)) {
    streak_px = solver::Vec2::Zero();
    return false;
  }
  return true;
}

// The pose fit's readings of one iteration (bounded by kMaxReadings: fixed
// sample counts) and where the model puts each.
struct FitReadings {
  std::array<Reading, kMaxReadings> readings{};
  std::array<solver::Vec2, kMaxReadings> predicted{};
  int count = 0;

  // A reading: what the model point is, read along `direction` at
  // `offset_px` from its prediction `at`.
  void push(Reading rd, const solver::Vec2& direction, double offset_px, const solver::Vec2& at) noexcept {
    rd.direction = direction;
    rd.offset_px = offset_px;
    readings[static_cast<std::size_t>(count)] = rd;
    predicted[static_cast<std::size_t>(count)] = at;
    ++count;
  }
};

// The weak prior around the fit's start (mm, mm, rad, rad, mm, rad, rad):
// it keeps directions the image does not observe (e.g. a tube seen end-on)
// where they were.
constexpr double kFitPriorSd[solver::kNumParams] = {3.0, 3.0, 0.1, 0.1, 5.0, 0.5, 0.5};
// The finite-difference steps of the fit's rows, in r's units.
constexpr double kFitStepH[solver::kNumParams] = {1e-3, 1e-3, 1e-5, 1e-5, 1e-3, 1e-5, 1e-5};

// The image point of the boundary circle cf (radius_mm) at angle_rad, and
// its arc's image normal towards the tip (cf2: the circle kDsMm further).
// False where it does not project, or where the arc runs along the tube (a
// reading across it slides).
bool arc_point(const solver::CameraModel& camera, const solver::CentrelineFrame& cf,
               const solver::CentrelineFrame& cf2, double radius_mm, double angle_rad, solver::Vec2& p,
               solver::Vec2& normal, double& px_per_mm) noexcept {
  const auto point_at = [&](const solver::CentrelineFrame& c, double angle) noexcept {
    return solver::Vec3(c.position + radius_mm * (std::cos(angle) * c.normal + std::sin(angle) * c.binormal));
  };
  solver::Vec2 p_s, p_a;
  if (!camera.project(point_at(cf, angle_rad), p) || !camera.project(point_at(cf2, angle_rad), p_s) ||
      !camera.project(point_at(cf, angle_rad + 1e-4), p_a)) {
    return false;
  }
  const solver::Vec2 along = (p_s - p) / kDsMm;  // px per mm along the tube
  px_per_mm = along.norm();
  const solver::Vec2 tangent = p_a - p;
  if (!(px_per_mm > 0.5) || !(tangent.norm() > 0.0)) {
    return false;
  }
  normal = solver::Vec2(-tangent.y(), tangent.x());
  normal.normalize();
  if (normal.dot(along) < 0.0) {
    normal = -normal;
  }
  return normal.dot(along) >= 0.5 * px_per_mm;
}

// What one iteration of the pose fit read on the boundary arcs.
struct ArcReadout {
  int readings = 0;                               // the arc readings kept
  bool smeared = false;                           // ImageFitSummary::smeared
  std::array<int, kNumBoundaries> on_boundary{};  // ... of them per boundary
};

// The boundary arcs at the frames f, each point read across its arc within
// window_mm; `streak_px`: the streak read in an earlier iteration (zero on
// a sharp frame). A reading whose colour change is clear only a few samples
// away (a smear) is set aside, and kept only when the smear is the frame's
// (motion blur), not one stripe's: a large share of many readings.
ArcReadout read_fit_arcs(const Refiner& refiner, const ExtractorConfig& config, const solver::CameraModel& camera,
                         const solver::InstrumentModel& model, const solver::PoseFrames& f, double window_mm,
                         const solver::Vec2& streak_px, bool widen_under_streak, FitReadings& fit) noexcept {
  const double radius = model.geometry().radius_mm;
  std::array<Reading, kMaxSmearedReadings> smeared{};
  std::array<solver::Vec2, kMaxSmearedReadings> smeared_at{};
  std::array<int, kNumBoundaries> sharp_on{};
  std::array<int, kNumBoundaries> smeared_on{};
  int smeared_count = 0;
  int arc_readings = 0;
  for (int j = 0; j < kNumBoundaries; ++j) {
    const BoundaryColours colours = colours_of(config, j);
    if (!colours.usable || j == 0) {  // the base arc: behind the shaft in most views (docs/vision.md)
      continue;
    }
    const double s_j = model.geometry().boundaries_mm[static_cast<std::size_t>(j)];
    const solver::CentrelineFrame cf = model.centreline(f, s_j);
    const solver::CentrelineFrame cf2 = model.centreline(f, s_j + kDsMm);
    double base = 0.0;
    double limb_half = 0.0;
    if (!solver::circle_limb_angles(cf, radius, base, limb_half)) {
      continue;
    }
    const double half = solver::kPi - limb_half;
    int on_this = 0;
    for (int i = 0; i < kFitArcSamples; ++i) {
      const double u = -config.refine_arc_span + 2.0 * config.refine_arc_span * i / (kFitArcSamples - 1.0);
      const double a = base + solver::kPi + u * half;
      solver::Vec2 p;
      solver::Vec2 normal;
      double px_per_mm = 0.0;
      if (!arc_point(camera, cf, cf2, radius, a, p, normal, px_per_mm)) {
        continue;
      }
      Reading rd;
      rd.arc = true;
      rd.boundary = j;
      rd.angle_rad = a;
      double tau = 0.0;
      // Under a streak along this normal the change is a ramp as long as
      // the smear: clear colours lie up to half of it from the crossing
      // (refine_streak_arc_retry).
      const double along_px = std::fabs(streak_px.dot(normal));
      const bool ramp = widen_under_streak && along_px >= kStreakArcMinAlongPx;
      const int reach = ramp ? std::min(kMaxClearReach, std::max(config.refine_smear_clear_reach,
                                                                 static_cast<int>(std::ceil(0.5 * along_px)) + 1))
                             : config.refine_smear_clear_reach;
      const double arc_window_px =
          ramp ? std::max(window_mm * px_per_mm, static_cast<double>(reach) + 2.0) : window_mm * px_per_mm;
      Crossing read = refiner.crossing(p, normal, arc_window_px, colours, reach, tau);
      if (ramp && read == Crossing::kSmeared) {
        read = Crossing::kSharp;  // the frame's smear, read: not one stripe's
      }
      if (colours.margin && read != Crossing::kNone) {
        // The tip arc (j = 0 is not read): under the streak read in an
        // earlier iteration (zero on a sharp frame), refine_smear_tip_bias.
        tau += config.refine_smear_tip_bias * std::fabs(streak_px.dot(normal));
      }
      if (read == Crossing::kSharp) {
        fit.push(rd, normal, tau, p);
        ++on_this;
      } else if (read == Crossing::kSmeared && smeared_count < kMaxSmearedReadings) {
        rd.direction = normal;
        rd.offset_px = tau;
        smeared[static_cast<std::size_t>(smeared_count)] = rd;
        smeared_at[static_cast<std::size_t>(smeared_count)] = p;
        ++smeared_count;
        ++smeared_on[static_cast<std::size_t>(j)];
      }
    }
    sharp_on[static_cast<std::size_t>(j)] = on_this;
    arc_readings += on_this;
  }
  ArcReadout out;
  const int all_arcs = arc_readings + smeared_count;
  out.smeared = smeared_count > 0 && all_arcs >= config.refine_smear_min_arc_readings &&
                static_cast<double>(smeared_count) >= config.refine_smear_share * static_cast<double>(all_arcs);
  if (out.smeared) {
    for (int i = 0; i < smeared_count; ++i) {
      const Reading& rd = smeared[static_cast<std::size_t>(i)];
      fit.push(rd, rd.direction, rd.offset_px, smeared_at[static_cast<std::size_t>(i)]);
    }
    arc_readings = all_arcs;
  }
  out.readings = arc_readings;
  for (std::size_t j = 0U; j < static_cast<std::size_t>(kNumBoundaries); ++j) {
    out.on_boundary[j] = sharp_on[j] + (out.smeared ? smeared_on[j] : 0);
  }
  return out;
}

// The boundaries the arcs read (3 readings or more), and the longest run
// of consecutive colour boundaries read (ImageFitSummary::boundary_run).
void count_read_boundaries(const std::array<int, kNumBoundaries>& on_boundary, int& boundaries,
                           int& boundary_run) noexcept {
  boundaries = 0;
  boundary_run = 0;
  int run = 0;
  for (std::size_t j = 0U; j < static_cast<std::size_t>(kNumBoundaries); ++j) {
    const bool read_j = on_boundary[j] >= 3;
    boundaries += read_j ? 1 : 0;
    if (j >= 1U && j + 1U < static_cast<std::size_t>(kNumBoundaries)) {  // the colour boundaries
      run = read_j ? run + 1 : 0;
      boundary_run = std::max(boundary_run, run);
    }
  }
}

// What one iteration of the pose fit read on the silhouette.
struct SilhouetteReadout {
  int readings = 0;  // on the striped section (ImageFitSummary::silhouette_readings)
  int plain = 0;     // ... of them where the peak's centre reads too (plain_silhouette_readings)
  int grasper = 0;   // on the grasper (ImageFitSummary::grasper_readings)
};

// The grasper's silhouette along `normal` through p (px from p, outwards
// positive). The metal is neutral and the tissue beside it is not, while
// the jaws' slit and the highlights on the metal, neutral too, make
// lightness edges stronger than the silhouette's (which edge() would take:
// 4 px inside on some hard frames). So the colour's spread, max - min of
// the 8-bit sRGB values, is read every kNeutralStepPx: the silhouette is
// where the mean spread over 1.5-4 px outside exceeds the mean over 1.5-4
// px inside by the most (at least kNeutralMinContrast), moved to where the
// spread crosses halfway between the two. False when there is no such
// change within window_px.
constexpr double kNeutralStepPx = 0.5;
constexpr int kNeutralSide = 6;  // samples averaged on each side
constexpr int kNeutralGap = 2;   // samples between a point and its sides
constexpr int kNeutralMargin = kNeutralSide + kNeutralGap;
constexpr int kNeutralMaxReach = 40;  // samples: a window of 20 px
constexpr double kNeutralMinContrast = 12.0;
constexpr int kMaxNeutralProfile = 2 * (kNeutralMaxReach + kNeutralMargin) + 1;
bool neutral_edge(const ImageView& image, const solver::Vec2& p, const solver::Vec2& normal, double window_px,
                  double& offset_px) noexcept {
  const int half = ceil_within(window_px / kNeutralStepPx, 1, kNeutralMaxReach) + kNeutralMargin;
  const int n = 2 * half + 1;
  std::array<double, kMaxNeutralProfile> spread{};
  for (int i = 0; i < n; ++i) {
    const double t = kNeutralStepPx * static_cast<double>(i - half);
    Rgb c;
    if (!sample(image, p.x() + t * normal.x(), p.y() + t * normal.y(), c)) {
      return false;
    }
    spread[static_cast<std::size_t>(i)] = std::max(c.r, std::max(c.g, c.b)) - std::min(c.r, std::min(c.g, c.b));
  }
  const auto mean = [&](int from, int to) noexcept {
    double sum = 0.0;
    for (int k = from; k <= to; ++k) {
      sum += spread[static_cast<std::size_t>(k)];
    }
    return sum / static_cast<double>(to - from + 1);
  };
  int best = -1;
  double best_contrast = kNeutralMinContrast;
  double best_mid = 0.0;
  for (int i = kNeutralMargin; i < n - kNeutralMargin; ++i) {
    const double inside = mean(i - kNeutralMargin, i - kNeutralGap - 1);
    const double outside = mean(i + kNeutralGap + 1, i + kNeutralMargin);
    if (outside - inside > best_contrast) {
      best_contrast = outside - inside;
      best = i;
      best_mid = 0.5 * (inside + outside);
    }
  }
  if (best < 0 || best == kNeutralMargin || best == n - kNeutralMargin - 1) {
    return false;  // none, or at the window's end: the change may lie beyond it
  }
  // The halfway crossing near the best point: the first within a sample of
  // it, else the last one within its gap.
  double at = static_cast<double>(best);
  for (int k = best - kNeutralGap; k < best + kNeutralGap; ++k) {
    const double a = spread[static_cast<std::size_t>(k)];
    const double b = spread[static_cast<std::size_t>(k) + 1U];
    if (a <= best_mid && b > best_mid) {
      at = static_cast<double>(k) + (best_mid - a) / (b - a);
      if (std::fabs(at - static_cast<double>(best)) <= 1.0) {
        break;
      }
    }
  }
  offset_px = kNeutralStepPx * (at - static_cast<double>(half));
  return std::fabs(offset_px) <= window_px;
}

// Silhouette readings at the frames f within edge_window_px: both sides
// along the striped section, the shaft's just before the base up to the
// channel exit (lambda_mm) and the grasper's past the tip (neither counted:
// the striped section must be seen for itself).
SilhouetteReadout read_fit_silhouette(const Refiner& refiner, const ExtractorConfig& config,
                                      const solver::CameraModel& camera, const solver::InstrumentModel& model,
                                      const solver::PoseFrames& f, double edge_window_px, double lambda_mm,
                                      FitReadings& fit) noexcept {
  SilhouetteReadout out;
  const auto read_silhouette = [&](Part part, double s, std::size_t side) noexcept {
    solver::Vec2 point;
    solver::Vec2 normal;
    bool at = false;
    switch (part) {
      case Part::kTube: at = silhouette_at(camera, model, f, s, side, point, normal); break;
      case Part::kShaft:
        at = shaft_silhouette_at(camera, model, f, s, side, point, normal) && camera.in_image(point);
        break;
      case Part::kGrasper:
        at = grasper_silhouette_at(camera, model, f, s, side, point, normal) && camera.in_image(point) &&
             !behind_tube_end(camera, model, f, point);
        break;
    }
    // The part's apparent half width at s, for the blurred edge's model:
    // only a frame with a streak reads that way.
    double half_width_px = 0.0;
    if (at && part != Part::kGrasper && refiner.has_streak()) {
      const solver::CircleLimbs limbs =
          part == Part::kTube ? model.limbs(camera, f, s) : model.shaft_limbs(camera, f, s);
      if (limbs.present[0] && limbs.present[1]) {
        half_width_px = 0.5 * (limbs.pixel[0] - limbs.pixel[1]).norm();
      }
    }
    double e = 0.0;
    bool outer_end = false;
    const bool read = at && (part == Part::kGrasper ? neutral_edge(refiner.image(), point, normal, edge_window_px, e)
                                                    : refiner.edge_across(point, normal, edge_window_px, half_width_px, e, outer_end));
    if (!read) {
      return false;
    }
    // What the peak's centre would give, for the validity rule (GuidedOptions).
    double peak_e = 0.0;
    out.plain += part == Part::kTube && (!outer_end || refiner.edge(point, normal, edge_window_px, peak_e)) ? 1 : 0;
    Reading rd;
    rd.part = part;
    rd.s_mm = s;
    rd.side = side;
    fit.push(rd, normal, e, point);
    return true;
  };
  const double bend_length_mm = model.geometry().bend_length_mm;
  for (std::size_t side = 0U; side < 2U; ++side) {
    for (int i = 0; i < kFitSilhouetteSamples; ++i) {
      const double s = bend_length_mm * (0.03 + 0.94 * i / (kFitSilhouetteSamples - 1.0));
      out.readings += read_silhouette(Part::kTube, s, side) ? 1 : 0;
    }
    for (int i = 0; i < kFitShaftSamples && config.refine_shaft_readings; ++i) {
      const double back = kFitShaftFirstMm + kFitShaftStepMm * i;
      if (back > lambda_mm - 1.0) {
        break;  // the shaft starts at the channel exit
      }
      static_cast<void>(read_silhouette(Part::kShaft, back, side));  // a missing shaft reading is no failure
    }
    for (int i = 0; i < kFitGrasperSamples && config.refine_grasper_readings; ++i) {
      const double beyond = kFitGrasperFirstMm + kFitGrasperStepMm * i;
      if (beyond > model.geometry().tcp_offset_mm - 1.0) {
        break;  // the grasper ends at the TCP
      }
      out.grasper += read_silhouette(Part::kGrasper, beyond, side) ? 1 : 0;
    }
  }
  return out;
}

// One robust step of the pose fit from its readings at x: Tukey weights at
// the readings' robust scale (MAD), finite-difference rows, the weak prior
// around `start`. False when the normal equations do not solve. rms_px: the
// weighted residual; largest_move_px: the largest move of a read model point
// along its reading direction under the step (the convergence test).
bool fit_step(const FitReadings& fit, const solver::CameraModel& camera, const solver::InstrumentModel& model,
              const solver::PoseVector& x, const solver::PoseVector& start,
              Eigen::Matrix<double, solver::kNumParams, 1>& delta, double& rms_px, double& largest_move_px) noexcept {
  const int n = fit.count;
  std::array<double, kMaxReadings> work{};
  for (int i = 0; i < n; ++i) {
    work[static_cast<std::size_t>(i)] = std::fabs(fit.readings[static_cast<std::size_t>(i)].offset_px);
  }
  RobustNormalEquations<solver::kNumParams> equations(tukey_cut_px(work.data(), n, 0.3));
  const auto& g = model.geometry();
  std::array<solver::PoseFrames, solver::kNumParams> shifted{};
  std::array<std::array<solver::CentrelineFrame, kNumBoundaries>, solver::kNumParams> shifted_boundaries{};
  for (int k = 0; k < solver::kNumParams; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    solver::PoseVector xk = x;
    xk[k] += kFitStepH[k];
    shifted[kk] = model.frames(xk);
    for (std::size_t j = 0U; j < static_cast<std::size_t>(kNumBoundaries); ++j) {
      shifted_boundaries[kk][j] = model.centreline(shifted[kk], g.boundaries_mm[j]);
    }
  }
  std::array<Eigen::Matrix<double, solver::kNumParams, 1>, kMaxReadings> rows{};  // d(reading)/dr, px per unit
  int used = 0;
  for (int i = 0; i < n; ++i) {
    const Reading& rd = fit.readings[static_cast<std::size_t>(i)];
    const double v = rd.offset_px;
    const double w = equations.weight(v);
    if (!(w > 0.0)) {
      continue;
    }
    Eigen::Matrix<double, solver::kNumParams, 1> row;
    bool ok = true;
    for (int k = 0; k < solver::kNumParams && ok; ++k) {
      solver::Vec2 pk;
      ok = predict(camera, model, shifted[static_cast<std::size_t>(k)], shifted_boundaries[static_cast<std::size_t>(k)],
                   rd, pk);
      row[k] = rd.direction.dot(pk - fit.predicted[static_cast<std::size_t>(i)]) / kFitStepH[k];
    }
    if (!ok || !row.allFinite()) {
      continue;
    }
    rows[static_cast<std::size_t>(used++)] = row;
    // The grasper's readings steer the fit but stay out of its residual,
    // which the acceptance and the comparisons of fits were set on
    // (docs/vision.md "The grasper").
    equations.add(row, v, w, rd.part != Part::kGrasper);
  }
  rms_px = equations.rms_px();
  if (!equations.solve(kFitPriorSd, x - start, delta)) {
    return false;
  }
  largest_move_px = 0.0;
  for (int i = 0; i < used; ++i) {
    largest_move_px = std::max(largest_move_px, std::fabs(rows[static_cast<std::size_t>(i)].dot(delta)));
  }
  return true;
}

}  // namespace

Status<VisionError> FeatureExtractor::pose_from_regions(const solver::CameraModel& camera,
                                                        const solver::InstrumentModel& model,
                                                        solver::PoseVector& r) const noexcept {
  const Interpretation& in = result_.interpretation;
  if (in.found_count < 3 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  constexpr int kParams = 5;
  constexpr int kParamIndex[kParams] = {solver::kXch, solver::kYch, solver::kLambda, solver::kPhi, solver::kTheta};
  constexpr double kStep[kParams] = {1e-3, 1e-3, 1e-3, 1e-5, 1e-5};
  constexpr int kRows = 2 * kNumMarkers;
  using Residuals = Eigen::Matrix<double, kRows, 1>;
  const auto& g = model.geometry();
  // Centroid minus the projected marker middle, per labelled marker (zero rows otherwise).
  const auto residuals = [&](const solver::PoseVector& at, Residuals& out) noexcept {
    out.setZero();
    const solver::PoseFrames f = model.frames(at);
    for (std::size_t m = 0U; m < static_cast<std::size_t>(kNumMarkers); ++m) {
      if (!in.markers[m].found) {
        continue;
      }
      const double s_mid = 0.5 * (g.boundaries_mm[m] + g.boundaries_mm[m + 1U]);
      solver::Vec2 p;
      if (!camera.project(model.centreline(f, s_mid).position, p)) {
        return false;
      }
      out[static_cast<Eigen::Index>(2U * m)] = in.markers[m].region.centroid.x - p.x();
      out[static_cast<Eigen::Index>(2U * m + 1U)] = in.markers[m].region.centroid.y - p.y();
    }
    return true;
  };
  solver::PoseVector x = r;
  Residuals e;
  if (!residuals(x, e)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  double cost = e.squaredNorm();
  double damping = 1e-3;
  for (int it = 0; it < 15; ++it) {
    Eigen::Matrix<double, kRows, kParams> jac;
    for (int k = 0; k < kParams; ++k) {
      solver::PoseVector xk = x;
      xk[kParamIndex[k]] += kStep[k];
      Residuals ek;
      if (!residuals(xk, ek)) {
        return Status<VisionError>::failure(VisionError::NoInstrument);
      }
      jac.col(k) = -(ek - e) / kStep[k];  // d(projection)/d(parameter)
    }
    Eigen::Matrix<double, kParams, kParams> normal = jac.transpose() * jac;
    normal.diagonal() *= 1.0 + damping;
    const Eigen::Matrix<double, kParams, 1> delta = normal.ldlt().solve(jac.transpose() * e);
    if (!delta.allFinite()) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
    solver::PoseVector trial = x;
    for (int k = 0; k < kParams; ++k) {
      trial[kParamIndex[k]] += delta[k];
    }
    Residuals et;
    const double trial_cost = residuals(trial, et) ? et.squaredNorm() : 1e300;
    if (trial_cost < cost) {
      const bool small = cost - trial_cost < 1e-6 * cost;
      x = trial;
      e = et;
      cost = trial_cost;
      damping = std::max(damping * 0.3, 1e-6);
      if (small) {
        break;
      }
    } else {
      damping *= 10.0;
      if (damping > 1e6) {
        break;
      }
    }
  }
  // The visible faces' centroids lie a few pixels off the centreline's
  // projection; much more is a wrong pose.
  const double rms = std::sqrt(cost / (2.0 * in.found_count));
  if (!(rms < 12.0) || !x.allFinite()) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  r = x;
  return ok_status<VisionError>();
}

Status<VisionError> FeatureExtractor::read_motion_streak(const ImageView& image, const solver::CameraModel& camera,
                                                         const solver::InstrumentModel& model,
                                                         const solver::PoseVector& r,
                                                         solver::Vec2& streak_px) const noexcept {
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  if (!read_streak(image, config_, camera, model, model.frames(r), streak_px)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  return ok_status<VisionError>();
}

Status<VisionError> FeatureExtractor::fit_insertion_to_base_rim(const ImageView& image,
                                                                const solver::CameraModel& camera,
                                                                const solver::InstrumentModel& model,
                                                                solver::PoseVector& r) const noexcept {
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  if (!config_.refine_base_rim) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  const auto& g = model.geometry();
  const double rim_radius = g.shaft_radius_mm + config_.refine_base_rim_share * (g.radius_mm - g.shaft_radius_mm);
  const double step_mm = config_.refine_rim_scan_step_mm;
  // Checked at creation: range <= step * kMaxRimScanSteps.
  const int steps = std::min(static_cast<int>(config_.refine_rim_scan_range_mm / step_mm + 1e-9), kMaxRimScanSteps);
  // Nearest first: 0, +step, -step, +2 step, ...
  for (int i = 0; i <= 2 * steps; ++i) {
    const int k = (i + 1) / 2;
    solver::PoseVector at = r;
    at[solver::kLambda] += (i % 2 == 1 ? 1.0 : -1.0) * static_cast<double>(k) * step_mm;
    if (!(at[solver::kLambda] > 0.0)) {
      continue;
    }
    const solver::PoseFrames frames = model.frames(at);
    if (!base_face_visible(model, frames)) {
      continue;
    }
    Refiner refiner(image, colors_, config_, camera, model, frames, edge_scratch_.get());
    double shift_mm = 0.0;
    if (refiner.rim_shift(rim_radius, shift_mm)) {
      // The rim moves the base, and the tube with it, along the axis:
      // lambda grows with the shift towards the tip.
      at[solver::kLambda] += shift_mm;
      r = at;
      return ok_status<VisionError>();
    }
  }
  return Status<VisionError>::failure(VisionError::NoInstrument);
}

Status<VisionError> FeatureExtractor::fit_pose_to_image(const ImageView& image, const solver::CameraModel& camera,
                                                        const solver::InstrumentModel& model, solver::PoseVector& r,
                                                        ImageFitSummary& summary, bool coarse_start) noexcept {
  summary = ImageFitSummary{};
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  const solver::PoseVector start = r;  // the weak prior's centre (kFitPriorSd)
  solver::PoseVector x = r;
  FitReadings fit;
  double rms = 0.0;
  int iterations =
      std::min(std::max(config_.refine_fit_iterations, 1) + (coarse_start ? kCoarseIterations : 0), kMaxFitIterations);
  bool widen_arcs = false;  // refine_streak_arc_retry, once set for the rest of the fit
  // The motion-blur streak, read once, at the first iteration whose arcs
  // read as smeared (a sharp frame never pays for it).
  bool streak_tried = false;
  solver::Vec2 streak_px = solver::Vec2::Zero();
  for (int it = 0; it < iterations; ++it) {
    const solver::PoseFrames f = model.frames(x);
    Refiner refiner(image, colors_, config_, camera, model, f, edge_scratch_.get());
    fit.count = 0;
    // From a coarse start (a pose from the regions) the first iterations
    // search wider windows and may see fewer boundaries.
    const bool coarse_it = coarse_start && it < kCoarseIterations;
    const int fine_it = coarse_start ? it - kCoarseIterations : it;
    const double window_mm =
        coarse_it ? config_.refine_coarse_search_mm : (fine_it == 0 ? config_.refine_search_mm : 0.6);
    const double edge_window_px = coarse_it ? config_.refine_coarse_edge_search_px : config_.refine_edge_search_px;
    const ArcReadout arcs = read_fit_arcs(refiner, config_, camera, model, f, window_mm, streak_px, widen_arcs, fit);
    summary.smeared = arcs.smeared;
    int boundaries = 0;
    int boundary_run = 0;
    count_read_boundaries(arcs.on_boundary, boundaries, boundary_run);
    // Under a streak of refine_streak_min_px and more, the silhouette is
    // read at its plateau's outer end where the smear across it is large
    // (Refiner::edge_across). Read once per fit: at the first iteration
    // whose arcs read as smeared, or (a smear across the tube leaves the
    // arcs sharp) at the first fine one that reads enough boundaries to
    // stand on the tube, where it must be longer (a pose beside the tube
    // reads widths from stray colour). Once read it is the frame's, for
    // every later iteration.
    const bool unsmeared_read = config_.refine_streak_unsmeared && !summary.smeared && !coarse_it &&
                                boundaries >= config_.refine_streak_unsmeared_min_boundaries;
    if ((summary.smeared || unsmeared_read) && config_.refine_streak && !streak_tried) {
      streak_tried = true;
      const double min_px = summary.smeared ? config_.refine_streak_min_px : config_.refine_streak_unsmeared_min_px;
      if (!read_streak(image, config_, camera, model, f, streak_px) || !(streak_px.norm() >= min_px)) {
        streak_px = solver::Vec2::Zero();
      }
    }
    summary.streak_px = streak_px;
    refiner.use_streak(summary.streak_px);
    const SilhouetteReadout silhouette =
        read_fit_silhouette(refiner, config_, camera, model, f, edge_window_px, x[solver::kLambda], fit);
    summary.iterations = it + 1;
    summary.arc_readings = arcs.readings;
    summary.silhouette_readings = silhouette.readings;
    summary.grasper_readings = silhouette.grasper;
    summary.plain_silhouette_readings = silhouette.plain;
    summary.boundaries = boundaries;
    summary.boundary_run = boundary_run;
    // A fine iteration needs 2 boundaries' arcs, and no silhouette reading:
    // the arcs and the shaft hold the tube where a smear or an occluder
    // hides its silhouette (the caller decides what such a fit may give,
    // GuidedOptions); or 1 boundary's arcs with the silhouette well read
    // (refine_one_boundary_min_silhouette: an occluder hiding the others).
    // A coarse one, from a rough seed, needs the silhouette.
    const bool arcs_hold = boundaries >= 2 ||
                           (boundaries == 1 && silhouette.plain >= config_.refine_one_boundary_min_silhouette);
    if (!coarse_it && !arcs_hold && !widen_arcs &&
        streak_for_arc_retry(image, config_, camera, model, f, streak_px)) {
      streak_tried = true;
      widen_arcs = true;
      ++iterations;  // the same pose read again, once per fit: at most kMaxFitIterations + 1
      continue;
    }
    if ((!coarse_it && !arcs_hold) || (coarse_it && silhouette.readings < 10)) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
    Eigen::Matrix<double, solver::kNumParams, 1> delta;
    double largest_move_px = 0.0;
    if (!fit_step(fit, camera, model, x, start, delta, rms, largest_move_px)) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
    x += delta;
    // Converged when the step moves no model point read by more than
    // refine_fit_tolerance_px along its reading direction.
    if (largest_move_px < config_.refine_fit_tolerance_px && !coarse_it) {
      summary.converged = true;
      break;
    }
  }
  summary.rms_px = rms;
  if (!x.allFinite()) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  r = x;
  return ok_status<VisionError>();
}

namespace {

constexpr int kShaftSamples = 8;          // per side
constexpr int kShaftIterations = 8;
// The search beyond the model's cross-section at the first iterations (the
// last repeated): the channel's play of 1.5 mm / 3 deg (1 sd) moves the
// shaft by up to about 100 px in a PAL image.
constexpr double kShaftWindowsPx[] = {120.0, 30.0, 10.0};
constexpr int kShaftRefineFrom = 2;         // iterations from which each end is moved to the gradient peak
constexpr double kShaftEdgeRefinePx = 3.0;  // ... searched within +/- this
constexpr double kShaftNeutralChroma = 12.0;  // a*b* chroma: the shaft below, tissue above (clear view)
// Under haze the limit follows the tissue (shaft_neutral_chroma): this share
// of its median chroma on a grid of kTissueGridX x kTissueGridY samples, not
// below the floor (sensor noise on the grey shaft). Measured on the hard set:
// shares 0.5 and 0.6 gave the same, 0.45 and 0.4 less; floors 2-4 the same.
constexpr double kShaftNeutralShare = 0.5;
constexpr double kShaftNeutralFloor = 3.0;
constexpr int kTissueGridX = 16;
constexpr int kTissueGridY = 12;
constexpr std::size_t kTissueGridSamples = static_cast<std::size_t>(kTissueGridX) * static_cast<std::size_t>(kTissueGridY);
constexpr double kShaftMaxRmsPx = 1.5;
constexpr int kShaftMinPerSide = 2;
constexpr int kMaxShaftReadings = 2 * kShaftSamples;

double chroma_at(const ImageView& image, const solver::Vec2& p, bool& ok) noexcept {
  Rgb c;
  ok = sample(image, p.x(), p.y(), c);
  if (!ok) {
    return 0.0;
  }
  const Lab lab = srgb_to_lab(to_byte(c.r), to_byte(c.g), to_byte(c.b));
  return std::hypot(lab.a, lab.b);
}

// The chroma below which a pixel counts as the shaft's (neutral): half the
// median chroma of the frame (mostly tissue) on a coarse grid, at most
// kShaftNeutralChroma, at least kShaftNeutralFloor. Haze or smoke veils the
// tissue with a grey that brings its chroma from 20-35 down to 6-15 while the
// shaft stays at 1-3, so a fixed limit calls the tissue shaft and no run has
// the shaft's width (docs/vision.md). Clear frames keep the fixed limit.
double shaft_neutral_chroma(const ImageView& image) noexcept {
  std::array<double, kTissueGridSamples> chroma{};
  int n = 0;
  for (int gy = 0; gy < kTissueGridY; ++gy) {
    for (int gx = 0; gx < kTissueGridX; ++gx) {
      const solver::Vec2 p((gx + 0.5) * image.width / kTissueGridX, (gy + 0.5) * image.height / kTissueGridY);
      bool ok = false;
      const double c = chroma_at(image, p, ok);
      if (ok) {
        chroma[static_cast<std::size_t>(n++)] = c;
      }
    }
  }
  if (n == 0) {
    return kShaftNeutralChroma;
  }
  return std::min(kShaftNeutralChroma, std::max(kShaftNeutralFloor, kShaftNeutralShare * median_of(chroma.data(), n)));
}

// The shaft's cross-section along the line from its model limb point a
// (side 0) to b (side 1), extended by `margin_px` on both sides: of the runs
// of neutral pixels (chroma below `neutral_chroma`) whose width is within
// kShaftWidthTolerance of the model's |b - a|, the one whose centre is
// nearest the model's; its ends as distances along the line from a (px). Short chromatic gaps (noise) are
// bridged; a run that reaches the line's end or the image's is no reading.
constexpr double kShaftWidthTolerance = 0.45;  // relative
constexpr int kMaxCrossSection = 320;          // samples (1 px)
bool shaft_cross_section(const ImageView& image, const solver::Vec2& a, const solver::Vec2& b, double margin_px,
                         double neutral_chroma, double& start_px, double& end_px) noexcept {
  const double width = (b - a).norm();
  if (!(width > 2.0)) {
    return false;
  }
  const solver::Vec2 d = (b - a) / width;
  const int first = -ceil_within(margin_px, 0, kMaxCrossSection);
  const int last = std::min(ceil_within(width + margin_px, 0, kMaxCrossSection), first + kMaxCrossSection - 1);
  constexpr int kMaxGap = 2;
  bool best_found = false;
  double best_distance = 1e30;
  int run_start = 0;
  int run_last = 0;  // last neutral sample of the open run
  bool in_run = false;
  bool run_open_at_start = false;
  const auto close_run = [&](bool open_end) noexcept {
    if (!in_run || run_open_at_start || open_end) {
      return;
    }
    const double run_width = static_cast<double>(run_last - run_start);
    if (std::fabs(run_width - width) > kShaftWidthTolerance * width) {
      return;
    }
    const double centre = 0.5 * (run_start + run_last);
    const double distance = std::fabs(centre - 0.5 * width);
    if (distance < best_distance) {
      best_distance = distance;
      best_found = true;
      start_px = run_start - 0.5;
      end_px = run_last + 0.5;
    }
  };
  for (int i = first; i <= last; ++i) {
    bool ok = false;
    const double c = chroma_at(image, a + static_cast<double>(i) * d, ok);
    if (!ok) {
      close_run(true);  // the run reaches the image's border
      in_run = false;
      run_open_at_start = true;  // until a chromatic sample starts a fresh run
      continue;
    }
    if (c < neutral_chroma) {
      if (!in_run) {
        in_run = true;
        run_start = i;
        run_open_at_start = run_open_at_start || i == first;
      }
      run_last = i;
    } else {
      if (in_run && i - run_last > kMaxGap) {
        close_run(false);
        in_run = false;
      }
      if (!in_run) {
        run_open_at_start = false;
      }
    }
  }
  close_run(true);
  return best_found;
}

// The shaft fit's parameters: the channel's pose x_ch, y_ch, psi, mu.
constexpr int kShaftParams = 4;
constexpr double kShaftPriorSd[kShaftParams] = {3.0, 3.0, 0.1, 0.1};  // mm, mm, rad, rad
constexpr double kShaftStepH[kShaftParams] = {1e-3, 1e-3, 1e-5, 1e-5};

// One iteration's shaft readings: per reading, the distance before the base
// (mm), the side, the model's silhouette point and outward normal, and the
// image edge's offset from it along that normal (px).
struct ShaftReadings {
  std::array<double, kMaxShaftReadings> back{};
  std::array<std::size_t, kMaxShaftReadings> sides{};
  std::array<solver::Vec2, kMaxShaftReadings> normals{};
  std::array<solver::Vec2, kMaxShaftReadings> predicted{};
  std::array<double, kMaxShaftReadings> offsets{};
  int count = 0;
  std::array<int, 2> per_side{};
};

// The shaft's cross-sections at the frames f from 1 mm before the base back
// to 3 mm after the channel exit (lambda_mm; the shaft near the camera
// leaves the image or is out of focus), within window_px; with
// `to_gradient_peak`, each end moved from the threshold's crossing to the
// colour-gradient peak's centre (the silhouette readings' rule).
void read_shaft(const ImageView& image, const Refiner& refiner, const solver::CameraModel& camera,
                const solver::InstrumentModel& model, const solver::PoseFrames& f, double lambda_mm, double window_px,
                double neutral_chroma, bool to_gradient_peak, ShaftReadings& out) noexcept {
  const double first_mm = 1.0;
  const double last_mm = std::max(first_mm, lambda_mm - 3.0);
  out.count = 0;
  out.per_side = {};
  for (int i = 0; i < kShaftSamples; ++i) {
    const double bk = first_mm + (last_mm - first_mm) * i / (kShaftSamples - 1.0);
    std::array<solver::Vec2, 2> point{};
    std::array<solver::Vec2, 2> normal{};
    if (!shaft_silhouette_at(camera, model, f, bk, 0U, point[0], normal[0]) ||
        !shaft_silhouette_at(camera, model, f, bk, 1U, point[1], normal[1])) {
      continue;
    }
    double t0 = 0.0;
    double t1 = 0.0;
    if (!shaft_cross_section(image, point[0], point[1], window_px, neutral_chroma, t0, t1)) {
      continue;
    }
    // Each end's distance from its model point along the line, as a
    // distance along that side's outward normal (straight edge).
    const double width = (point[1] - point[0]).norm();
    const solver::Vec2 d = (point[1] - point[0]) / width;
    const double along[2] = {t0, t1 - width};
    for (std::size_t side = 0U; side < 2U; ++side) {
      const auto k = static_cast<std::size_t>(out.count++);
      out.back[k] = bk;
      out.sides[k] = side;
      out.normals[k] = normal[side];
      out.predicted[k] = point[side];
      out.offsets[k] = along[side] * d.dot(normal[side]);
      double e = 0.0;
      if (to_gradient_peak &&
          refiner.edge(point[side] + out.offsets[k] * normal[side], normal[side], kShaftEdgeRefinePx, e)) {
        out.offsets[k] += e;
      }
      ++out.per_side[side];
    }
  }
}

// One robust step of the shaft fit from its readings at x (Tukey weights at
// the readings' MAD scale, finite-difference rows, the weak prior around
// `start`): the channel's pose change. False when the normal equations do
// not solve; rms_px: the weighted residual.
bool shaft_step(const ShaftReadings& readings, const solver::CameraModel& camera,
                const solver::InstrumentModel& model, const solver::PoseVector& x, const solver::PoseVector& start,
                Eigen::Matrix<double, kShaftParams, 1>& delta, double& rms_px) noexcept {
  const int n = readings.count;
  std::array<double, kMaxShaftReadings> work{};
  for (int i = 0; i < n; ++i) {
    work[static_cast<std::size_t>(i)] = std::fabs(readings.offsets[static_cast<std::size_t>(i)]);
  }
  RobustNormalEquations<kShaftParams> equations(tukey_cut_px(work.data(), n, 1.0));
  std::array<solver::PoseFrames, kShaftParams> shifted{};
  for (int k = 0; k < kShaftParams; ++k) {
    solver::PoseVector xk = x;
    xk[k] += kShaftStepH[k];
    shifted[static_cast<std::size_t>(k)] = model.frames(xk);
  }
  for (int i = 0; i < n; ++i) {
    const auto q = static_cast<std::size_t>(i);
    const double w = equations.weight(readings.offsets[q]);
    if (!(w > 0.0)) {
      continue;
    }
    Eigen::Matrix<double, kShaftParams, 1> row;
    bool ok = true;
    for (int k = 0; k < kShaftParams && ok; ++k) {
      const solver::CircleLimbs limbs =
          model.shaft_limbs(camera, shifted[static_cast<std::size_t>(k)], readings.back[q]);
      ok = limbs.present[readings.sides[q]];
      row[k] = readings.normals[q].dot(limbs.pixel[readings.sides[q]] - readings.predicted[q]) / kShaftStepH[k];
    }
    if (!ok || !row.allFinite()) {
      continue;
    }
    equations.add(row, readings.offsets[q], w);
  }
  rms_px = equations.rms_px();
  return equations.solve(kShaftPriorSd, (x - start).head<kShaftParams>(), delta);
}

}  // namespace

Status<VisionError> FeatureExtractor::fit_channel_to_shaft(const ImageView& image, const solver::CameraModel& camera,
                                                           const solver::InstrumentModel& model, solver::PoseVector& r,
                                                           ShaftFitSummary& summary) const noexcept {
  summary = ShaftFitSummary{};
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  const solver::PoseVector start = r;
  solver::PoseVector x = r;
  const double neutral_chroma = shaft_neutral_chroma(image);
  ShaftReadings readings;
  double rms = 1e9;
  for (int it = 0; it < kShaftIterations; ++it) {
    const double window = kShaftWindowsPx[std::min(it, 2)];
    const solver::PoseFrames f = model.frames(x);
    const Refiner refiner(image, colors_, config_, camera, model, f, edge_scratch_.get());
    read_shaft(image, refiner, camera, model, f, x[solver::kLambda], window, neutral_chroma, it >= kShaftRefineFrom,
               readings);
    summary.iterations = it + 1;
    summary.readings = readings.count;
    if (readings.per_side[0] < kShaftMinPerSide || readings.per_side[1] < kShaftMinPerSide) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
    Eigen::Matrix<double, kShaftParams, 1> delta;
    if (!shaft_step(readings, camera, model, x, start, delta, rms)) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
    x.head<kShaftParams>() += delta;
  }
  summary.rms_px = rms;
  if (!x.allFinite() || !(rms <= kShaftMaxRmsPx)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  r = x;
  return ok_status<VisionError>();
}

Status<VisionError> FeatureExtractor::refine_corners(const ImageView& image, const solver::CameraModel& camera,
                                                     const solver::InstrumentModel& model,
                                                     const solver::PoseVector& r,
                                                     const solver::Vec2& streak_px) noexcept {
  Extraction& e = result_;
  if (!e.refined) {
    e.stage4_corners = e.corners;
  }
  e.refined = true;
  for (auto& c : e.corners) {
    c = Corner{};
  }
  e.corner_count = 0;
  e.boundary_measured.fill(false);
  e.boundary_shift_mm.fill(0.0);
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  const solver::PoseFrames frames = model.frames(r);
  Refiner refiner(image, colors_, config_, camera, model, frames, edge_scratch_.get());
  refiner.use_streak(streak_px);
  const auto& g = model.geometry();
  for (int j = 0; j < kNumBoundaries; ++j) {
    const BoundaryColours colours = colours_of(config_, j);
    const double s_j = g.boundaries_mm[static_cast<std::size_t>(j)];
    // Two passes: the wide search, then a narrow one around its result
    // (the arc's shape follows the shift). The base boundary's arc is not
    // read (in most views it lies behind the shaft, nearer to the camera and
    // only 0.06 mm thinner, so its colour change is the shaft's outline; its
    // end face's rim is read instead, below), nor the tip boundary's when
    // the tip's end face is turned towards the camera (the blue-to-grey
    // change is then the grasper's outline on that face, 0.1-0.3 mm from
    // the circle: docs/vision.md; the image fit still reads that arc,
    // which measured better than leaving it out there),
    // nor is any arc that shows no clear colour change: such a boundary's
    // corners are the limb points of the pose given (fitted to the image by
    // fit_pose_to_image), reported with refine_predicted_confidence.
    double shift = 0.0;
    double step = 0.0;
    bool measured = colours.usable && j != 0 && !(j == kNumBoundaries - 1 && tip_face_visible(model, frames)) &&
                    refiner.arc_shift(s_j, colours, config_.refine_search_mm, step);
    if (measured) {
      shift = step;
      measured = refiner.arc_shift(s_j + shift, colours, 0.4, step);
      shift += measured ? step : 0.0;
      measured = measured && std::fabs(shift) <= config_.refine_search_mm;
    }
    if (!measured) {
      shift = 0.0;
    }
    // The base's position along the tube from its end face's rim, when that
    // face is turned towards the camera; its corners are then the limb
    // points of the shifted circle (the silhouette beside them is the
    // shaft's outline as much as the tube's, so no offset across).
    const bool base = j == 0;
    if (base && config_.refine_base_rim && base_face_visible(model, frames)) {
      const double rim_radius = g.shaft_radius_mm + config_.refine_base_rim_share * (g.radius_mm - g.shaft_radius_mm);
      measured = refiner.rim_shift(rim_radius, step);
      shift = measured ? step : 0.0;
    }
    e.boundary_measured[static_cast<std::size_t>(j)] = measured;
    e.boundary_shift_mm[static_cast<std::size_t>(j)] = shift;
    for (std::size_t side = 0U; side < 2U; ++side) {
      // The limb point of the shifted circle, moved along the silhouette's
      // normal by the offset measured beside it.
      solver::Vec2 limb;
      solver::Vec2 normal;
      if (!silhouette_at(camera, model, frames, s_j + shift, side, limb, normal)) {
        continue;
      }
      // Without enough silhouette beside it (a neighbouring part in front,
      // the image's border) the corner stays the shifted circle's limb
      // point, with the confidence of a predicted one.
      double offset = 0.0;
      bool side_measured = measured && !base;
      if (side_measured && !refiner.silhouette_offset(s_j + shift, side, j, offset)) {
        offset = 0.0;
        side_measured = false;
      }
      const solver::Vec2 corner = limb + offset * normal;
      if (corner.x() < 0.0 || corner.y() < 0.0 || corner.x() > image.width - 1 || corner.y() > image.height - 1) {
        continue;
      }
      Corner& c = e.corners[2U * static_cast<std::size_t>(j) + side];
      c.found = true;
      c.pixel = Point{corner.x(), corner.y()};
      c.confidence = side_measured ? 0.9 : config_.refine_predicted_confidence;
      ++e.corner_count;
    }
  }
  if (e.corner_count == 0) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  return ok_status<VisionError>();
}

void FeatureExtractor::restore_stage4_corners() noexcept {
  if (result_.refined) {
    restore_corners(result_.stage4_corners);
    result_.refined = false;
    result_.boundary_measured.fill(false);  // stage 4 measures no boundary along the model
    result_.boundary_shift_mm.fill(0.0);
  }
}

void FeatureExtractor::restore_snapshot(const CornerSnapshot& snapshot) noexcept {
  restore_corners(snapshot.corners);
  result_.refined = snapshot.refined;
  result_.boundary_measured = snapshot.boundary_measured;
  result_.boundary_shift_mm = snapshot.boundary_shift_mm;
}

void FeatureExtractor::restore_corners(const std::array<Corner, kNumCorners>& corners) noexcept {
  Extraction& e = result_;
  e.corners = corners;
  e.corner_count = 0;
  for (const Corner& c : e.corners) {
    e.corner_count += c.found ? 1 : 0;
  }
}

}  // namespace vision
}  // namespace tcpest
