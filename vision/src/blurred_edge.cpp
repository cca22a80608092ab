#include "blurred_edge.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {
namespace detail {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kSampleCells = BlurredEdgeScratch::kSampleCells;
constexpr int kMaxSampleHalf = BlurredEdgeScratch::kMaxSampleHalf;
constexpr int kMaxEdges = BlurredEdgeScratch::kMaxEdges;

static_assert(BlurredEdgeScratch::kMaxEdgeHalf * kBlurredEdgeGridPx >= kMaxBlurredEdgeWindowPx + 1.0, "the edge grid covers the window");
static_assert(kSampleCells * kBlurredEdgeGridPx == kBlurredEdgeSampleStepPx, "samples lie on the grid");

// The integral of the sharp shading sqrt(2u - u^2) from the limb (u = 0) to
// u, in units of the half width: a quarter disc's area up to the crest,
// then 1 per unit beyond it (the shading clamped at the crest). Exact.
double shading_integral_exact(double u) noexcept {
  if (!(u > 0.0)) {
    return 0.0;
  }
  if (u >= 1.0) {
    return 0.25 * kPi + (u - 1.0);
  }
  const double v = u - 1.0;  // in [-1, 0)
  return 0.5 * (v * std::sqrt(std::max(0.0, 1.0 - v * v)) + dmath::asin(v)) + 0.25 * kPi;
}

// The same from a table over [0, 1] (linear between entries: within
// 1e-6 of the exact value), built once: the tables of one reading need it
// a few hundred times.
class ShadingIntegral {
 public:
  static constexpr int kEntries = 4096;
  ShadingIntegral() noexcept {
    for (int i = 0; i <= kEntries; ++i) {
      table_[static_cast<std::size_t>(i)] = shading_integral_exact(static_cast<double>(i) / kEntries);
    }
  }
  double operator()(double u) const noexcept {
    if (!(u > 0.0)) {
      return 0.0;
    }
    if (u >= 1.0) {
      return table_[kEntries] + (u - 1.0);
    }
    const double x = u * kEntries;
    const auto i = static_cast<std::size_t>(x);
    const double f = x - static_cast<double>(i);
    return table_[i] + f * (table_[i + 1U] - table_[i]);
  }

 private:
  std::array<double, kEntries + 1> table_{};
};

double shading_integral(double u) noexcept {
  static const ShadingIntegral table;
  return table(u);
}

// The box average over [d - w/2, d + w/2] (d: px inside the edge) of the
// sharp shading and of the inside step.
void blurred_bases(double d_px, double smear_px, double half_width_px, double& shading, double& inside) noexcept {
  const double lo = d_px - 0.5 * smear_px;
  const double hi = d_px + 0.5 * smear_px;
  shading = half_width_px * (shading_integral(hi / half_width_px) - shading_integral(lo / half_width_px)) / smear_px;
  inside = std::min(1.0, std::max(0.0, hi / smear_px));
}

// The grid index of the least residual: every other position first, then
// those beside the least (a neighbour can undercut it), so that the least
// and both its neighbours are known in `sse`. False when a residual fails.
bool least_residual(const BlurredEdgeScratch& scratch, std::array<double, kMaxEdges>& sse, int& best) noexcept {
  std::array<bool, kMaxEdges> done{};
  const int edges = scratch.edges();
  const auto compute = [&](int e) noexcept {
    const auto ee = static_cast<std::size_t>(e);
    if (e < 0 || e >= edges || done[ee]) {
      return true;
    }
    done[ee] = true;
    return scratch.residual(e, sse[ee]);
  };
  best = -1;
  for (int e = 0; e < edges; e += 2) {  // edges is odd: both ends are tried
    if (!compute(e)) {
      return false;
    }
    if (best < 0 || sse[static_cast<std::size_t>(e)] < sse[static_cast<std::size_t>(best)]) {
      best = e;
    }
  }
  for (int round = 0; round < 2; ++round) {  // at most one move to a neighbour, then its own neighbours
    if (!compute(best - 1) || !compute(best + 1)) {
      return false;
    }
    for (const int e : {best - 1, best + 1}) {
      if (e >= 0 && e < edges && sse[static_cast<std::size_t>(e)] < sse[static_cast<std::size_t>(best)]) {
        best = e;
      }
    }
  }
  return compute(best - 1) && compute(best + 1);
}

}  // namespace

void BlurredEdgeScratch::StridedSums::build(const std::array<double, kMaxTable>& values, int count) noexcept {
  for (int k = 0; k < count; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    prefix[kk] = values[kk] + (k >= kSampleCells ? prefix[kk - kSampleCells] : 0.0);
  }
}

double BlurredEdgeScratch::StridedSums::sum(int k0, int n) const noexcept {
  const int before = k0 - kSampleCells * n;
  return prefix[static_cast<std::size_t>(k0)] - (before >= 0 ? prefix[static_cast<std::size_t>(before)] : 0.0);
}

bool BlurredEdgeScratch::prepare(const BlurredEdgeProfile& profile, double smear_px, double half_width_px,
                               double window_px) noexcept {
  profile_ = &profile;
  half_ = profile.half;
  n_ = 2 * half_ + 1;
  edge_half_ = static_cast<int>(std::ceil((window_px + 1.0) / kBlurredEdgeGridPx));
  table_half_ = edge_half_ + kSampleCells * half_ + 1;
  const int table_count = 2 * table_half_ + 1;
  for (int k = 0; k < table_count; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    blurred_bases(kBlurredEdgeGridPx * static_cast<double>(k - table_half_), smear_px, half_width_px, shading_[kk],
                  inside_[kk]);
  }
  const auto build = [&](StridedSums& sums, const auto& value) noexcept {
    for (int k = 0; k < table_count; ++k) {
      product_[static_cast<std::size_t>(k)] = value(static_cast<std::size_t>(k));
    }
    sums.build(product_, table_count);
  };
  build(s_ss_, [&](std::size_t k) noexcept { return shading_[k] * shading_[k]; });
  build(s_si_, [&](std::size_t k) noexcept { return shading_[k] * inside_[k]; });
  build(s_s_, [&](std::size_t k) noexcept { return shading_[k]; });
  build(s_ii_, [&](std::size_t k) noexcept { return inside_[k] * inside_[k]; });
  build(s_i_, [&](std::size_t k) noexcept { return inside_[k]; });
  sum_c_ = {0.0, 0.0, 0.0};
  sum_c2_ = 0.0;
  for (int i = 0; i < n_; ++i) {
    for (std::size_t ch = 0U; ch < 3U; ++ch) {
      const double c = profile.rgb[static_cast<std::size_t>(i)][ch];
      if (!std::isfinite(c)) {
        return false;
      }
      sum_c_[ch] += c;
      sum_c2_ += c * c;
    }
  }
  return true;
}

// The residual with the edge at grid index e, the levels solved (the
// normal equations' symmetric 3 x 3 matrix inverted by cofactors).
bool BlurredEdgeScratch::residual(int e, double& out) const noexcept {
  // Sample i (t = step (i - half)) of edge e (at grid (e - edge_half))
  // reads table entry k = (e - edge_half) - cells (i - half) + table_half.
  const int k0 = (e - edge_half_) + kSampleCells * half_ + table_half_;  // i = 0
  const double a00 = s_ss_.sum(k0, n_);
  const double a01 = s_si_.sum(k0, n_);
  const double a02 = s_s_.sum(k0, n_);
  const double a11 = s_ii_.sum(k0, n_);
  const double a12 = s_i_.sum(k0, n_);
  const double a22 = static_cast<double>(n_);
  const double c00 = a11 * a22 - a12 * a12;
  const double c01 = a02 * a12 - a01 * a22;
  const double c02 = a01 * a12 - a02 * a11;
  const double c11 = a00 * a22 - a02 * a02;
  const double c12 = a01 * a02 - a00 * a12;
  const double c22 = a00 * a11 - a01 * a01;
  const double det = a00 * c00 + a01 * c01 + a02 * c02;
  // The shading is nil where the edge leaves the profile: no level is
  // then defined, and this position explains nothing.
  if (!(std::fabs(det) > 1e-12 * (1.0 + std::fabs(a00 * a11 * a22)))) {
    out = sum_c2_;
    return true;
  }
  std::array<double, 3> rs{};
  std::array<double, 3> ri{};
  for (int i = 0; i < n_; ++i) {
    const auto k = static_cast<std::size_t>(k0 - kSampleCells * i);
    const auto& c = profile_->rgb[static_cast<std::size_t>(i)];
    for (std::size_t ch = 0U; ch < 3U; ++ch) {
      rs[ch] += shading_[k] * c[ch];
      ri[ch] += inside_[k] * c[ch];
    }
  }
  double explained = 0.0;
  for (std::size_t ch = 0U; ch < 3U; ++ch) {
    // b^T A^-1 b with b = (rs, ri, sum_c), A^-1 = C / det.
    const double b0 = rs[ch];
    const double b1 = ri[ch];
    const double b2 = sum_c_[ch];
    explained += (b0 * (c00 * b0 + c01 * b1 + c02 * b2) + b1 * (c01 * b0 + c11 * b1 + c12 * b2) +
                  b2 * (c02 * b0 + c12 * b1 + c22 * b2)) /
                 det;
  }
  out = sum_c2_ - explained;
  return std::isfinite(out);
}

bool fit_blurred_edge(const BlurredEdgeProfile& profile, double smear_px, double half_width_px, double window_px,
                      BlurredEdgeScratch& scratch, BlurredEdgeFit& fit) noexcept {
  if (profile.half < 2 || profile.half > kMaxSampleHalf || !(half_width_px > 1.0) || !std::isfinite(half_width_px) ||
      !(smear_px >= 0.0) || !std::isfinite(smear_px) || !(window_px > 0.0)) {
    return false;
  }
  const double smear = std::max(smear_px, 1.0);  // a sharp edge still spreads over about a pixel
  const double window = std::min(window_px, kMaxBlurredEdgeWindowPx);
  if (!scratch.prepare(profile, smear, half_width_px, window)) {
    return false;
  }
  std::array<double, kMaxEdges> sse{};
  int best = -1;
  if (!least_residual(scratch, sse, best)) {
    return false;
  }
  if (best <= 0 || best >= scratch.edges() - 1) {
    return false;  // at the search's end: the edge may lie beyond it
  }
  const double before = sse[static_cast<std::size_t>(best) - 1U];
  const double at = sse[static_cast<std::size_t>(best)];
  const double after = sse[static_cast<std::size_t>(best) + 1U];
  const double curvature = before - 2.0 * at + after;
  const double fraction = curvature > 0.0 ? 0.5 * (before - after) / curvature : 0.0;
  fit.edge_px = scratch.edge_px(static_cast<double>(best) + fraction);
  fit.smear_px = smear;
  fit.residual = at;
  return std::fabs(fit.edge_px) <= window;
}

bool fit_blurred_edge_and_smear(const BlurredEdgeProfile& profile, double smear_px, double smear_search_px,
                                double half_width_px, double window_px, BlurredEdgeScratch& scratch,
                                BlurredEdgeFit& fit) noexcept {
  if (!std::isfinite(smear_px) || !(smear_search_px >= 0.0) || !std::isfinite(smear_search_px)) {
    return false;
  }
  const int steps = static_cast<int>(std::min(std::floor(smear_search_px / kBlurredEdgeSmearStepPx), 16.0));
  bool found = false;
  for (int k = -steps; k <= steps; ++k) {
    const double smear = smear_px + kBlurredEdgeSmearStepPx * static_cast<double>(k);
    BlurredEdgeFit tried;
    if (smear >= 1.0 && fit_blurred_edge(profile, smear, half_width_px, window_px, scratch, tried) &&
        (!found || tried.residual < fit.residual)) {
      fit = tried;
      found = true;
    }
  }
  return found;
}

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
