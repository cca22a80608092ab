// The data feature extraction's four stages (paper section 2.3) hand each
// other, one definition each: stage 1's regions (RegionSet), stage 2's
// labelled markers (Interpretation), stage 3's borders (Border), stage 4's
// corners (Corner), and the whole frame's Extraction. The stages themselves
// are regions.hpp, interpretation.hpp, borders.hpp and corners.hpp;
// features.hpp composes them.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "tcpest/common/static_vector.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {

enum class VisionError : std::uint8_t {
  BadImage,        // null data, bad size or stride
  ImageTooLarge,   // larger than the extractor was created for
  TooManyRuns,     // the classified image is too fragmented for the run buffer
  NoInstrument,    // no chain of marker regions found
  BorderFitFailed, // too few edge points on a side
  BadParameter,    // invalid configuration at creation
  OutOfMemory,     // the buffers could not be allocated at creation
};
const char* to_string(VisionError e) noexcept;

struct Point {
  double x = 0.0;  // pixels, (0, 0) = centre of the top-left pixel
  double y = 0.0;
};

// A connected component of one colour, with its moments.
struct Region {
  PixelClass cls = PixelClass::Background;
  std::int32_t area = 0;  // pixels
  Point centroid{};
  double cov_xx = 0.0, cov_xy = 0.0, cov_yy = 0.0;  // second central moments / area
  double half_major = 0.0;  // 2 sqrt(largest eigenvalue): the half axis of the equivalent ellipse
  double half_minor = 0.0;
  double orientation_rad = 0.0;  // of the major axis, image x towards y
  std::int32_t x_min = 0, x_max = 0, y_min = 0, y_max = 0;  // bounding box, inclusive
  // Adds the moments of another region (a virtual node of the tree).
  void merge(const Region& other) noexcept;
  // Recomputes half axes and orientation from the covariance.
  void update_shape() noexcept;
  // Half extent of the equivalent ellipse in unit direction (dx, dy).
  double extent_along(double dx, double dy) const noexcept;
};

constexpr std::size_t kMaxRegions = 64U;        // regions handed to stage 2 (the largest)
constexpr int kNumMarkers = solver::kNumMarkers;
constexpr int kNumBoundaries = solver::kNumBoundaries;
constexpr int kNumCorners = solver::kNumCorners;

struct RegionSet {
  StaticVector<Region, kMaxRegions> regions;
  bool too_many_regions = false;  // more candidates than kMaxRegions: the smallest were dropped
  std::int32_t run_count = 0;
};

// One labelled marker (a level of the tree): a region or a virtual merge of two.
struct MarkerObservation {
  bool found = false;
  Region region{};
  std::array<std::int16_t, 2> region_index{{-1, -1}};  // into RegionSet::regions
  double log_posterior = 0.0;
};

struct Interpretation {
  std::array<MarkerObservation, kNumMarkers> markers{};
  int first_marker = -1;  // 0-based level of the first found marker, -1 if none
  int last_marker = -1;
  int found_count = 0;
  double score = 0.0;
};

// A quadratic Bezier curve B(t) = (1-t)^2 p0 + 2 (1-t) t p1 + t^2 p2, t in [0, 1].
struct Bezier {
  Point p0{}, p1{}, p2{};
  Point at(double t) const noexcept;
  Point derivative(double t) const noexcept;
};

constexpr std::size_t kMaxSkeletonSamples = 64U;

struct EdgePoint {
  Point pixel{};
  double weight = 0.0;  // final IRLS weight
  double t = 0.0;       // chord-length parameter
};

struct Border {
  bool valid = false;
  Bezier curve{};
  StaticVector<EdgePoint, kMaxSkeletonSamples> points;
  double scale_px = 0.0;  // final MAD scale of the residuals
  int iterations = 0;
};

struct Corner {
  bool found = false;
  Point pixel{};
  double confidence = 0.0;  // 0..1
};

struct Extraction {
  RegionSet regions;
  Interpretation interpretation;
  std::array<Point, kMaxSkeletonSamples> skeleton{};
  int skeleton_count = 0;
  std::array<Border, 2> borders{};  // [side]: 0 = left, 1 = right (model.md's side rule)
  std::array<Corner, kNumCorners> corners{};
  int corner_count = 0;
  // Model-guided corners (refine_corners): stage 4's corners are kept here,
  // and each boundary's measured shift along the tube from the pose's.
  bool refined = false;
  std::array<Corner, kNumCorners> stage4_corners{};
  std::array<bool, kNumBoundaries> boundary_measured{};
  std::array<double, kNumBoundaries> boundary_shift_mm{};
};

// The class image of stage 1 (row-major, `width` per row, PixelClass
// values), as stage 3 reads it.
struct ClassImage {
  const std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
};

// The corners as the solver wants them (pixels, presence per k).
void corners_to_arrays(const Extraction& e, std::array<solver::Vec2, kNumCorners>& pixels,
                       std::array<bool, kNumCorners>& present) noexcept;

}  // namespace vision
}  // namespace tcpest
