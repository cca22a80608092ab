// The four stages on frames rendered by hal/render, and the allocation
// proof: hundreds of frames through stages 1-4 and the solver without any
// heap allocation after start-up.
#include <gtest/gtest.h>

#include <vector>

#include "tcpest/render/renderer.hpp"
#include "tcpest/solver/pose_solver.hpp"
#include "tcpest/test/alloc_counter.hpp"
#include "tcpest/vision/features.hpp"
#include "tcpest/vision/overlay.hpp"

namespace tcpest {
namespace vision {
namespace {

struct Fixture {
  solver::CameraModel camera = solver::CameraModel::create(solver::default_pal_camera()).value();
  solver::InstrumentModel model = solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
  std::unique_ptr<render::Renderer> renderer;
  std::vector<std::uint8_t> pixels;
  render::GroundTruth truth;
  Fixture() {
    auto created = render::Renderer::create(camera, model, render::RenderSettings{});
    renderer = std::move(created.value());
    pixels.resize(static_cast<std::size_t>(camera.width() * camera.height() * 3));
  }
  ImageView render_pose(double lambda, double phi_deg, double theta_deg) {
    render::SceneSpec spec;
    spec.r = model.geometry().nominal_pose(lambda, solver::deg_to_rad(phi_deg), solver::deg_to_rad(theta_deg));
    const MutableImageView out{pixels.data(), camera.width(), camera.height(),
                               static_cast<std::size_t>(camera.width()) * 3U};
    EXPECT_TRUE(renderer->render(spec, out, truth).ok());
    return out.view();
  }
};

TEST(Pipeline, FindsTheMarkerChainAndCornersOnARenderedFrame) {
  Fixture f;
  const ImageView image = f.render_pose(25.0, 30.0, 40.0);
  ExtractorConfig config;
  auto created = FeatureExtractor::create(config, default_color_model());
  ASSERT_TRUE(created.ok());
  auto fx = std::move(created.value());
  const MarkerPriors priors = model_priors(f.camera, f.model, f.truth.instruments[0].r);
  ASSERT_TRUE(fx->extract(image, priors).ok());
  const Extraction& e = fx->result();
  EXPECT_GE(e.interpretation.found_count, 4);
  EXPECT_TRUE(e.borders[0].valid);
  EXPECT_TRUE(e.borders[1].valid);
  EXPECT_GE(e.corner_count, 6);
  // The overlay draws without touching anything outside the image.
  std::vector<std::uint8_t> copy(image.data, image.data + image.stride_bytes * static_cast<std::size_t>(image.height));
  draw_extraction(MutableImageView{copy.data(), image.width, image.height, image.stride_bytes}, e, ReprojectedModel{});
}

TEST(Pipeline, NoInstrumentIsAnErrorValue) {
  Fixture f;
  std::vector<std::uint8_t> tissue(f.pixels.size(), 120U);
  const ImageView image{tissue.data(), f.camera.width(), f.camera.height(),
                        static_cast<std::size_t>(f.camera.width()) * 3U};
  auto created = FeatureExtractor::create(ExtractorConfig{}, default_color_model());
  ASSERT_TRUE(created.ok());
  auto fx = std::move(created.value());
  const auto status = fx->extract(image, generic_priors(f.camera, f.model));
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error(), VisionError::NoInstrument);
}

TEST(Pipeline, ZeroHeapAllocationsPerFrameInStages1To4AndTheSolver) {
  Fixture f;
  // A few different frames, rendered before the counted scope.
  std::vector<std::vector<std::uint8_t>> frames;
  const double poses[4][3] = {{20.0, 0.0, 0.0}, {25.0, 30.0, 40.0}, {30.0, -60.0, -60.0}, {35.0, 60.0, 80.0}};
  for (const auto& p : poses) {
    static_cast<void>(f.render_pose(p[0], p[1], p[2]));
    frames.push_back(f.pixels);
  }
  auto created = FeatureExtractor::create(ExtractorConfig{}, default_color_model());
  ASSERT_TRUE(created.ok());
  auto fx = std::move(created.value());
  solver::PoseSolver pose_solver(f.camera, f.model);
  TemporalPriors temporal;
  const MarkerPriors generic = generic_priors(f.camera, f.model);
  int extracted = 0;
  {
    test::AllocationScope scope;
    for (int i = 0; i < 300; ++i) {
      const auto& px = frames[static_cast<std::size_t>(i) % frames.size()];
      const ImageView image{px.data(), f.camera.width(), f.camera.height(),
                            static_cast<std::size_t>(f.camera.width()) * 3U};
      MarkerPriors priors;
      if (!temporal.priors(priors)) {
        priors = generic;
      }
      if (fx->extract(image, priors).ok()) {
        ++extracted;
        temporal.add(fx->result().interpretation);
      }
      solver::CornerObservation observed;
      corners_to_arrays(fx->result(), observed.pixel, observed.visible);
      solver::PoseVector r = f.model.geometry().nominal_pose(25.0, 0.0, 0.0);
      static_cast<void>(pose_solver.solve(observed, solver::SolveMode::Adaptive, r));  // outcome not under test
    }
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_GT(extracted, 0);
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
