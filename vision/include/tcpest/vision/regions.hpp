// Stage 1 of feature extraction (paper section 2.3): every pixel classified
// through a lookup table built from the colour model (a*b* Gaussians), then
// 8-connected components over runs of one class, with their moments: the
// regions stage 2 labels. Every buffer is allocated once in
// RegionFinder::create(); finding a frame's regions allocates nothing. No
// recursion; every loop has a fixed bound.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/vision/classifier_lut.hpp"
#include "tcpest/vision/color_model.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {

constexpr std::size_t kMaxCandidates = 1024U;  // regions above the minimum area before selection

struct RegionsConfig {
  int max_width = 1920;  // the largest frame (the class image and the run buffer are sized for it)
  int max_height = 1080;
  std::int32_t min_region_area = 12;  // pixels; smaller components are noise
  // Stage 1 classifies every classify_step-th pixel in x and y (1 or 2) and
  // builds the regions on that grid (moments scaled back to pixels); the
  // class image stays full size (each grid class fills its step x step
  // block) and stages 3-4 read the full-resolution RGB image. 0 = auto: 2
  // when the grid still has at least as many points as a PAL 720x576 frame
  // (kAutoStepMinPixels, e.g. 1920x1080), else 1 (docs/vision.md).
  int classify_step = 0;
};

// The auto rule of RegionsConfig::classify_step: step 2 from 4 x 720 x 576
// pixels on.
constexpr std::int64_t kAutoStepMinPixels = std::int64_t{4} * 720 * 576;
// The step stage 1 uses for an image of this size (resolves 0 = auto).
int classify_step_for(int configured_step, int width, int height) noexcept;

class RegionFinder {
 public:
  RegionFinder() noexcept = default;
  // Owned through create()'s pointer, never copied or moved (its buffers are sized at create()).
  RegionFinder(const RegionFinder&) = delete;
  RegionFinder& operator=(const RegionFinder&) = delete;
  RegionFinder(RegionFinder&&) = delete;
  RegionFinder& operator=(RegionFinder&&) = delete;
  ~RegionFinder() = default;
  // Builds the lookup table from `colors` and allocates every buffer
  // (start-up only). BadParameter for an invalid configuration or colour
  // model, OutOfMemory when an allocation fails.
  static Result<std::unique_ptr<RegionFinder>, VisionError> create(const RegionsConfig& config,
                                                                   const ColorModel& colors) noexcept;

  // The regions of `image` into `out` (cleared first): at most kMaxRegions,
  // the largest when there are more (out.too_many_regions). Keeps the class
  // image. BadImage, ImageTooLarge (beyond max_width x max_height) and
  // TooManyRuns (too fragmented for the run buffer; out.too_many_regions)
  // leave `out` without regions.
  Status<VisionError> find(const ImageView& image, RegionSet& out) noexcept;

  const RegionsConfig& config() const noexcept { return config_; }
  const ClassifierLut& lut() const noexcept { return lut_; }
  // Class of each pixel of the last frame (row-major, width() per row).
  const std::uint8_t* class_image() const noexcept { return classes_.get(); }
  ClassImage classes() const noexcept { return ClassImage{classes_.get(), width_, height_}; }
  // The grid step of the last frame (1 = every pixel).
  int classify_step() const noexcept { return step_; }
  int width() const noexcept { return width_; }
  int height() const noexcept { return height_; }
  // The last frame find() accepted (valid and not too large); an invalid
  // view before the first.
  const ImageView& image() const noexcept { return image_; }

 private:
  struct Run {
    std::int32_t parent = 0;
    std::int16_t y = 0;
    std::int16_t x0 = 0;  // first pixel
    std::int16_t x1 = 0;  // one past the last pixel
    std::uint8_t cls = 0;
  };
  std::int32_t find_root(std::int32_t run) noexcept;
  // The row work: classes of `count` pixels `step` apart into `out`, then
  // the row's runs (grid coordinates) appended from run_count.
  void classify_row(const std::uint8_t* px, int count, int step, std::uint8_t* out) const noexcept;
  bool cut_runs(const std::uint8_t* classes, int count, int grid_y, std::int32_t& run_count) noexcept;
  // The steps of find(): the grid's classes and runs, joined into
  // 8-connected components (false: the runs overflowed); the joins of a
  // row's runs [row_begin, row_end) with the previous row's of the same
  // class; the components of at least the minimum area into candidates_,
  // with their raw moment sums (`overflow`: more than kMaxCandidates); one
  // run's sums; the sums turned into pixel moments and shapes, the
  // candidates still large enough first (returns how many); and the
  // largest kMaxRegions of them into `out`.
  bool classify_and_label(const ImageView& image, int step, std::int32_t& run_count) noexcept;
  void join_with_previous_row(std::int32_t row_begin, std::int32_t row_end, std::int32_t prev_begin,
                              std::int32_t prev_end) noexcept;
  std::size_t accumulate_candidates(std::int32_t run_count, int step, bool& overflow) noexcept;
  static void add_run_moments(const Run& r, Region& reg) noexcept;
  std::size_t finish_candidates(std::size_t candidate_count, int step) noexcept;
  void select_regions(std::size_t candidate_count, RegionSet& out) noexcept;

  RegionsConfig config_{};
  ClassifierLut lut_{};
  std::unique_ptr<std::uint8_t[]> classes_;
  std::unique_ptr<Run[]> runs_;
  std::unique_ptr<std::int32_t[]> region_of_root_;
  std::unique_ptr<Region[]> candidates_;
  std::unique_ptr<std::uint8_t[]> grid_row_;  // one row of grid classes (step > 1)
  std::int32_t max_runs_ = 0;
  int width_ = 0;
  int height_ = 0;
  int step_ = 1;
  ImageView image_{};
};

}  // namespace vision
}  // namespace tcpest
