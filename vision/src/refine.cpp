// Model-guided corners: the apparent corners re-measured around a first pose.
//
// Stage 4 reads each corner from the image alone, where the boundary's
// ellipse touches the silhouette, often with a flat contact: the position
// along the border is ill-conditioned there, and at the two end boundaries
// (shaft, grasper) the chroma change is weak. Given a first pose, the model
// predicts the shape of every boundary's image (an ellipse arc) and of the
// silhouette next to it; two quantities remain to be read from the image,
// each where it is well conditioned:
// - along the tube: the shift of the boundary's circle that puts its visible
//   arc on the colour change. Every arc point gives one reading, across a
//   strong colour edge (the median of up to refine_arc_samples readings);
// - across: the silhouette's offset, read on the colour-gradient maximum
//   along its normal at 8 points beside the corner (a line fitted to the
//   offsets against the arc length, taken at the corner).
// The corner is the limb point of the shifted circle, moved by that offset.
#include <algorithm>
#include <cmath>

#include "refiner.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

using detail::Refiner;
using detail::BoundaryColours;
using detail::colours_of;
using detail::silhouette_at;
using detail::base_face_visible;
using detail::tip_face_visible;

Status<VisionError> FeatureExtractor::refine_corners(const ImageView& image, const solver::CameraModel& camera,
                                                     const solver::InstrumentModel& model,
                                                     const solver::PoseVector& r,
                                                     const solver::Vec2& streak_px) noexcept {
  Extraction& e = result_;
  if (!e.refined) {
    e.stage4_corners = e.corners;
  }
  e.refined = true;
  for (auto& c : e.corners) {
    c = Corner{};
  }
  e.corner_count = 0;
  e.boundary_measured.fill(false);
  e.boundary_shift_mm.fill(0.0);
  if (image.data == nullptr || image.width < 2 || image.height < 2 || !r.allFinite()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  const solver::PoseFrames frames = model.frames(r);
  Refiner refiner(image, colors_, config_, camera, model, frames, edge_scratch_.get());
  refiner.use_streak(streak_px);
  const auto& g = model.geometry();
  for (int j = 0; j < kNumBoundaries; ++j) {
    const BoundaryColours colours = colours_of(config_, j);
    const double s_j = g.boundaries_mm[static_cast<std::size_t>(j)];
    // Two passes: the wide search, then a narrow one around its result
    // (the arc's shape follows the shift). The base boundary's arc is not
    // read (in most views it lies behind the shaft, nearer to the camera and
    // only 0.06 mm thinner, so its colour change is the shaft's outline; its
    // end face's rim is read instead, below), nor the tip boundary's when
    // the tip's end face is turned towards the camera (the blue-to-grey
    // change is then the grasper's outline on that face, 0.1-0.3 mm from
    // the circle: docs/vision.md; the image fit still reads that arc,
    // which measured better than leaving it out there),
    // nor is any arc that shows no clear colour change: such a boundary's
    // corners are the limb points of the pose given (fitted to the image by
    // fit_pose_to_image), reported with refine_predicted_confidence.
    double shift = 0.0;
    double step = 0.0;
    bool measured = colours.usable && j != 0 && !(j == kNumBoundaries - 1 && tip_face_visible(model, frames)) &&
                    refiner.arc_shift(s_j, colours, config_.refiner.refine_search_mm, step);
    if (measured) {
      shift = step;
      measured = refiner.arc_shift(s_j + shift, colours, 0.4, step);
      shift += measured ? step : 0.0;
      measured = measured && std::fabs(shift) <= config_.refiner.refine_search_mm;
    }
    if (!measured) {
      shift = 0.0;
    }
    // The base's position along the tube from its end face's rim, when that
    // face is turned towards the camera; its corners are then the limb
    // points of the shifted circle (the silhouette beside them is the
    // shaft's outline as much as the tube's, so no offset across).
    const bool base = j == 0;
    if (base && config_.refiner.refine_base_rim && base_face_visible(model, frames)) {
      const double rim_radius = g.shaft_radius_mm + config_.refiner.refine_base_rim_share * (g.radius_mm - g.shaft_radius_mm);
      measured = refiner.rim_shift(rim_radius, step);
      shift = measured ? step : 0.0;
    }
    e.boundary_measured[static_cast<std::size_t>(j)] = measured;
    e.boundary_shift_mm[static_cast<std::size_t>(j)] = shift;
    for (std::size_t side = 0U; side < 2U; ++side) {
      // The limb point of the shifted circle, moved along the silhouette's
      // normal by the offset measured beside it.
      solver::Vec2 limb;
      solver::Vec2 normal;
      if (!silhouette_at(camera, model, frames, s_j + shift, side, limb, normal)) {
        continue;
      }
      // Without enough silhouette beside it (a neighbouring part in front,
      // the image's border) the corner stays the shifted circle's limb
      // point, with the confidence of a predicted one.
      double offset = 0.0;
      bool side_measured = measured && !base;
      if (side_measured && !refiner.silhouette_offset(s_j + shift, side, j, offset)) {
        offset = 0.0;
        side_measured = false;
      }
      const solver::Vec2 corner = limb + offset * normal;
      if (corner.x() < 0.0 || corner.y() < 0.0 || corner.x() > image.width - 1 || corner.y() > image.height - 1) {
        continue;
      }
      Corner& c = e.corners[2U * static_cast<std::size_t>(j) + side];
      c.found = true;
      c.pixel = Point{corner.x(), corner.y()};
      c.confidence = side_measured ? 0.9 : config_.refiner.refine_predicted_confidence;
      ++e.corner_count;
    }
  }
  if (e.corner_count == 0) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  return ok_status<VisionError>();
}

void FeatureExtractor::restore_stage4_corners() noexcept {
  if (result_.refined) {
    restore_corners(result_.stage4_corners);
    result_.refined = false;
    result_.boundary_measured.fill(false);  // stage 4 measures no boundary along the model
    result_.boundary_shift_mm.fill(0.0);
  }
}

void FeatureExtractor::restore_snapshot(const CornerSnapshot& snapshot) noexcept {
  restore_corners(snapshot.corners);
  result_.refined = snapshot.refined;
  result_.boundary_measured = snapshot.boundary_measured;
  result_.boundary_shift_mm = snapshot.boundary_shift_mm;
}

void FeatureExtractor::restore_corners(const std::array<Corner, kNumCorners>& corners) noexcept {
  Extraction& e = result_;
  e.corners = corners;
  e.corner_count = 0;
  for (const Corner& c : e.corners) {
    e.corner_count += c.found ? 1 : 0;
  }
}

}  // namespace vision
}  // namespace tcpest
