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
// Pure: no image, no camera, no allocation.
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

// The edge that best explains `profile` under a smear of `smear_px` across
// it, for a part of apparent half width `half_width_px`, looked for within
// +/- window_px. False when the inputs are out of range (half_width_px <= 1,
// a non-finite value, a profile too long) or the best position lies at the
// search's end.
bool fit_blurred_edge(const BlurredEdgeProfile& profile, double smear_px, double half_width_px, double window_px,
                      BlurredEdgeFit& fit) noexcept;

// The same, with the smear also searched: every kBlurredEdgeSmearStepPx
// within +/- smear_search_px of `smear_px` (not below 1 px; at most 16
// steps either way), the fit of the least residual kept. The smear read
// from the arcs is a fraction of a pixel to a few pixels off
// (docs/vision.md), and the edge follows an error in it.
constexpr double kBlurredEdgeSmearStepPx = 2.0;
bool fit_blurred_edge_and_smear(const BlurredEdgeProfile& profile, double smear_px, double smear_search_px,
                                double half_width_px, double window_px, BlurredEdgeFit& fit) noexcept;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
