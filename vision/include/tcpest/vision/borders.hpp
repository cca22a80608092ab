// Stage 3 of feature extraction (paper section 2.3): the instrument's two
// borders. A skeleton through the labelled markers' centroids, extended
// past both ends; along its normals the colour gradient's strongest maximum
// near the labelled region's edge is an edge point; a quadratic Bezier per
// side is fitted to them by IRLS with Tukey's biweight. Allocation-free; no
// recursion; every loop has a fixed bound.
#pragma once

#include <array>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {

struct BordersConfig {
  int skeleton_samples = 40;  // 8..kMaxSkeletonSamples
  // The skeleton runs past the end markers' centroids by this many of their
  // half extents (a stripe's end lies at ~0.87): just past the end boundaries.
  double skeleton_extension = 1.3;
  double edge_search_min = 0.35;            // edge search window along the normal, in local half widths
  double edge_search_max = 1.9;
  // Outward correction of the gradient maximum: the tube's shading falls off
  // towards the silhouette, which pulls the maximum inwards (measured on
  // rendered frames, docs/vision.md).
  double edge_offset_px = 0.3;
  double tukey_c = 1.5;
  int irls_iterations = 10;                 // 1..50
  int irls_scale_iterations = 4;            // the MAD scale is re-estimated during the first ones only (1..irls_iterations)
};

class BorderFitter {
 public:
  BorderFitter() noexcept = default;
  // Validates the configuration (BadParameter) and allocates the fitter
  // (OutOfMemory); it needs no other buffer.
  static Result<std::unique_ptr<BorderFitter>, VisionError> create(const BordersConfig& config) noexcept;

  // The borders of the instrument labelled by `in` (at least 2 found
  // markers) in `image`, whose stage-1 classes are `classes` (the same
  // size): `borders` (reset first; [side]: 0 = left, 1 = right) and the
  // skeleton's samples (`skeleton`, `skeleton_count` of them).
  // BorderFitFailed when neither side could be fitted.
  Status<VisionError> fit(const ImageView& image, const ClassImage& classes, const Interpretation& in,
                          std::array<Border, 2>& borders, std::array<Point, kMaxSkeletonSamples>& skeleton,
                          int& skeleton_count) const noexcept;

  const BordersConfig& config() const noexcept { return config_; }

 private:
  BordersConfig config_{};
};

}  // namespace vision
}  // namespace tcpest
