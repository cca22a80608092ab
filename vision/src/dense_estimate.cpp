#include "tcpest/vision/dense_estimate.hpp"

#include <algorithm>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {

using solver::PoseVector;
using solver::Vec2;

namespace {

struct Candidate {
  PoseVector r = PoseVector::Zero();
  Vec2 streak = Vec2::Zero();
  double cost = 0.0;
};

// Insertion sort by cost (a handful of candidates).
void sort_by_cost(Candidate* c, int n) noexcept {
  for (int i = 1; i < n; ++i) {
    for (int j = i; j > 0 && c[j].cost < c[j - 1].cost; --j) {
      const Candidate t = c[j];
      c[j] = c[j - 1];
      c[j - 1] = t;
    }
  }
}

// The starts: the pipeline's poses, the start pose and its variants (at
// most kMaxDenseStarts - kMaxDenseScreenKeep: 2 seeds, the start, 6 + 4
// variants; the screen's come after).
int collect_starts(const PoseVector* seeds, int nseeds, const PoseVector& start, const DenseOptions& options,
                   PoseVector* starts) noexcept {
  int n = 0;
  for (int i = 0; i < nseeds; ++i) {
    if (seeds[i].allFinite()) {
      starts[n++] = seeds[i];
    }
  }
  if (start.allFinite()) {
    starts[n++] = start;
    if (options.start_variants) {
      for (int d = -1; d <= 1; d += 2) {
        PoseVector q = start;
        q[solver::kLambda] += d * options.lambda_step_mm;
        starts[n++] = q;
        q = start;
        q[solver::kTheta] += d * options.bend_step_rad;
        starts[n++] = q;
        q = start;
        q[solver::kPhi] += d * options.bend_step_rad;
        starts[n++] = q;
      }
    }
    if (options.channel_variants) {
      for (int d = -1; d <= 1; d += 2) {
        PoseVector q = start;
        q[solver::kXch] += d * options.channel_step_mm;
        starts[n++] = q;
        q = start;
        q[solver::kYch] += d * options.channel_step_mm;
        starts[n++] = q;
      }
    }
  }
  return n;
}

// The coarse region's poses: the starts' and, with the screen, the start's
// channel moved to the screen's extremes in x and y, and tilted to its
// extremes in psi and mu when the screen tilts (kScreenReachPoses).
constexpr int kScreenReachPoses = 8;
int coarse_region(const PoseVector* starts, int n, const PoseVector& start, bool screen,
                  const DenseOptions& options, PoseVector* region) noexcept {
  int nr = 0;
  for (int i = 0; i < n; ++i) {
    region[nr++] = starts[i];
  }
  if (screen) {
    const bool tilt = options.screen_tilt_rad > 0.0;
    for (int d = -1; d <= 1; d += 2) {
      const double shift_mm = d * options.screen_channel_mm;
      PoseVector q = start;
      q[solver::kXch] += shift_mm;
      region[nr++] = q;
      q = start;
      q[solver::kYch] += shift_mm;
      region[nr++] = q;
      if (tilt) {
        q = start;
        q[solver::kPsi] += d * options.screen_tilt_rad;
        region[nr++] = q;
        q = start;
        q[solver::kMu] += d * options.screen_tilt_rad;
        region[nr++] = q;
      }
    }
  }
  return nr;
}

// `c` into the `keep` cheapest so far, sorted by cost (on a tie the
// earlier stays first; a costlier one than all `keep` is not kept).
void keep_cheapest(const Candidate& c, Candidate* best, int keep, int& count) noexcept {
  int at = count;
  while (at > 0 && c.cost < best[at - 1].cost) {
    --at;
  }
  if (at >= keep) {
    return;
  }
  const int last = count < keep ? count : keep - 1;
  for (int j = last; j > at; --j) {
    best[j] = best[j - 1];
  }
  best[at] = c;
  if (count < keep) {
    ++count;
  }
}

// The screen: the cost alone at the start's channel and insertion moved
// (and its channel tilted, with screen_tilt_rad) on a small grid; the
// `keep` cheapest appended to `starts` (n updated).
void screen_starts(DenseFit& fit, const PoseVector& start, const Vec2& streak0, const DenseOptions& options,
                   PoseVector* starts, int& n) noexcept {
  constexpr int kChannelSteps = 1;  // -1..1 in x and in y
  constexpr int kLambdaSteps = 2;   // -2..2
  const int tilt_steps = options.screen_tilt_rad > 0.0 ? 1 : 0;
  const int keep = std::clamp(options.screen_keep, 0, kMaxDenseScreenKeep);
  Candidate best[kMaxDenseScreenKeep];
  int nb = 0;
  for (int ix = -kChannelSteps; ix <= kChannelSteps; ++ix) {
    for (int iy = -kChannelSteps; iy <= kChannelSteps; ++iy) {
      for (int ip = -tilt_steps; ip <= tilt_steps; ++ip) {
        for (int im = -tilt_steps; im <= tilt_steps; ++im) {
          for (int il = -kLambdaSteps; il <= kLambdaSteps; ++il) {
            if (ix == 0 && iy == 0 && ip == 0 && im == 0 && il == 0) {
              continue;  // the start itself is fitted anyway
            }
            Candidate c;
            c.r = start;
            c.r[solver::kXch] += ix * options.screen_channel_mm;
            c.r[solver::kYch] += iy * options.screen_channel_mm;
            c.r[solver::kPsi] += ip * options.screen_tilt_rad;
            c.r[solver::kMu] += im * options.screen_tilt_rad;
            c.r[solver::kLambda] += il * options.screen_lambda_mm;
            c.streak = streak0;
            PoseVector r = c.r;
            const DenseFitSummary s = fit.fit(r, c.streak, 0, false, true);
            if (s.ok) {
              c.cost = s.cost;
              keep_cheapest(c, best, keep, nb);
            }
          }
        }
      }
    }
  }
  for (int i = 0; i < nb && n < kMaxDenseStarts; ++i) {
    starts[n++] = best[i].r;
  }
}

// Every start fitted coarsely in the region set; sorted by cost.
int coarse_fits(DenseFit& fit, const PoseVector* starts, int n, const Vec2& streak0, const DenseOptions& options,
                Candidate* out) noexcept {
  int nc = 0;
  for (int i = 0; i < n; ++i) {
    Candidate c;
    c.r = starts[i];
    c.streak = streak0;
    const DenseFitSummary s = fit.fit(c.r, c.streak, options.coarse_iterations, false, true);
    if (s.ok) {
      c.cost = s.cost;
      out[nc++] = c;
    }
  }
  sort_by_cost(out, nc);
  return nc;
}

// The streak screen (DenseOptions::streak_screen_directions): a candidate
// without a streak takes the cheapest streak of the grid at its pose,
// when cheaper than none; its cost is then the screened one. No streak
// is evaluated the same way (no iteration) rather than taken from the
// coarse fit's cost, so that the costs compare.
void screen_streak(DenseFit& fit, const DenseOptions& options, Candidate& c) noexcept {
  if (options.streak_screen_directions <= 0 || c.streak.norm() > DenseFit::kMinStreakPx) {
    return;
  }
  PoseVector r = c.r;
  Vec2 none = Vec2::Zero();
  const DenseFitSummary at_none = fit.fit(r, none, 0, false, true);
  if (!at_none.ok) {
    return;
  }
  double best_cost = at_none.cost;
  Vec2 best = Vec2::Zero();
  const int lengths = options.streak_screen_lengths;
  for (int il = 0; il < lengths; ++il) {
    const double length_px =
        lengths > 1 ? options.streak_screen_min_px +
                          (options.streak_screen_max_px - options.streak_screen_min_px) * il / (lengths - 1)
                    : options.streak_screen_min_px;
    for (int id = 0; id < options.streak_screen_directions; ++id) {
      const double angle_rad = solver::kPi * id / options.streak_screen_directions;
      Vec2 streak(length_px * dmath::cos(angle_rad), length_px * dmath::sin(angle_rad));
      r = c.r;
      const DenseFitSummary s = fit.fit(r, streak, 0, false, true);
      if (s.ok && s.cost < best_cost) {
        best_cost = s.cost;
        best = streak;
      }
    }
  }
  c.streak = best;
  c.cost = best_cost;
}

// The softest steps: the fine stage's winner moved by -/+ its softest
// step (DenseFit::softest_step), each fitted finely; a lower cost replaces
// the winner. The failing frames' tubes are slid along themselves with
// every parameter compensating, which a fixed hop along the insertion
// alone does not follow (docs/vision.md, "The dense stage").
void softest_steps(DenseFit& fit, const DenseOptions& options, Candidate& best) noexcept {
  if (!(options.softest_step_px > 0.0)) {
    return;
  }
  PoseVector step;
  if (!fit.softest_step(best.r, best.streak, options.softest_step_px, step)) {
    return;  // no corner in the image or no factorisation: the winner stays
  }
  const Candidate from = best;
  for (int d = -1; d <= 1; d += 2) {
    Candidate c = from;
    c.r += d * step;
    const DenseFitSummary s = fit.fit(c.r, c.streak, options.fine_iterations, false, true);
    if (s.ok && s.cost < best.cost) {
      c.cost = s.cost;
      best = c;
    }
  }
}

// Clears the fit's encoder box when the search ends.
struct BoxCleared {
  DenseFit& fit;
  BoxCleared(const BoxCleared&) = delete;
  BoxCleared& operator=(const BoxCleared&) = delete;
  BoxCleared(BoxCleared&&) = delete;
  BoxCleared& operator=(BoxCleared&&) = delete;
  ~BoxCleared() { fit.set_encoder_box(EncoderBox{}); }
};

}  // namespace

bool dense_options_valid(const DenseOptions& options) noexcept {
  const auto pixels_ok = [](int n) noexcept { return n >= 256 && n <= (1 << 20); };
  const auto iterations_ok = [](int n) noexcept { return n >= 1 && n <= 100; };
  return pixels_ok(options.coarse_pixels) && pixels_ok(options.fine_pixels) &&
         iterations_ok(options.coarse_iterations) && iterations_ok(options.fine_iterations) &&
         options.fine_candidates >= 0 && options.fine_candidates <= kMaxDenseFineCandidates &&
         options.coarse_smoothing >= 0 && options.coarse_smoothing <= 8 &&
         options.lambda_step_mm > 0.0 && options.lambda_step_mm <= 10.0 && options.bend_step_rad > 0.0 &&
         options.bend_step_rad <= 1.0 && options.channel_step_mm > 0.0 && options.channel_step_mm <= 5.0 &&
         options.min_corner_support >= 0.0 && options.min_corner_support <= 1.0 &&
         options.max_measured_corners >= 0 && options.max_measured_corners <= kNumCorners &&
         options.max_measured_corners_valid >= -1 && options.max_measured_corners_valid <= kNumCorners &&
         options.screen_keep >= 0 && options.screen_keep <= kMaxDenseScreenKeep && options.screen_tilt_rad >= 0.0 &&
         options.screen_tilt_rad <= 0.3 && options.screen_channel_mm > 0.0 &&
         options.screen_channel_mm <= 5.0 && options.screen_lambda_mm > 0.0 && options.screen_lambda_mm <= 5.0 &&
         options.softest_step_px >= 0.0 && options.softest_step_px <= 20.0 &&
         options.streak_screen_directions >= 0 && options.streak_screen_directions <= 36 &&
         options.streak_screen_lengths >= 1 && options.streak_screen_lengths <= 8 &&
         options.streak_screen_min_px > DenseFit::kMinStreakPx &&
         options.streak_screen_max_px >= options.streak_screen_min_px &&
         options.streak_screen_max_px <= 20.0 && options.max_valid_tcp_change_mm >= 0.0 &&
         options.max_valid_tcp_change_mm <= 10.0 && options.pipeline_corner_weight >= 0.0 &&
         options.pipeline_corner_weight <= 1.0 && options.pipeline_corner_gate_px > 0.0 &&
         options.pipeline_corner_gate_px <= 20.0 && options.encoder_box_lambda_mm >= 0.0 &&
         options.encoder_box_lambda_mm <= 10.0 && options.encoder_box_angle_rad >= 0.0 &&
         options.encoder_box_angle_rad <= 1.0;
}

void blend_pipeline_corners(std::array<Corner, kNumCorners>& dense, const std::array<Corner, kNumCorners>& pipeline,
                            const DenseOptions& options) noexcept {
  const double weight = options.pipeline_corner_weight;
  const double gate_px = options.pipeline_corner_gate_px;
  for (std::size_t k = 0; k < dense.size(); ++k) {
    Corner& d = dense[k];
    const Corner& p = pipeline[k];
    if (!d.found || !p.found) {
      continue;
    }
    const double du = p.pixel.x - d.pixel.x;
    const double dv = p.pixel.y - d.pixel.y;
    // NaN compares false: a non-finite pixel is never within the gate.
    if (du * du + dv * dv < gate_px * gate_px) {
      d.pixel.x += weight * du;
      d.pixel.y += weight * dv;
    }
  }
}

DenseResult dense_estimate(DenseFit& fit, const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const ImageView& image, const PoseVector* seeds, int seed_count, const PoseVector& start,
                           const PoseVector* encoders, const Vec2& streak_px, const DenseOptions& options) noexcept {
  DenseResult result;
  // Every fit below holds its pose within the encoders' box (none without them).
  EncoderBox box;
  if (encoders != nullptr) {
    box.encoders = *encoders;
    box.lambda_tolerance_mm = options.encoder_box_lambda_mm;
    box.angle_tolerance_rad = options.encoder_box_angle_rad;
  }
  fit.set_encoder_box(box);
  const BoxCleared cleared{fit};  // and none after, whichever way this returns
  const int nseeds = seed_count < 0 ? 0 : (seed_count > kMaxDenseSeeds ? kMaxDenseSeeds : seed_count);
  PoseVector starts[kMaxDenseStarts];
  int n = collect_starts(seeds, nseeds, start, options, starts);
  if (n == 0) {
    return result;
  }
  const Vec2 streak0 = streak_px.allFinite() ? streak_px : Vec2::Zero();
  // Coarse: every start on a small work image over all of them (with the
  // screen: and over the channel's reach, the screen's starts added).
  const bool screen = options.screen_keep > 0 && start.allFinite();
  PoseVector coarse_poses[kMaxDenseStarts + kScreenReachPoses];
  const int nr = coarse_region(starts, n, start, screen, options, coarse_poses);
  Candidate coarse[kMaxDenseStarts];
  int nc = 0;
  if (fit.set_region(image, coarse_poses, nr, streak0.norm(), options.coarse_pixels, options.coarse_smoothing).ok()) {
    if (screen) {
      screen_starts(fit, start, streak0, options, starts, n);
    }
    nc = coarse_fits(fit, starts, n, streak0, options, coarse);
  }
  Candidate fine[kMaxDenseFineCandidates + kMaxDenseSeeds];
  int nf = 0;
  const int keep =
      options.fine_candidates < kMaxDenseFineCandidates ? options.fine_candidates : kMaxDenseFineCandidates;
  double region_streak_px = streak0.norm();
  for (int i = 0; i < nc && i < keep; ++i) {
    screen_streak(fit, options, coarse[i]);
    region_streak_px = std::max(region_streak_px, coarse[i].streak.norm());
    fine[nf++] = coarse[i];
  }
  // Fine: the best coarse results and the pipeline's own poses as they are.
  if (nseeds > 0 && seeds[0].allFinite()) {
    fine[nf].r = seeds[0];
    fine[nf].streak = streak0;
    ++nf;
  }
  PoseVector region[kMaxDenseFineCandidates + kMaxDenseSeeds];
  for (int i = 0; i < nf; ++i) {
    region[i] = fine[i].r;
  }
  if (nf == 0 || !fit.set_region(image, region, nf, region_streak_px, options.fine_pixels, 0).ok()) {
    return result;
  }
  bool have = false;
  Candidate best;
  for (int i = 0; i < nf; ++i) {
    Candidate c = fine[i];
    const DenseFitSummary s = fit.fit(c.r, c.streak, options.fine_iterations, false, true);
    if (s.ok && (!have || s.cost < best.cost)) {
      c.cost = s.cost;
      best = c;
      have = true;
    }
  }
  if (!have) {
    return result;
  }
  softest_steps(fit, options, best);
  // Once more from the best, so that the responsibilities are its own.
  result.fit = fit.fit(best.r, best.streak, 3, false, true);
  if (!result.fit.ok) {
    return result;
  }
  result.ok = true;
  result.r = best.r;
  result.streak_px = best.streak;
  fit.corner_support(best.r, best.streak, result.support);
  solver::CornerSet corners;
  model.corners(camera, best.r, corners);
  for (std::size_t k = 0; k < static_cast<std::size_t>(kNumCorners); ++k) {
    if (corners.in_image[k] && result.support[k] >= options.min_corner_support) {
      result.corners[k].found = true;
      result.corners[k].pixel = Point{corners.pixel[k].x(), corners.pixel[k].y()};
      result.corners[k].confidence = result.support[k];
      ++result.corner_count;
    }
  }
  return result;
}

}  // namespace vision
}  // namespace tcpest
