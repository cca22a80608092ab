// Shared helpers of the renderer tests: the default camera and geometry, a
// frame buffer, and a renderer built once per test program.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "tcpest/render/renderer.hpp"

namespace tcpest {
namespace render {
namespace test {

struct Frame {
  std::vector<std::uint8_t> pixels;
  std::vector<float> coverage;
  MutableImageView view;
  explicit Frame(int w, int h)
      : pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3U),
        coverage(static_cast<std::size_t>(w) * static_cast<std::size_t>(h)),
        view{pixels.data(), w, h, static_cast<std::size_t>(w) * 3U} {}
};

inline solver::CameraModel pal_camera() { return solver::CameraModel::create(solver::default_pal_camera()).value(); }
inline solver::InstrumentModel default_instrument() {
  return solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
}
inline std::unique_ptr<Renderer> make_renderer(const solver::CameraModel& camera,
                                               const RenderSettings& settings = RenderSettings{}) {
  auto r = Renderer::create(camera, default_instrument(), settings);
  return r.ok() ? std::move(r.value()) : nullptr;
}

}  // namespace test
}  // namespace render
}  // namespace tcpest
