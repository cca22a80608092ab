// The model-guided readings' geometry and image probes (docs/vision.md
// "Model-guided corners"): where the model puts a silhouette or an end face
// at a pose, and the Refiner, which reads the image around the model's
// prediction at one pose: a boundary arc's shift along the tube, the base's
// rim, the silhouette's offset, a colour change or an edge along a line.
//
// Shared by the corners' refinement (refine.cpp), the image fit
// (image_fit.cpp), the motion streak (motion_streak.cpp) and the shaft's fit
// (shaft_fit.cpp). No allocation: every profile is a fixed-size array.
#pragma once

#include <cstddef>
#include <cstdint>

#include "blurred_edge.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace detail {

constexpr double kDsMm = 1e-3;     // finite difference along the tube
constexpr int kMaxClearReach = 8;  // a crossing's clear colours at most this many samples away

// ceil(v) as an int within [lo, hi]: clamped before the cast (a window
// from a projection next to the camera can be huge, or NaN: lo).
int ceil_within(double v, int lo, int hi) noexcept;

// What a colour-change reading found (Refiner::crossing).
enum class Crossing : std::uint8_t { kNone, kSharp, kSmeared };

// How the colour changes across boundary j, base -> tip.
struct BoundaryColours {
  bool usable = false;
  bool margin = false;    // blue against neutral (shaft, grasper) instead of yellow - blue
  double want = 0.0;      // sign of the profile's change from base to tip
};

BoundaryColours colours_of(const ExtractorConfig& config, int j) noexcept;

// True when the tip's end face (the last stripe's, between the grasper's
// radius and the tube's, facing along the tube) is turned towards the
// camera: the colour change at the tip boundary is then the grasper's
// outline on that face, not the boundary's circle.
bool tip_face_visible(const solver::InstrumentModel& model, const solver::PoseFrames& f) noexcept;

// True when the base's end face (the first stripe's, between the shaft's
// radius and the tube's, facing back along the tube) is turned towards the
// camera: the camera behind the plane at s = 0.
bool base_face_visible(const solver::InstrumentModel& model, const solver::PoseFrames& f) noexcept;

// The model's silhouette point of `side` at arc length s and its outward
// image normal; false when the model gives no limb point there.
bool silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                   const solver::PoseFrames& f, double s_mm, std::size_t side, solver::Vec2& point,
                   solver::Vec2& normal) noexcept;

// The same for the grasper's silhouette `beyond_mm` past the tip.
bool grasper_silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                           const solver::PoseFrames& f, double beyond_mm, std::size_t side, solver::Vec2& point,
                           solver::Vec2& normal) noexcept;

// True when the image point p lies behind the tube's end: the tip's face
// turned away from the camera (the grasper runs away from it) and p within
// the image of the tube's circle at s = L (its centre's image and the
// larger image of a radius there, +1 px). The grasper's silhouette there is
// hidden by the tube; what lies there is the tube's own edge.
bool behind_tube_end(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                     const solver::PoseFrames& f, const solver::Vec2& p) noexcept;

// The same for the shaft's silhouette `back_mm` before the base.
bool shaft_silhouette_at(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                         const solver::PoseFrames& f, double back_mm, std::size_t side, solver::Vec2& point,
                         solver::Vec2& normal) noexcept;

// Reads the image around the model's prediction at one pose (frames). Holds
// references only: everything it is given must outlive it.
class Refiner {
 public:
  // `edge_scratch`: the blurred edge's model's tables (the extractor's);
  // without them the silhouette under a streak is read at the outer end.
  Refiner(const ImageView& image, const ColorModel& colors, const ExtractorConfig& config,
          const solver::CameraModel& camera, const solver::InstrumentModel& model, const solver::PoseFrames& frames,
          BlurredEdgeScratch* edge_scratch) noexcept
      : image_(image), colors_(colors), config_(config), camera_(camera), model_(model), frames_(frames),
        edge_scratch_(edge_scratch) {}

  const ImageView& image() const noexcept { return image_; }

  // The motion-blur streak (px, image; zero: none) under which the
  // silhouette is read by edge_across.
  void use_streak(const solver::Vec2& streak_px) noexcept { streak_px_ = streak_px; }
  bool has_streak() const noexcept { return streak_px_.squaredNorm() > 0.0; }

  // Median shift (mm along the tube) that puts the visible arc of the
  // circle at s on the colour change; false when too few arc points see it.
  bool arc_shift(double s_mm, const BoundaryColours& colours, double window_mm, double& shift_mm) noexcept;

  // Shift (mm along the tube) of the base's rim (its end face, seen as a
  // thin bright ring: RefinerConfig::refine_base_rim) from the model's,
  // read on the ring of `radius` at s = 0; false when too few arc points
  // see it or they spread.
  bool rim_shift(double radius, double& shift_mm) noexcept;

  // Offset (px, outwards) of the silhouette from the model's beside the
  // corner of `side` of the circle at s; false with too few readings.
  bool silhouette_offset(double s_mm, std::size_t side, int j, double& offset_px) noexcept;

  // The colour change along `dir` through p nearest to p (px, signed),
  // between readings that are clearly on each side: the mean of two
  // neighbouring samples. A sharp change is clear at the very next pair on
  // each side; a smeared one only within `clear_reach` pairs (1: sharp
  // changes only). The nearest sharp change if there is one, else the
  // nearest smeared one.
  Crossing crossing(const solver::Vec2& p, const solver::Vec2& dir, double window_px, const BoundaryColours& colours,
                    int clear_reach, double& tau_px) const noexcept;

  // The colour-gradient maximum along `normal` through p (px from p,
  // outwards positive), moved by the shading correction of stage 3.
  bool edge(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double& offset_px) const noexcept;

  // The silhouette's reading under the streak: where the smear across the
  // normal, |streak . normal|, reaches refine_streak_across_px, the outer
  // end of the gradient's plateau (outer_end); else edge(). A smear of 5 px
  // (the default) and more flattens the gradient's peak into a plateau as wide as the
  // smear, whose centre the tube's shading pulls inwards and whose ends
  // often lie beyond edge()'s window (docs/vision.md).
  bool edge_across(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double half_width_px,
                   double& offset_px, bool& outer_end) const noexcept;

 private:
  // The median over the visible arc of the tube's circle at s (the points
  // taken on the ring of `radius` there) of what `read(p, dir, px_per_mm,
  // tau_px)` finds along the tube (dir, unit) from each point p, as a shift
  // in mm; false when fewer than 3 or refine_min_arc_share of the points
  // read, or their MAD exceeds max_spread_mm.
  template <typename Read>
  bool median_arc_shift(double s_mm, double radius, double max_spread_mm, Read read, double& shift_mm) noexcept;

  double score(double x, double y, bool margin, bool& ok) const noexcept;

  // The lightness ridge along `dir` through p nearest to p (px, signed,
  // sub-pixel), within reach_px: a local maximum standing
  // refine_base_rim_contrast above the samples kRimSidePx on either side.
  bool ridge(const solver::Vec2& p, const solver::Vec2& dir, double reach_px, double& tau_px) const noexcept;

  // The silhouette at mid-exposure by the blurred edge's model
  // (detail::fit_blurred_edge): the linear-light profile along `normal`
  // through p, over the window, half the smear across and a margin for the
  // levels on both sides; px from p, outwards positive.
  bool edge_blurred(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double across_px,
                    double half_width_px, double& offset_px) const noexcept;

  // The outer end of the linear-light colour gradient's plateau along
  // `normal` through p (where it falls below kOuterEndShare of its peak on
  // the tissue's side, which the tube's shading does not reach), moved in
  // by half the smear across: the silhouette at mid-exposure, px from p,
  // outwards positive. The peak is looked for within window_px + half the
  // smear; false when the plateau runs to the profile's end or the result
  // lies beyond window_px.
  bool edge_outer_end(const solver::Vec2& p, const solver::Vec2& normal, double window_px, double across_px,
                      double& offset_px) const noexcept;

  const ImageView& image_;
  const ColorModel& colors_;
  const ExtractorConfig& config_;
  const solver::CameraModel& camera_;
  const solver::InstrumentModel& model_;
  const solver::PoseFrames& frames_;
  solver::Vec2 streak_px_ = solver::Vec2::Zero();
  BlurredEdgeScratch* edge_scratch_;
};

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
