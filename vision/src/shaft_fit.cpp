// The channel's pose fitted to the shaft's silhouette before the base
// (docs/vision.md "The channel's pose from the shaft").
#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>

#include "fit_scratch.hpp"
#include "refiner.hpp"
#include "robust_step.hpp"
#include "sampling.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

using detail::Rgb;
using detail::sample;
using detail::to_byte;
using detail::tukey_cut_px;
using detail::Refiner;
using detail::ceil_within;
using detail::shaft_silhouette_at;

using detail::kShaftSamples;
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
using detail::kMaxShaftReadings;

double chroma_at(const ImageView& image, const solver::Vec2& p, bool& ok) noexcept {
  Rgb c;
  ok = sample(image, p.x(), p.y(), c);
  if (!ok) {
    return 0.0;
  }
  const Lab lab = srgb_to_lab(to_byte(c.r), to_byte(c.g), to_byte(c.b));
  return dmath::hypot(lab.a, lab.b);
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
  return std::min(kShaftNeutralChroma, std::max(kShaftNeutralFloor, kShaftNeutralShare * detail::median_of(chroma.data(), n)));
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
using detail::kShaftParams;
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
// `start`): the channel's pose change. False when the round's problem does
// not solve; rms_px: the weighted residual.
bool shaft_step(const ShaftReadings& readings, const solver::CameraModel& camera,
                const solver::InstrumentModel& model, const solver::PoseVector& x, const solver::PoseVector& start,
                detail::RobustRows<kShaftParams, kMaxShaftReadings>& equations,
                Eigen::Matrix<double, kShaftParams, 1>& delta, double& rms_px) noexcept {
  const int n = readings.count;
  std::array<double, kMaxShaftReadings> work{};
  for (int i = 0; i < n; ++i) {
    work[static_cast<std::size_t>(i)] = std::fabs(readings.offsets[static_cast<std::size_t>(i)]);
  }
  equations.start(tukey_cut_px(work.data(), n, 1.0));
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
    if (!equations.add(row, readings.offsets[q], w)) {
      return false;  // cannot happen: at most kMaxShaftReadings readings, the rows' capacity
    }
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
    if (!shaft_step(readings, camera, model, x, start, fit_scratch_->shaft_fit, delta, rms)) {
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

}  // namespace vision
}  // namespace tcpest
