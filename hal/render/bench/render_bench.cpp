// Frame rendering time, one core: the targets are 720x576 <= 100 ms (the
// demo renders its sequence on the fly) and 1920x1080 <= 1 s. The scenes
// are the `seq` set's poses (a typical mix of near/far, bent/straight).
#include <benchmark/benchmark.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "tcpest/render/dataset.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/render/renderer.hpp"

namespace {

using tcpest::render::GroundTruth;
using tcpest::render::Renderer;
using tcpest::render::SceneSpec;
namespace solver = tcpest::solver;

solver::CameraIntrinsics hd_camera() {
  solver::CameraIntrinsics k;
  k.width = 1920;
  k.height = 1080;
  k.fx = 1050.0;
  k.fy = 1050.0;
  k.cx = 959.5;
  k.cy = 539.5;
  k.k1 = -0.30;
  k.k2 = 0.10;
  return k;
}

void render_frames(benchmark::State& state, const solver::CameraIntrinsics& intrinsics, std::uint32_t hard,
                   bool two) {
  const auto camera = solver::CameraModel::create(intrinsics).value();
  const auto instrument = solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
  auto created = Renderer::create(camera, instrument, tcpest::render::RenderSettings{});
  if (!created.ok()) {
    state.SkipWithError("renderer creation failed");
    return;
  }
  Renderer& renderer = *created.value();
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(camera.width()) * static_cast<std::size_t>(camera.height()) * 3U);
  const tcpest::MutableImageView view{pixels.data(), camera.width(), camera.height(),
                                      static_cast<std::size_t>(camera.width()) * 3U};
  const tcpest::render::SequenceGenerator sequence(instrument.geometry(), 1U);
  std::uint32_t frame = 0U;
  for (auto _ : state) {
    SceneSpec scene;
    const auto sample = sequence.sample(frame * 10U);  // 0.4 s apart: varied poses
    scene.r = sample.r;
    scene.seed = frame;
    scene.hard_cases = hard;
    scene.second_instrument = two;
    scene.r2 = renderer.mirrored_nominal_pose(22.0, 0.3, -0.7);
    GroundTruth truth;
    if (!renderer.render(scene, view, truth).ok()) {
      state.SkipWithError("render failed");
      return;
    }
    benchmark::DoNotOptimize(pixels.data());
    ++frame;
  }
}

void BM_RenderPal(benchmark::State& state) { render_frames(state, solver::default_pal_camera(), 0U, false); }
void BM_RenderPalTwoInstruments(benchmark::State& state) {
  render_frames(state, solver::default_pal_camera(), 0U, true);
}
void BM_RenderPalAllHardCases(benchmark::State& state) {
  render_frames(state, solver::default_pal_camera(), tcpest::render::kAllHardCases, false);
}
void BM_RenderHd(benchmark::State& state) { render_frames(state, hd_camera(), 0U, false); }

void BM_JpegEncodePal(benchmark::State& state) {
  std::vector<std::uint8_t> pixels(std::size_t{720U} * 576U * 3U);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    pixels[i] = static_cast<std::uint8_t>((i * 2654435761U) >> 24U);
  }
  auto encoder = tcpest::render::JpegEncoder::create(720, 576);
  const tcpest::ImageView view{pixels.data(), 720, 576, std::size_t{720U} * 3U};
  for (auto _ : state) {
    if (!encoder.value()->encode(view, 92).ok()) {
      state.SkipWithError("encode failed");
      return;
    }
  }
}

}  // namespace

BENCHMARK(BM_RenderPal)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_RenderPalTwoInstruments)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_RenderPalAllHardCases)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_RenderHd)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK(BM_JpegEncodePal)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
