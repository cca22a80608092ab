#include "tcpest/loop/rendered_scene.hpp"

#include <new>

namespace tcpest {
namespace loop {

Result<std::unique_ptr<RenderedScene>, render::RenderError> RenderedScene::create(const solver::CameraModel& camera,
                                                                                 const solver::InstrumentModel& model,
                                                                                 std::uint64_t seed, double rate_hz,
                                                                                 std::uint32_t frames) noexcept {
  using R = Result<std::unique_ptr<RenderedScene>, render::RenderError>;
  std::unique_ptr<RenderedScene> scene(new (std::nothrow) RenderedScene(model.geometry(), seed, rate_hz));
  if (!scene) {
    return R::failure(render::RenderError::OutOfMemory);
  }
  auto renderer = render::Renderer::create(camera, model, render::RenderSettings{});
  if (!renderer.ok()) {
    return R::failure(renderer.error());
  }
  scene->renderer_ = std::move(renderer.value());
  scene->width_ = camera.width();
  scene->height_ = camera.height();
  scene->frames_ = frames;
  return R::success(std::move(scene));
}

Status<hal::CameraError> RenderedScene::render(std::uint32_t index, const MutableImageView& out,
                                               hal::FrameTruth& truth) noexcept {
  render::SceneSpec spec;
  spec.r = sequence_.sample(index).r;
  spec.seed = render::image_seed(seed_, index);   // sensor noise per frame
  spec.world_seed = sequence_.world_seed();          // the same tissue in every frame
  spec.tissue_depth_mm = sequence_.tissue_depth_mm();
  const auto drawn = renderer_->render(spec, out, truth_);
  if (!drawn.ok()) {
    return Status<hal::CameraError>::failure(drawn.error() == render::RenderError::BadImage
                                                 ? hal::CameraError::kWrongSize
                                                 : hal::CameraError::kBadArgument);
  }
  const render::InstrumentTruth& t = truth_.instruments[0];
  truth.valid = true;
  for (int i = 0; i < solver::kNumParams; ++i) {
    truth.r[static_cast<std::size_t>(i)] = t.r[i];
  }
  truth.tcp_mm = {t.tcp.x(), t.tcp.y(), t.tcp.z()};
  for (std::size_t k = 0; k < static_cast<std::size_t>(solver::kNumCorners); ++k) {
    truth.corners_px[k] = {t.corners[k].x(), t.corners[k].y()};
    truth.corner_visible[k] = t.visible[k];
  }
  return ok_status<hal::CameraError>();
}

JointPrior RenderedScene::encoder_reading(std::uint32_t index) const noexcept {
  const render::SequenceSample s = sequence_.sample(index);
  return JointPrior{s.prior.joints[0], s.prior.joints[1], s.prior.joints[2]};
}

}  // namespace loop
}  // namespace tcpest
