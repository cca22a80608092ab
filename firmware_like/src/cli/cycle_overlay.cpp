#include "cli/cycle_overlay.hpp"

#include <cstddef>
#include <cstring>

#include "tcpest/vision/overlay.hpp"

namespace tcpest {
namespace cli {

namespace {

// The model's corners and TCP in the image at the cycle's estimate.
vision::ReprojectedModel reproject(const ModelSetup& models, const loop::CycleRecord& r) noexcept {
  vision::ReprojectedModel model;
  if (!r.solved) {
    return model;
  }
  solver::CornerSet corners;
  models.instrument.corners(models.camera, r.publication.r, corners, nullptr);
  model.valid = true;
  for (std::size_t k = 0; k < static_cast<std::size_t>(vision::kNumCorners); ++k) {
    model.present[k] = corners.present[k];
    model.corners[k] = vision::Point{corners.pixel[k].x(), corners.pixel[k].y()};
  }
  solver::Vec2 tcp_px;
  if (models.camera.project(corners.tcp, tcp_px)) {
    model.tcp_valid = true;
    model.tcp = vision::Point{tcp_px.x(), tcp_px.y()};
  }
  return model;
}

}  // namespace

void draw_cycle_overlay(const MutableImageView& out, const ImageView& frame, const vision::Extraction* extraction,
                        const ModelSetup& models, const loop::CycleRecord& r, const hal::FrameTruth* truth) noexcept {
  for (int y = 0; y < frame.height; ++y) {
    std::memcpy(out.row(y), frame.row(y), static_cast<std::size_t>(frame.width) * 3U);
  }
  const vision::ReprojectedModel model = reproject(models, r);
  if (extraction != nullptr) {
    vision::draw_extraction(out, *extraction, model);
  }
  if (truth != nullptr && truth->valid) {
    solver::Vec2 truth_px;
    const solver::Vec3 truth_tcp(truth->tcp_mm[0], truth->tcp_mm[1], truth->tcp_mm[2]);
    if (models.camera.project(truth_tcp, truth_px)) {
      vision::draw_cross(out, vision::Point{truth_px.x(), truth_px.y()}, 9, 0U, 255U, 0U);  // truth: green cross
    }
  }
}

}  // namespace cli
}  // namespace tcpest
