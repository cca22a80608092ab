// The image fit: the pose fitted to the image around a first pose by robust
// Gauss-Newton on the model's readings (boundary arcs, the tube's, the
// shaft's and the grasper's silhouettes), the first pose from the regions,
// and the insertion from the base's rim (docs/vision.md "Model-guided
// corners", step 1).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "motion_streak.hpp"
#include "refiner.hpp"
#include "fit_scratch.hpp"
#include "robust_step.hpp"
#include "sampling.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

using detail::Rgb;
using detail::sample;
using detail::tukey_cut_px;
using detail::Refiner;
using detail::BoundaryColours;
using detail::Crossing;
using detail::colours_of;
using detail::ceil_within;
using detail::kDsMm;
using detail::kMaxClearReach;
using detail::silhouette_at;
using detail::grasper_silhouette_at;
using detail::shaft_silhouette_at;
using detail::behind_tube_end;
using detail::base_face_visible;

// refine_streak_arc_retry widens an arc's reading where the smear along its
// normal is this long or longer (shorter: the sharp reading's reach holds).
constexpr double kStreakArcMinAlongPx = 3.0;

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

using detail::kFitSilhouetteSamples;
// The shaft's silhouette just before the base (1 to 8.5 mm,
// detail::fit_shaft_back_mm): it fixes the channel axis in the image, which
// the base boundary's corners (never read directly: docs/vision.md) depend on.
using detail::kFitShaftSamples;
// The grasper's silhouette 2 to 9.5 mm past the tip: it holds the tip's
// direction where an occluder or a smear hides the stripes. Not nearer:
// within 1-2 mm of the tip the wider tube's end beside it is read instead.
using detail::kFitGrasperSamples;
constexpr double kFitGrasperFirstMm = 2.0;
constexpr double kFitGrasperStepMm = 1.5;
constexpr int kMaxReadings = detail::kMaxFitReadings;
constexpr int kMaxSmearedReadings = kNumBoundaries * detail::kFitArcSamples;
constexpr int kMaxFitIterations = 20;
constexpr int kCoarseIterations = 3;  // wide-window iterations from a coarse start

// Where a reading's model point is at the frames f.
// `boundary_frames`: the centreline frame at every boundary for f.
bool predict(const solver::CameraModel& camera, const solver::InstrumentModel& model, const solver::PoseFrames& f,
             const std::array<solver::CentrelineFrame, kNumBoundaries>& boundary_frames, const Reading& reading,
             solver::Vec2& pixel) noexcept {
  if (reading.arc) {
    const solver::CentrelineFrame& cf = boundary_frames[static_cast<std::size_t>(reading.boundary)];
    const solver::Vec3 x = cf.position + model.geometry().radius_mm * (dmath::cos(reading.angle_rad) * cf.normal +
                                                                        dmath::sin(reading.angle_rad) * cf.binormal);
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
    return solver::Vec3(c.position + radius_mm * (dmath::cos(angle) * c.normal + dmath::sin(angle) * c.binormal));
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
    for (int i = 0; i < detail::kFitArcSamples; ++i) {
      const double u = -config.refiner.refine_arc_span + 2.0 * config.refiner.refine_arc_span * i / (detail::kFitArcSamples - 1.0);
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
      const int reach = ramp ? std::min(kMaxClearReach, std::max(config.refiner.refine_smear_clear_reach,
                                                                 static_cast<int>(std::ceil(0.5 * along_px)) + 1))
                             : config.refiner.refine_smear_clear_reach;
      const double arc_window_px =
          ramp ? std::max(window_mm * px_per_mm, static_cast<double>(reach) + 2.0) : window_mm * px_per_mm;
      Crossing read = refiner.crossing(p, normal, arc_window_px, colours, reach, tau);
      if (ramp && read == Crossing::kSmeared) {
        read = Crossing::kSharp;  // the frame's smear, read: not one stripe's
      }
      if (colours.margin && read != Crossing::kNone) {
        // The tip arc (j = 0 is not read): under the streak read in an
        // earlier iteration (zero on a sharp frame), refine_smear_tip_bias.
        tau += config.refiner.refine_smear_tip_bias * std::fabs(streak_px.dot(normal));
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
  out.smeared = smeared_count > 0 && all_arcs >= config.refiner.refine_smear_min_arc_readings &&
                static_cast<double>(smeared_count) >= config.refiner.refine_smear_share * static_cast<double>(all_arcs);
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
  double shaft_width_px = std::numeric_limits<double>::quiet_NaN();    // ImageFitSummary::shaft_width_px
  double grasper_width_px = std::numeric_limits<double>::quiet_NaN();  // ImageFitSummary::grasper_width_px
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

// How far outside the model's silhouette `part` was read on both sides
// alike: the mean of the two sides' median offsets (along their outward
// normals), NaN when a side has no reading. Bounded: one pass.
double common_offset_px(Part part, const FitReadings& fit) noexcept {
  std::array<std::array<double, kMaxReadings>, 2> offsets{};
  int counts[2] = {0, 0};
  for (int i = 0; i < fit.count; ++i) {
    const Reading& rd = fit.readings[static_cast<std::size_t>(i)];
    if (!rd.arc && rd.part == part) {
      const std::size_t side = rd.side & 1U;
      offsets[side][static_cast<std::size_t>(counts[side])] = rd.offset_px;
      ++counts[side];
    }
  }
  if (counts[0] == 0 || counts[1] == 0) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return 0.5 * (detail::median_of(offsets[0].data(), counts[0]) + detail::median_of(offsets[1].data(), counts[1]));
}

// Takes the part's learned width off each of its readings (PartWidths).
void take_off_width(Part part, double width_px, FitReadings& fit) noexcept {
  for (int i = 0; i < fit.count; ++i) {
    Reading& rd = fit.readings[static_cast<std::size_t>(i)];
    if (!rd.arc && rd.part == part) {
      rd.offset_px -= width_px;
    }
  }
}

// Silhouette readings at the frames f within edge_window_px: both sides
// along the striped section, the shaft's just before the base up to the
// channel exit (lambda_mm) and the grasper's past the tip (neither counted:
// the striped section must be seen for itself).
SilhouetteReadout read_fit_silhouette(const Refiner& refiner, const ExtractorConfig& config,
                                      const solver::CameraModel& camera, const solver::InstrumentModel& model,
                                      const solver::PoseFrames& f, double edge_window_px, double lambda_mm,
                                      const PartWidths& widths, FitReadings& fit) noexcept {
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
      const double s = detail::fit_silhouette_s_mm(bend_length_mm, i);
      out.readings += read_silhouette(Part::kTube, s, side) ? 1 : 0;
    }
    for (int i = 0; i < kFitShaftSamples && config.refiner.refine_shaft_readings; ++i) {
      const double back = detail::fit_shaft_back_mm(i);
      if (back > lambda_mm - 1.0) {
        break;  // the shaft starts at the channel exit
      }
      static_cast<void>(read_silhouette(Part::kShaft, back, side));  // a missing shaft reading is no failure
    }
    for (int i = 0; i < kFitGrasperSamples && config.refiner.refine_grasper_readings; ++i) {
      const double beyond = kFitGrasperFirstMm + kFitGrasperStepMm * i;
      if (beyond > model.geometry().tcp_offset_mm - 1.0) {
        break;  // the grasper ends at the TCP
      }
      out.grasper += read_silhouette(Part::kGrasper, beyond, side) ? 1 : 0;
    }
  }
  out.shaft_width_px = common_offset_px(Part::kShaft, fit);
  out.grasper_width_px = common_offset_px(Part::kGrasper, fit);
  take_off_width(Part::kShaft, widths.shaft_px(), fit);
  take_off_width(Part::kGrasper, widths.grasper_px(), fit);
  return out;
}

// One robust step of the pose fit from its readings at x: Tukey weights at
// the readings' robust scale (MAD), finite-difference rows, the weak prior
// around `start`. False when the round's problem does not solve. rms_px: the
// weighted residual; largest_move_px: the largest move of a read model point
// along its reading direction under the step (the convergence test).
bool fit_step(const FitReadings& fit, const solver::CameraModel& camera, const solver::InstrumentModel& model,
              const solver::PoseVector& x, const solver::PoseVector& start,
              detail::RobustRows<solver::kNumParams, kMaxReadings>& equations,
              Eigen::Matrix<double, solver::kNumParams, 1>& delta, double& rms_px, double& largest_move_px) noexcept {
  const int n = fit.count;
  std::array<double, kMaxReadings> work{};
  for (int i = 0; i < n; ++i) {
    work[static_cast<std::size_t>(i)] = std::fabs(fit.readings[static_cast<std::size_t>(i)].offset_px);
  }
  equations.start(tukey_cut_px(work.data(), n, 0.3));
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
    if (!equations.add(row, v, w, rd.part != Part::kGrasper)) {
      return false;  // cannot happen: at most kMaxReadings readings, the rows' capacity
    }
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

Status<VisionError> FeatureExtractor::fit_insertion_to_base_rim(const ImageView& image,
                                                                const solver::CameraModel& camera,
                                                                const solver::InstrumentModel& model,
                                                                solver::PoseVector& r) const noexcept {
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  if (!config_.refiner.refine_base_rim) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  const auto& g = model.geometry();
  const double rim_radius = g.shaft_radius_mm + config_.refiner.refine_base_rim_share * (g.radius_mm - g.shaft_radius_mm);
  const double step_mm = config_.refiner.refine_rim_scan_step_mm;
  // Checked at creation: range <= step * kMaxRimScanSteps.
  const int steps = std::min(static_cast<int>(config_.refiner.refine_rim_scan_range_mm / step_mm + 1e-9), kMaxRimScanSteps);
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
      std::min(std::max(config_.refiner.refine_fit_iterations, 1) + (coarse_start ? kCoarseIterations : 0), kMaxFitIterations);
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
        coarse_it ? config_.refiner.refine_coarse_search_mm : (fine_it == 0 ? config_.refiner.refine_search_mm : 0.6);
    const double edge_window_px = coarse_it ? config_.refiner.refine_coarse_edge_search_px : config_.refiner.refine_edge_search_px;
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
    const bool unsmeared_read = config_.refiner.refine_streak_unsmeared && !summary.smeared && !coarse_it &&
                                boundaries >= config_.refiner.refine_streak_unsmeared_min_boundaries;
    if ((summary.smeared || unsmeared_read) && config_.refiner.refine_streak && !streak_tried) {
      streak_tried = true;
      const double min_px = summary.smeared ? config_.refiner.refine_streak_min_px : config_.refiner.refine_streak_unsmeared_min_px;
      if (!detail::read_streak(image, config_, camera, model, f, streak_px) || !(streak_px.norm() >= min_px)) {
        streak_px = solver::Vec2::Zero();
      }
    }
    summary.streak_px = streak_px;
    refiner.use_streak(summary.streak_px);
    const SilhouetteReadout silhouette =
        read_fit_silhouette(refiner, config_, camera, model, f, edge_window_px, x[solver::kLambda], part_widths_, fit);
    summary.iterations = it + 1;
    summary.arc_readings = arcs.readings;
    summary.silhouette_readings = silhouette.readings;
    summary.grasper_readings = silhouette.grasper;
    summary.plain_silhouette_readings = silhouette.plain;
    summary.shaft_width_px = silhouette.shaft_width_px;
    summary.grasper_width_px = silhouette.grasper_width_px;
    summary.boundaries = boundaries;
    summary.boundary_run = boundary_run;
    // A fine iteration needs 2 boundaries' arcs, and no silhouette reading:
    // the arcs and the shaft hold the tube where a smear or an occluder
    // hides its silhouette (the caller decides what such a fit may give,
    // GuidedOptions); or 1 boundary's arcs with the silhouette well read
    // (refine_one_boundary_min_silhouette: an occluder hiding the others).
    // A coarse one, from a rough seed, needs the silhouette.
    const bool arcs_hold = boundaries >= 2 ||
                           (boundaries == 1 && silhouette.plain >= config_.refiner.refine_one_boundary_min_silhouette);
    if (!coarse_it && !arcs_hold && !widen_arcs &&
        detail::streak_for_arc_retry(image, config_, camera, model, f, streak_px)) {
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
    if (!fit_step(fit, camera, model, x, start, fit_scratch_->image_fit, delta, rms, largest_move_px)) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
    x += delta;
    // Converged when the step moves no model point read by more than
    // refine_fit_tolerance_px along its reading direction.
    if (largest_move_px < config_.refiner.refine_fit_tolerance_px && !coarse_it) {
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

void PartWidths::Window::add(double px) noexcept {
  if (!std::isfinite(px) || std::fabs(px) > kMaxWidthPx) {
    return;  // not read on both sides, or no silhouette of the part
  }
  values_[next_] = px;
  next_ = (next_ + 1) % kWindow;
  count_ = std::min(count_ + 1, kWindow);
  learned_px_ = median_px();
}

double PartWidths::Window::median_px() const noexcept {
  if (count_ < kMinFrames) {
    return 0.0;
  }
  const int n = std::min(count_, kWindow);  // count_ never exceeds the window
  double work[kWindow] = {};
  std::copy(values_, values_ + n, work);
  const double median = detail::median_of(work, n);
  // Only a width the frames agree on: the median beyond kAgreement of its
  // standard errors (the MAD's scale over the square root of the frames).
  for (int i = 0; i < n; ++i) {
    work[i] = std::fabs(values_[i] - median);
  }
  const double standard_error = detail::kMadToSigma * detail::median_of(work, n) / std::sqrt(static_cast<double>(n));
  return std::fabs(median) > kAgreement * standard_error ? median : 0.0;
}

void PartWidths::learn(const ImageFitSummary& fit) noexcept {
  shaft_.add(fit.shaft_width_px);
  grasper_.add(fit.grasper_width_px);
}

}  // namespace vision
}  // namespace tcpest
