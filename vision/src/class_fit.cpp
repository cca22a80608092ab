// A coarse pose from the class image (ours): chamfer matching of the model's
// stripes onto the blue and yellow pixels. It needs neither the labelling of
// stage 2 nor the borders of stage 3, so it serves the views those stages
// cannot: a tube seen nearly end-on (stripes a few pixels long), markers
// that touch in the image and form one region, a reversed labelling. It only
// brings a seed (the encoders' pose, or the regions' rough pose) close
// enough for the image fit (fit_pose_to_image), which then decides.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "fit_scratch.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/solver/numeric_diff.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

namespace {

// "No pixel of the class near": larger than any capped distance (x3), and
// small enough that adding a step cannot overflow.
constexpr std::uint16_t kFar = 4000U;
constexpr int kStepsAlong = detail::kClassStepsAlong;
constexpr int kStepsAround = detail::kClassStepsAround;
constexpr int kMaxSamples = detail::kClassMaxSamples;
constexpr double kMinSamples = 20.0;  // facing samples in the image (summed weights), at least
constexpr double kFacingMin = 0.0;   // -n . view: a sample's weight rises from 0 here ...
constexpr double kFacingRamp = 0.25; // ... to 1 this much higher (facing the camera)
constexpr double kCapPx = 60.0;     // a sample farther than this from its colour counts as this far
constexpr double kFineCapPx = 15.0; // ... and in the second descent (occluded stripes)
constexpr double kPriorWeightPx = 3.0;  // residual of one prior standard deviation
constexpr int kGridPoints = 3;              // per axis of the coarse look around the seed
constexpr double kGridLambdaMm = 2.5;
constexpr double kGridAngleRad = 0.15;
// The other direction: coloured pixels of the class image (a grid sample)
// should lie near a sample of their colour. Without it, a pose that moves
// the instrument away (smaller in the image, inside its regions) would cost
// nothing. Capped, so that colour far from the model (tissue, a decoy) has
// no pull.
constexpr int kMaxCoverage = detail::kClassMaxCoverage;
constexpr double kCoverageCapPx = 15.0;
// The channel's pose known from the shaft: its prior's standard deviations.
constexpr double kKnownChannelSdMm = 0.5;
constexpr double kKnownChannelSdRad = 0.03;

int colour_index(PixelClass c) noexcept { return c == PixelClass::Yellow ? 1 : 0; }

constexpr int kParams = detail::kClassParams;
constexpr int kRows = detail::kClassRows;
using ClassResiduals = Eigen::Matrix<double, kRows, 1>;
// Difference steps of about a pixel: the distance image is piecewise linear.
constexpr std::array<double, kParams> kStepH = {0.05, 0.05, 0.002, 0.002, 0.05, 0.004, 0.004};
// Each descent: Marquardt's damping schedule (the cost is piecewise linear:
// the gain ratio says little about the next step), the numeric Jacobian
// only at the trials taken, at most
// kClassFitIterations + 4 trial steps (six rejected in a row end it); it
// ends where a step lowers the cost by less than 0.1 %.
constexpr solver::SolverOptions kClassSolve{FeatureExtractor::kClassFitIterations + 4, 1e-10, 1e-10, 1e-3, 1e-2,
                                            solver::DampingSchedule::kMarquardt,
                                            solver::JacobianEvaluation::kWhenTaken};

// Coverage points: the class image's coloured pixels on a grid whose step
// gives at most about kMaxCoverage of them (from the regions' total area).
struct Coverage {
  std::array<solver::Vec2, kMaxCoverage> at{};
  std::array<int, kMaxCoverage> colour{};  // colour_index
  int count = 0;
};

Coverage coverage_points(const RegionSet& regions, const std::uint8_t* cls, int width, int height) noexcept {
  Coverage out;
  double coloured = 0.0;
  for (const Region& region : regions.regions) {
    coloured += static_cast<double>(region.area);
  }
  const int step = std::max(2, static_cast<int>(std::ceil(1.2 * std::sqrt(coloured / kMaxCoverage))));
  for (int y = step / 2; y < height && out.count < kMaxCoverage; y += step) {
    for (int x = step / 2; x < width && out.count < kMaxCoverage; x += step) {
      const std::uint8_t c =
          cls[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)];
      if (c == static_cast<std::uint8_t>(PixelClass::Blue) || c == static_cast<std::uint8_t>(PixelClass::Yellow)) {
        out.at[static_cast<std::size_t>(out.count)] = solver::Vec2(x, y);
        out.colour[static_cast<std::size_t>(out.count)] = colour_index(static_cast<PixelClass>(c));
        ++out.count;
      }
    }
  }
  return out;
}

// Stripe sample i at the frames f: a point on the tube's surface (3 along
// each stripe, 12 around), its outward normal, and its marker's index.
int stripe_sample(const solver::InstrumentModel& model, const solver::PoseFrames& f, int i, solver::Vec3& point,
                  solver::Vec3& normal) noexcept {
  const auto& g = model.geometry();
  const int m = i / (kStepsAlong * kStepsAround);
  const int along = (i / kStepsAround) % kStepsAlong;
  const int around = i % kStepsAround;
  const double s0 = g.boundaries_mm[static_cast<std::size_t>(m)];
  const double s1 = g.boundaries_mm[static_cast<std::size_t>(m) + 1U];
  const double s = s0 + (s1 - s0) * (0.2 + 0.3 * along);
  const double a = 6.283185307179586 * around / kStepsAround;
  const solver::CentrelineFrame c = model.centreline(f, s);
  normal = dmath::cos(a) * c.normal + dmath::sin(a) * c.binormal;
  point = c.position + g.radius_mm * normal;
  return m;
}

// A coarse look around the seed r (the encoders' joints are off by up to a
// few mm and 0.2 rad): the best of a 3 x 3 x 3 grid in lambda, phi and
// theta, by the mean residual per sample (a pose that shows fewer samples
// is not cheaper for that) plus the prior's rows as they are. 27
// evaluations of the cost, no derivatives. False when no grid pose shows
// kMinSamples.
template <typename Cost>
bool coarse_grid_start(const Cost& residuals, const solver::PoseVector& r, solver::PoseVector& x) noexcept {
  double cost = 0.0;
  bool have_start = false;
  for (int g_index = 0; g_index < kGridPoints * kGridPoints * kGridPoints; ++g_index) {
    // The grid index's three digits (base kGridPoints), each -1, 0 or +1.
    const int digit_lambda = g_index % kGridPoints - 1;
    const int digit_phi = (g_index / kGridPoints) % kGridPoints - 1;
    const int digit_theta = g_index / (kGridPoints * kGridPoints) - 1;
    solver::PoseVector trial = r;
    trial[solver::kLambda] += kGridLambdaMm * static_cast<double>(digit_lambda);
    trial[solver::kPhi] += kGridAngleRad * static_cast<double>(digit_phi);
    trial[solver::kTheta] += kGridAngleRad * static_cast<double>(digit_theta);
    ClassResiduals et;
    double wt = 0.0;
    residuals(trial, et, wt);
    const double trial_cost = et.head(kMaxSamples + kMaxCoverage).squaredNorm() / std::max(wt, 1.0) +
                              et.tail(kParams).squaredNorm() / kMaxSamples;
    if (wt >= kMinSamples && (!have_start || trial_cost < cost)) {
      have_start = true;
      cost = trial_cost;
      x = trial;
    }
  }
  return have_start;
}

// A descent of the residuals from x on the minimiser (forward differences).
// A pose that shows fewer than kMinSamples facing samples is outside the
// fit's domain: a trial there is a failed step (the residuals are defined
// there, so a difference step may land there). False when the descent
// could not start or broke down (non-finite values, a singular system).
template <typename Cost>
bool descend(const Cost& residuals, solver::LevenbergMarquardt<kParams, kRows>& lm, solver::PoseVector& x) noexcept {
  auto shows_enough = [&residuals](const solver::PoseVector& at, ClassResiduals& out) noexcept {
    double weight_sum = 0.0;
    residuals(at, out, weight_sum);
    return weight_sum >= kMinSamples ? solver::Evaluation::kAcceptable : solver::Evaluation::kDefinedOnly;
  };
  auto problem = solver::make_forward_difference<kParams, kRows>(shows_enough, kStepH);
  return solver::ended_at_a_point(lm.minimise(problem, x, kClassSolve).status);
}

}  // namespace

void FeatureExtractor::compute_class_distances() noexcept {
  const int width = regions_->width();
  const int height = regions_->height();
  // Only where a distance below the cap can occur: the coloured regions'
  // bounding box grown by the cap. Outside it every distance is capped.
  int x0 = width, y0 = height, x1 = -1, y1 = -1;
  for (const Region& region : result_.regions.regions) {
    x0 = std::min(x0, region.x_min);
    y0 = std::min(y0, region.y_min);
    x1 = std::max(x1, region.x_max);
    y1 = std::max(y1, region.y_max);
  }
  class_distance_ready_ = true;
  if (x1 < 0) {
    distance_box_ = {0, 0, -1, -1};  // no coloured region: an empty box, every distance capped
    return;
  }
  const int margin = static_cast<int>(kCapPx) + 2;
  distance_box_ = {std::max(0, x0 - margin), std::max(0, y0 - margin), std::min(width - 1, x1 + margin),
                   std::min(height - 1, y1 + margin)};
  const int bx0 = distance_box_[0], by0 = distance_box_[1], bx1 = distance_box_[2], by1 = distance_box_[3];
  const auto w = static_cast<std::size_t>(width);
  // Both colours in the same sweep: the class image is read once, and the
  // two distance images' dependency chains (each pixel on its left
  // neighbour) run side by side. Forward pass (left, up-left, up,
  // up-right), then backward (right, down-right, down, down-left): the
  // 3-4 chamfer distance.
  std::uint16_t* const blue = class_distance_[0].get();
  std::uint16_t* const yellow = class_distance_[1].get();
  const auto want_blue = static_cast<std::uint8_t>(PixelClass::Blue);
  const auto want_yellow = static_cast<std::uint8_t>(PixelClass::Yellow);
  // One pixel's chamfer step from its four already-swept neighbours
  // (`along` the sweep's row, `n0`-`n2` in the row swept before; nullptr
  // at the box's edge).
  const auto relax = [](std::uint16_t v, const std::uint16_t* along, const std::uint16_t* n0,
                        const std::uint16_t* n1, const std::uint16_t* n2) noexcept {
    if (v == 0U) {
      return v;
    }
    if (along != nullptr) {
      v = std::min(v, static_cast<std::uint16_t>(*along + 3U));
    }
    if (n1 != nullptr) {
      v = std::min(v, static_cast<std::uint16_t>(*n1 + 3U));
    }
    if (n0 != nullptr) {
      v = std::min(v, static_cast<std::uint16_t>(*n0 + 4U));
    }
    if (n2 != nullptr) {
      v = std::min(v, static_cast<std::uint16_t>(*n2 + 4U));
    }
    return v;
  };
  for (int y = by0; y <= by1; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * w;
    const std::uint8_t* cls = regions_->class_image() + row;
    const bool has_up = y > by0;
    for (int x = bx0; x <= bx1; ++x) {
      const auto at = row + static_cast<std::size_t>(x);
      const bool left = x > bx0;
      const bool right = x < bx1;
      for (std::uint16_t* d : {blue, yellow}) {
        const std::uint8_t want = d == blue ? want_blue : want_yellow;
        const std::uint16_t start = cls[x] == want ? std::uint16_t{0} : kFar;
        d[at] = relax(start, left ? &d[at - 1U] : nullptr, has_up && left ? &d[at - w - 1U] : nullptr,
                      has_up ? &d[at - w] : nullptr, has_up && right ? &d[at - w + 1U] : nullptr);
      }
    }
  }
  for (int y = by1; y >= by0; --y) {
    const std::size_t row = static_cast<std::size_t>(y) * w;
    const bool has_down = y < by1;
    for (int x = bx1; x >= bx0; --x) {
      const auto at = row + static_cast<std::size_t>(x);
      const bool left = x > bx0;
      const bool right = x < bx1;
      for (std::uint16_t* d : {blue, yellow}) {
        d[at] = relax(d[at], right ? &d[at + 1U] : nullptr, has_down && right ? &d[at + w + 1U] : nullptr,
                      has_down ? &d[at + w] : nullptr, has_down && left ? &d[at + w - 1U] : nullptr);
      }
    }
  }
}

double FeatureExtractor::class_distance_px(int colour, double x, double y) const noexcept {
  if (!(x >= distance_box_[0]) || !(y >= distance_box_[1]) || !(x < distance_box_[2]) || !(y < distance_box_[3])) {
    return kCapPx;  // outside the box every distance is capped (and the box may be empty)
  }
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const double fx = x - x0;
  const double fy = y - y0;
  const std::uint16_t* d = class_distance_[static_cast<std::size_t>(colour)].get();
  const auto v = [&](int xx, int yy) noexcept {
    return static_cast<double>(
        d[static_cast<std::size_t>(yy) * static_cast<std::size_t>(regions_->width()) + static_cast<std::size_t>(xx)]);
  };
  const double value = (1.0 - fy) * ((1.0 - fx) * v(x0, y0) + fx * v(x0 + 1, y0)) +
                       fy * ((1.0 - fx) * v(x0, y0 + 1) + fx * v(x0 + 1, y0 + 1));
  return std::min(value / 3.0, kCapPx);
}

Status<VisionError> FeatureExtractor::fit_pose_to_classes(const solver::CameraModel& camera,
                                                          const solver::InstrumentModel& model, solver::PoseVector& r,
                                                          double& cost_px, bool channel_known) noexcept {
  if (regions_->width() < 2 || regions_->height() < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  if (!class_distance_ready_) {
    compute_class_distances();
  }
  const solver::PoseVector start = r;
  // With the channel's pose from the shaft (fit_channel_to_shaft), it is
  // held within about that fit's accuracy.
  const double channel_mm = channel_known ? kKnownChannelSdMm : 3.0;
  const double channel_rad = channel_known ? kKnownChannelSdRad : 0.1;
  const double prior_sd[kParams] = {channel_mm, channel_mm, channel_rad, channel_rad, 5.0, 0.5, 0.5};
  const Coverage coverage =
      coverage_points(result_.regions, regions_->class_image(), regions_->width(), regions_->height());
  // Every sample counts with a weight that grows from 0 where the surface
  // grazes the line of sight to 1 where it faces the camera: a smooth cost,
  // whatever the view (a tube seen end-on shows only grazing surface).
  std::array<solver::Vec2, kMaxSamples> projected{};
  std::array<int, kMaxSamples> projected_colour{};
  double cap_px = kCapPx;
  const auto residuals = [&](const solver::PoseVector& at, ClassResiduals& out, double& weight_sum) noexcept {
    out.setZero();
    weight_sum = 0.0;
    int n_projected = 0;
    const solver::PoseFrames f = model.frames(at);
    for (int i = 0; i < kMaxSamples; ++i) {
      solver::Vec3 point, normal;
      const int m = stripe_sample(model, f, i, point, normal);
      const double depth = point.norm();
      const double facing = depth > 0.0 ? -normal.dot(point) / depth : 0.0;
      const double w = std::min(1.0, std::max(0.0, (facing - kFacingMin) / kFacingRamp));
      solver::Vec2 p;
      if (w <= 0.0 || !camera.project(point, p)) {
        continue;
      }
      const int colour = colour_index(config_.interpretation.marker_classes[static_cast<std::size_t>(m)]);
      out[i] = w * std::min(class_distance_px(colour, p.x(), p.y()), cap_px);
      weight_sum += camera.in_image(p) ? w : 0.0;
      if (w > 0.5) {
        projected[static_cast<std::size_t>(n_projected)] = p;
        projected_colour[static_cast<std::size_t>(n_projected)] = colour;
        ++n_projected;
      }
    }
    for (int q = 0; q < coverage.count; ++q) {
      double best_sq = kCoverageCapPx * kCoverageCapPx;
      for (int i = 0; i < n_projected; ++i) {
        if (projected_colour[static_cast<std::size_t>(i)] == coverage.colour[static_cast<std::size_t>(q)]) {
          best_sq = std::min(best_sq,
                             (projected[static_cast<std::size_t>(i)] - coverage.at[static_cast<std::size_t>(q)]).squaredNorm());
        }
      }
      out[kMaxSamples + q] = std::sqrt(best_sq);
    }
    for (int k = 0; k < kParams; ++k) {
      out[kMaxSamples + kMaxCoverage + k] = kPriorWeightPx * (at[k] - start[k]) / prior_sd[k];
    }
  };
  solver::PoseVector x = r;
  if (!coarse_grid_start(residuals, r, x)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  // Two descents: the first with distances capped at kCapPx (a wide basin:
  // a seed a stripe away is still drawn in), the second from its end with
  // the cap at kFineCapPx, so that stripe samples an occluder (or the
  // image's border) hides, far from every pixel of their colour, weigh
  // no more than a near miss and stop pulling the visible stripes onto
  // the wrong ones (docs/vision.md, "Fallback seeds").
  for (int phase = 0; phase < 2; ++phase) {
    cap_px = phase == 0 ? kCapPx : kFineCapPx;
    if (!descend(residuals, fit_scratch_->class_fit, x)) {
      return Status<VisionError>::failure(VisionError::NoInstrument);
    }
  }
  if (!x.allFinite()) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  // The cost reported with the wide cap, whatever the last descent used.
  cap_px = kCapPx;
  ClassResiduals e;
  double weight_sum = 0.0;
  residuals(x, e, weight_sum);
  cost_px = e.head(kMaxSamples).sum() / std::max(weight_sum, 1.0);
  r = x;
  return ok_status<VisionError>();
}

}  // namespace vision
}  // namespace tcpest
