// The motion-blur streak from the stripe boundaries' widths (motion_streak.hpp).
#include "motion_streak.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>

#include "refiner.hpp"
#include "robust_step.hpp"
#include "sampling.hpp"
#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

// Motion blur's streak from the boundary arcs (read_streak,
// docs/decisions/0014-motion-streak-reading.md). Each stripe boundary is a sharp colour change
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
constexpr double kStreakSharpWidthPx = 5.8;  // measured on sharp frames (docs/decisions/0014-motion-streak-reading.md)
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
        return solver::Vec3(cf.position + g.radius_mm * (dmath::cos(angle) * cf.normal + dmath::sin(angle) * cf.binormal));
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
    if (config.interpretation.marker_classes[mm] != PixelClass::Blue) {
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

}  // namespace

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

bool streak_for_arc_retry(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                          const solver::InstrumentModel& model, const solver::PoseFrames& f,
                          solver::Vec2& streak_px) noexcept {
  if (!config.refiner.refine_streak_arc_retry || !config.refiner.refine_streak) {
    return false;
  }
  if (streak_px.norm() > 0.0) {
    return true;
  }
  if (!read_streak(image, config, camera, model, f, streak_px) ||
      !(streak_px.norm() >= config.refiner.refine_streak_arc_retry_min_px)) {
    streak_px = solver::Vec2::Zero();
    return false;
  }
  return true;
}

}  // namespace detail

Status<VisionError> FeatureExtractor::read_motion_streak(const ImageView& image, const solver::CameraModel& camera,
                                                         const solver::InstrumentModel& model,
                                                         const solver::PoseVector& r,
                                                         solver::Vec2& streak_px) const noexcept {
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  if (!detail::read_streak(image, config_, camera, model, model.frames(r), streak_px)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  return ok_status<VisionError>();
}

}  // namespace vision
}  // namespace tcpest
