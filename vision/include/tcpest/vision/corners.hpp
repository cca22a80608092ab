// Stage 4 of feature extraction (paper section 2.3): the apparent corners
// (k = 2 j + side, model.md). Along curves parallel to each border, inside
// the tube, the yellow-minus-blue chroma score (or an end marker's blue
// margin) crosses zero at every marker boundary; the crossings trace the
// boundary's visible arc, half an ellipse tangent to both borders, whose
// tangency points are the corners. Every buffer (the chroma profiles) is
// allocated once in CornerFinder::create(); finding a frame's corners
// allocates nothing. No recursion; every loop has a fixed bound.
#pragma once

#include <array>
#include <cstddef>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/vision/color_model.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {

constexpr std::size_t kProfileInsets = 8U;
constexpr std::size_t kMaxProfileSamples = 512U;

struct CornersConfig {
  int profile_samples = 160;                // chroma profile samples along each border, 16..kMaxProfileSamples
  // The profiles are read along curves parallel to the border, from this far
  // inside to profile_max_inset times the tube's half width.
  double profile_min_inset_px = 3.0;
  double profile_max_inset = 1.1;
  // Stage 4 refits each border locally, on the edge points within this many
  // tube widths of the corner.
  double local_border_window = 1.5;
  // At an end boundary the local fit keeps the edge points on the marker's
  // side, and at most this far beyond.
  double end_margin_px = 2.0;
  // Corners of lower confidence are not reported (docs/vision.md: below ~0.45
  // most are misplaced).
  double min_corner_confidence = 0.45;
  // The local borders' IRLS (as stage 3's, BordersConfig).
  double tukey_c = 1.5;
  int irls_iterations = 10;                 // 1..50
  int irls_scale_iterations = 4;            // 1..irls_iterations
};

class CornerFinder {
 public:
  CornerFinder() noexcept = default;
  // Owned through create()'s pointer, never copied or moved (its buffers are sized at create()).
  CornerFinder(const CornerFinder&) = delete;
  CornerFinder& operator=(const CornerFinder&) = delete;
  CornerFinder(CornerFinder&&) = delete;
  CornerFinder& operator=(CornerFinder&&) = delete;
  ~CornerFinder() = default;
  // Validates the configuration and the colour model (BadParameter) and
  // allocates the profiles (OutOfMemory).
  static Result<std::unique_ptr<CornerFinder>, VisionError> create(const CornersConfig& config,
                                                                   const ColorModel& colors) noexcept;

  // The corners of the instrument labelled by `in` (at least 2 found
  // markers, each marker's colour its region's) and bordered by `borders`
  // (stage 3's; at least one valid) in `image`: `corners` (reset first;
  // [k]) and how many were found. NoInstrument without markers or borders.
  Status<VisionError> find(const ImageView& image, const Interpretation& in, const std::array<Border, 2>& borders,
                           std::array<Corner, kNumCorners>& corners, int& corner_count) noexcept;

  const CornersConfig& config() const noexcept { return config_; }

 private:
  using ProfileRows = std::array<std::array<double, kMaxProfileSamples>, kProfileInsets>;
  using ProfileValid = std::array<std::array<bool, kMaxProfileSamples>, kProfileInsets>;
  struct Scratch {
    // The chroma profiles [side][inset][sample].
    std::array<ProfileRows, 2> score{};
    std::array<ProfileRows, 2> margin{};
    std::array<ProfileValid, 2> valid{};
    std::array<Border, 2> local_borders{};  // the borders around one boundary
  };
  CornersConfig config_{};
  ColorModel colors_{};
  std::unique_ptr<Scratch> scratch_;
};

}  // namespace vision
}  // namespace tcpest
