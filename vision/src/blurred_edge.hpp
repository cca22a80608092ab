// The silhouette under a motion-blur streak, read by a model of the blurred
// edge (the image fit's silhouette readings, docs/vision.md "The blurred
// edge's model").
//
// Across the silhouette of a cylinder lit from the camera, the tube's
// radiance falls to its limb as the cosine between the surface normal and
// the view, sqrt(2u - u^2) at u = depth inside the limb / apparent half
// width (clamped at the crest, u = 1), and beyond the limb lies the tissue.
// A camera's motion over the exposure averages that profile over the smear
// across the edge (a box of |streak . normal| px). The profile is sampled
// in linear light (three channels), and for every candidate edge position
// on a 0.25 px grid the levels are solved by least squares over the basis
// {blurred shading, blurred inside step, 1} per channel; the edge is where
// the summed squared residual is least (refined by a parabola). The box
// blur of each basis is in closed form, and its sums over the samples come
// from prefix sums, so one reading costs a few microseconds.
//
// Pure: no image, no camera, no allocation (the caller owns the scratch).
#pragma once

#include <array>

namespace tcpest {
namespace vision {
namespace detail {

constexpr double kBlurredEdgeSampleStepPx = 0.5;  // the profile's spacing (px)
constexpr double kBlurredEdgeGridPx = 0.25;       // the edge's candidate positions (px)
constexpr int kMaxBlurredEdgeSamples = 161;       // +/- 40 px at 0.5 px
constexpr double kMaxBlurredEdgeWindowPx = 16.0;  // the edge is looked for within +/- this (clamped)

struct BlurredEdgeProfile {
  // rgb[i]: linear-light (R, G, B) at t_i = kBlurredEdgeSampleStepPx (i - half)
  // px along the normal, outwards positive; n = 2 half + 1 samples.
  std::array<std::array<double, 3>, kMaxBlurredEdgeSamples> rgb{};
  int half = 0;
};

struct BlurredEdgeFit {
  double edge_px = 0.0;   // px from the profile's centre, outwards positive
  double smear_px = 0.0;  // the smear across the edge the fit took
  double residual = 0.0;  // sum of squared residuals over the samples and channels
};

// The scratch of one fit: the blurred bases tabulated over d = edge - t,
// their strided sums, and the profile's own sums (some 26 KB). Allocated
// once by its owner (the FeatureExtractor, at create()) and rebuilt for
// every fit: no state carries over from one reading to the next.
class BlurredEdgeScratch {
 public:
  // False when a sample is not finite.
  bool prepare(const BlurredEdgeProfile& profile, double smear_px, double half_width_px, double window_px) noexcept;
  int edges() const noexcept { return 2 * edge_half_ + 1; }
  // Grid index e's edge, px from the profile's centre.
  double edge_px(double e) const noexcept { return kBlurredEdgeGridPx * (e - static_cast<double>(edge_half_)); }
  // The residual with the edge at grid index e, the levels solved.
  bool residual(int e, double& out) const noexcept;

  // Bounds of the tables.
  static constexpr int kMaxEdgeHalf = 68;  // ceil((kMaxBlurredEdgeWindowPx + 1) / kBlurredEdgeGridPx)
  static constexpr int kSampleCells = 2;   // kBlurredEdgeSampleStepPx / kBlurredEdgeGridPx
  static constexpr int kMaxSampleHalf = (kMaxBlurredEdgeSamples - 1) / 2;
  // The table of d = edge - t, on the grid: +/- (edge reach + profile reach + 1 cell).
  static constexpr int kMaxTableHalf = kMaxEdgeHalf + kSampleCells * kMaxSampleHalf + 1;
  static constexpr int kMaxTable = 2 * kMaxTableHalf + 1;
  static constexpr int kMaxEdges = 2 * kMaxEdgeHalf + 1;

 private:
  // Sums over the n samples of a table entry taken at k0, k0 - 2, ...,
  // k0 - 2 (n - 1): stride-2 prefix sums, so each sum is one difference.
  struct StridedSums {
    std::array<double, kMaxTable> prefix{};
    void build(const std::array<double, kMaxTable>& values, int count) noexcept;
    double sum(int k0, int n) const noexcept;
  };

  const BlurredEdgeProfile* profile_ = nullptr;
  int half_ = 0;
  int n_ = 0;
  int edge_half_ = 0;
  int table_half_ = 0;  // entry k of the tables: d = kBlurredEdgeGridPx (k - table_half_) px inside the edge
  std::array<double, kMaxTable> shading_{};
  std::array<double, kMaxTable> inside_{};
  std::array<double, kMaxTable> product_{};
  StridedSums s_ss_, s_si_, s_s_, s_ii_, s_i_;
  std::array<double, 3> sum_c_{};
  double sum_c2_ = 0.0;
};

// The edge that best explains `profile` under a smear of `smear_px` across
// it, for a part of apparent half width `half_width_px`, looked for within
// +/- window_px. False when the inputs are out of range (half_width_px <= 1,
// a non-finite value, a profile too long) or the best position lies at the
// search's end.
bool fit_blurred_edge(const BlurredEdgeProfile& profile, double smear_px, double half_width_px, double window_px,
                      BlurredEdgeScratch& scratch, BlurredEdgeFit& fit) noexcept;

// The same, with the smear also searched: every kBlurredEdgeSmearStepPx
// within +/- smear_search_px of `smear_px` (not below 1 px; at most 16
// steps either way), the fit of the least residual kept. The smear read
// from the arcs is a fraction of a pixel to a few pixels off
// (docs/vision.md), and the edge follows an error in it.
constexpr double kBlurredEdgeSmearStepPx = 2.0;
bool fit_blurred_edge_and_smear(const BlurredEdgeProfile& profile, double smear_px, double smear_search_px,
                                double half_width_px, double window_px, BlurredEdgeScratch& scratch,
                                BlurredEdgeFit& fit) noexcept;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
