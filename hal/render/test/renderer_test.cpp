#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "render_test_support.hpp"
#include "tcpest/render/dataset.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace render {
namespace {

using solver::PoseVector;

PoseVector nominal(double lambda, double phi_deg, double theta_deg) {
  return solver::InstrumentGeometry{}.nominal_pose(lambda, solver::deg_to_rad(phi_deg), solver::deg_to_rad(theta_deg));
}

double covered_pixels(const test::Frame& f) {
  double sum = 0.0;
  for (float c : f.coverage) {
    sum += static_cast<double>(c);
  }
  return sum;
}

class RendererTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    camera_ = new solver::CameraModel(test::pal_camera());
    renderer_ = test::make_renderer(*camera_).release();
  }
  static void TearDownTestSuite() {
    delete renderer_;
    delete camera_;
  }
  static solver::CameraModel* camera_;
  static Renderer* renderer_;
};
solver::CameraModel* RendererTest::camera_ = nullptr;
Renderer* RendererTest::renderer_ = nullptr;

// Verifies: REQ-HAL-008
TEST_F(RendererTest, SameSeedGivesByteIdenticalImages) {
  ASSERT_NE(renderer_, nullptr);
  test::Frame a(720, 576);
  test::Frame b(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 30.0, 60.0);
  scene.seed = 42U;
  scene.hard_cases = kAllHardCases;
  scene.second_instrument = true;
  scene.r2 = renderer_->mirrored_nominal_pose(20.0, 0.4, -0.9);
  GroundTruth ta;
  GroundTruth tb;
  ASSERT_TRUE(renderer_->render(scene, a.view, ta).ok());
  // Something else in between: no state may leak from one frame to the next.
  SceneSpec other = scene;
  other.seed = 7U;
  other.hard_cases = 0U;
  ASSERT_TRUE(renderer_->render(other, b.view, tb).ok());
  EXPECT_NE(a.pixels, b.pixels);
  ASSERT_TRUE(renderer_->render(scene, b.view, tb).ok());
  EXPECT_EQ(a.pixels, b.pixels);
  // A second renderer of the same camera gives the same bytes.
  auto second = test::make_renderer(*camera_);
  ASSERT_NE(second, nullptr);
  test::Frame c(720, 576);
  ASSERT_TRUE(second->render(scene, c.view, tb).ok());
  EXPECT_EQ(a.pixels, c.pixels);
}

// A look (Appearance) changes how the frame looks, never what it shows:
// the same ground truth, other pixels; the default look is the renderer's
// own; a look outside what a render can show is refused.
// Verifies: REQ-HAL-009
TEST_F(RendererTest, ALookChangesThePixelsNotTheTruth) {
  test::Frame plain(720, 576);
  test::Frame looked(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 20.0, 50.0);
  scene.seed = 11U;
  GroundTruth plain_truth;
  ASSERT_TRUE(renderer_->render(scene, plain.view, plain_truth).ok());
  SceneSpec other = scene;
  other.appearance = random_look(5U).appearance;
  GroundTruth looked_truth;
  ASSERT_TRUE(renderer_->render(other, looked.view, looked_truth).ok());
  EXPECT_NE(plain.pixels, looked.pixels);
  for (std::size_t k = 0; k < solver::kNumCorners; ++k) {
    EXPECT_EQ(plain_truth.instruments[0].corners[k], looked_truth.instruments[0].corners[k]) << k;
    EXPECT_EQ(plain_truth.instruments[0].visible[k], looked_truth.instruments[0].visible[k]) << k;
  }
  // Back to the default look: the renderer keeps no look of the last frame.
  ASSERT_TRUE(renderer_->render(scene, looked.view, looked_truth).ok());
  EXPECT_EQ(plain.pixels, looked.pixels);
  SceneSpec bad = scene;
  bad.appearance.white_balance[0] = 0.0;
  EXPECT_EQ(renderer_->render(bad, looked.view, looked_truth).error(), RenderError::BadScene);
  bad = scene;
  bad.appearance.blue_albedo[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(renderer_->render(bad, looked.view, looked_truth).error(), RenderError::BadScene);
}

// The parts the solver does not model (the shaft's and the grasper's
// radii) and the lamp beside the lens change the pixels, never the corners
// or the TCP; the lamp casts the instrument's shadow on the tissue; out of
// their ranges the scene is refused.
// Verifies: REQ-HAL-009
TEST_F(RendererTest, PartRadiiAndTheLampChangeThePixelsNotTheTruth) {
  test::Frame plain(720, 576);
  test::Frame changed(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 20.0, 50.0);
  scene.seed = 12U;
  GroundTruth plain_truth;
  ASSERT_TRUE(renderer_->render(scene, plain.view, plain_truth).ok());
  const auto same_truth = [&plain_truth](const GroundTruth& t) {
    EXPECT_EQ(plain_truth.instruments[0].tcp, t.instruments[0].tcp);
    for (std::size_t k = 0; k < solver::kNumCorners; ++k) {
      EXPECT_EQ(plain_truth.instruments[0].corners[k], t.instruments[0].corners[k]) << k;
    }
  };
  SceneSpec wider = scene;
  wider.appearance.grasper_radius_scale = 1.15;
  wider.appearance.shaft_radius_scale = 0.9;
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(wider, changed.view, truth).ok());
  EXPECT_NE(plain.pixels, changed.pixels);
  same_truth(truth);
  SceneSpec lamp = scene;
  lamp.appearance.lamp_offset_mm = {3.0, -2.0};
  ASSERT_TRUE(renderer_->render(lamp, changed.view, truth).ok());
  EXPECT_NE(plain.pixels, changed.pixels);
  same_truth(truth);
  // The lamp beside the lens casts the instrument's shadow on the tissue:
  // tissue beside the instrument (not its own pixels, whose shading moves
  // less) turns much darker than under the lamp at the lens.
  SceneSpec near = scene;
  near.clean = true;
  near.tissue_depth_mm = 45.0;
  std::vector<float> coverage(720U * 576U);
  ASSERT_TRUE(renderer_->render(near, plain.view, truth, coverage.data()).ok());
  near.appearance.lamp_offset_mm = {0.0, 4.0};
  ASSERT_TRUE(renderer_->render(near, changed.view, truth, coverage.data()).ok());
  int shadowed = 0;
  for (std::size_t i = 0U; i < coverage.size(); ++i) {
    const int before = plain.pixels[3U * i] + plain.pixels[3U * i + 1U] + plain.pixels[3U * i + 2U];
    const int after = changed.pixels[3U * i] + changed.pixels[3U * i + 1U] + changed.pixels[3U * i + 2U];
    shadowed += coverage[i] == 0.0F && before > 60 && 2 * after < before ? 1 : 0;
  }
  EXPECT_GT(shadowed, 100);
  SceneSpec bad = scene;
  bad.appearance.grasper_radius_scale = 2.0;
  EXPECT_EQ(renderer_->render(bad, changed.view, truth).error(), RenderError::BadScene);
  bad = scene;
  bad.appearance.lamp_offset_mm[1] = 25.0;
  EXPECT_EQ(renderer_->render(bad, changed.view, truth).error(), RenderError::BadScene);
}

TEST_F(RendererTest, AFixedWorldSeedKeepsTheSceneOnlyTheNoiseChanges) {
  test::Frame a(720, 576);
  test::Frame b(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 10.0, 30.0);
  scene.clean = true;  // no sensor noise: only the world could differ
  scene.world_seed = 77U;
  scene.tissue_depth_mm = 80.0;
  scene.seed = 1U;
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, a.view, truth).ok());
  scene.seed = 2U;
  ASSERT_TRUE(renderer_->render(scene, b.view, truth).ok());
  EXPECT_EQ(a.pixels, b.pixels);
  scene.world_seed = 78U;
  ASSERT_TRUE(renderer_->render(scene, b.view, truth).ok());
  EXPECT_NE(a.pixels, b.pixels);
}

TEST_F(RendererTest, EveryHardCaseRendersAndChangesTheImage) {
  test::Frame base(720, 576);
  test::Frame hard(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, -30.0, 70.0);
  scene.seed = 9U;
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, base.view, truth).ok());
  for (int b = 0; b < kNumHardCases; ++b) {
    scene.hard_cases = 1U << static_cast<unsigned>(b);
    ASSERT_TRUE(renderer_->render(scene, hard.view, truth).ok());
    EXPECT_NE(base.pixels, hard.pixels) << hard_case_name(b);
    EXPECT_EQ(truth.hard_cases, scene.hard_cases);
  }
}

TEST_F(RendererTest, RenderDoesNotAllocate) {
  test::Frame f(720, 576);
  SceneSpec scene;
  scene.r = nominal(30.0, 45.0, -50.0);
  scene.hard_cases = kAllHardCases;
  scene.second_instrument = true;
  scene.r2 = renderer_->mirrored_nominal_pose(20.0, 0.0, 0.5);
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, f.view, truth, f.coverage.data()).ok());  // warm-up
  tcpest::test::AllocationScope scope;
  ASSERT_TRUE(renderer_->render(scene, f.view, truth, f.coverage.data()).ok());
  EXPECT_EQ(scope.count(), 0U);
}

// Verifies: REQ-HAL-008
TEST_F(RendererTest, GroundTruthMatchesTheModel) {
  test::Frame f(720, 576);
  SceneSpec scene;
  scene.r = nominal(20.0, 0.0, 40.0);
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, f.view, truth).ok());
  solver::CornerSet corners;
  renderer_->instrument().corners(*camera_, scene.r, corners);
  const InstrumentTruth& it = truth.instruments[0];
  EXPECT_EQ(it.view, InstrumentView::Visible);
  EXPECT_EQ(truth.instrument_count, 1);
  EXPECT_LT((it.tcp - renderer_->instrument().tcp(scene.r)).norm(), 1e-12);
  for (int k = 0; k < solver::kNumCorners; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    EXPECT_EQ(it.present[ku], corners.present[ku]);
    EXPECT_EQ(it.in_image[ku], corners.in_image[ku]);
    if (corners.present[ku]) {
      EXPECT_LT((it.corners[ku] - corners.pixel[ku]).norm(), 1e-12);
    }
  }
  // A gentle bend seen from the side: every corner visible.
  EXPECT_EQ(it.corners_visible, 12);
  // ground_truth() alone agrees with render().
  GroundTruth alone;
  ASSERT_TRUE(renderer_->ground_truth(scene, alone).ok());
  EXPECT_EQ(alone.instruments[0].visible, it.visible);
}

TEST_F(RendererTest, SelfOcclusionHidesCornersBehindTheTube) {
  // Bent back towards the camera, part of the bending section hides the base:
  // some corners in the image must be reported hidden.
  test::Frame f(720, 576);
  int hidden_total = 0;
  for (int index = 0; index < kLabGridSize; ++index) {
    SceneSpec scene;
    scene.r = lab_sample(renderer_->instrument().geometry(), index, 3U).r;
    GroundTruth truth;
    ASSERT_TRUE(renderer_->ground_truth(scene, truth).ok());
    const InstrumentTruth& it = truth.instruments[0];
    hidden_total += it.corners_in_image - it.corners_visible;
    for (int k = 0; k < solver::kNumCorners; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      EXPECT_TRUE(!it.visible[ku] || it.in_image[ku]);
    }
  }
  EXPECT_GT(hidden_total, 0);
}

TEST_F(RendererTest, OccluderHidesTheCornersUnderIt) {
  test::Frame f(720, 576);
  int hidden_by_occluder = 0;
  for (std::uint64_t seed = 1U; seed <= 20U; ++seed) {
    SceneSpec scene;
    scene.r = nominal(25.0, 20.0, 40.0);
    scene.seed = seed;
    GroundTruth clear;
    ASSERT_TRUE(renderer_->ground_truth(scene, clear).ok());
    scene.hard_cases = kHardOccluder;
    GroundTruth occluded;
    ASSERT_TRUE(renderer_->ground_truth(scene, occluded).ok());
    hidden_by_occluder += clear.instruments[0].corners_visible - occluded.instruments[0].corners_visible;
    EXPECT_LE(occluded.instruments[0].corners_visible, clear.instruments[0].corners_visible);
  }
  EXPECT_GT(hidden_by_occluder, 0);
}

TEST_F(RendererTest, LabelsTellWhatEachPixelShows) {
  test::Frame f(720, 576);
  SceneSpec scene;
  scene.r = nominal(20.0, 0.0, 40.0);
  scene.clean = true;
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, f.view, truth, f.coverage.data()).ok());
  const std::uint8_t* labels = renderer_->labels();
  int per_marker[5] = {0, 0, 0, 0, 0};
  for (std::size_t i = 0; i < 720U * 576U; ++i) {
    const int l = labels[i];
    const bool instrument = l >= kPixelInstrument && l < kPixelInstrument + 8;
    // A pixel centre on the instrument is (almost) fully covered, and vice versa.
    if (instrument) {
      EXPECT_GT(f.coverage[i], 0.0F);
    } else {
      EXPECT_LT(f.coverage[i], 1.0F);
    }
    if (l >= kPixelInstrument + kPartMarker1Label && l < kPixelInstrument + kPartMarker1Label + 5) {
      ++per_marker[l - kPixelInstrument - kPartMarker1Label];
    }
  }
  for (int m = 0; m < 5; ++m) {
    EXPECT_GT(per_marker[m], 50) << "marker " << m + 1;
  }
}

// Verifies: REQ-HAL-008
TEST_F(RendererTest, InstrumentBehindTheCameraGivesAValidImageWithoutIt) {
  test::Frame f(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 0.0, 30.0);
  scene.r[solver::kPsi] = solver::kPi;  // channel pointing backwards
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, f.view, truth, f.coverage.data()).ok());
  EXPECT_EQ(truth.instruments[0].view, InstrumentView::BehindCamera);
  EXPECT_EQ(truth.instruments[0].corners_in_image, 0);
  EXPECT_EQ(covered_pixels(f), 0.0);
}

// Verifies: REQ-HAL-008
TEST_F(RendererTest, InstrumentOutOfViewGivesAValidImageWithoutIt) {
  test::Frame f(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 0.0, 30.0);
  scene.r[solver::kXch] = 400.0;
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, f.view, truth, f.coverage.data()).ok());
  EXPECT_EQ(truth.instruments[0].view, InstrumentView::OutOfView);
  EXPECT_EQ(covered_pixels(f), 0.0);
}

TEST_F(RendererTest, SecondInstrumentIsRenderedWithItsOwnTruth) {
  test::Frame one(720, 576);
  test::Frame two(720, 576);
  SceneSpec scene;
  scene.r = nominal(25.0, 30.0, 60.0);
  GroundTruth truth;
  ASSERT_TRUE(renderer_->render(scene, one.view, truth, one.coverage.data()).ok());
  scene.second_instrument = true;
  scene.r2 = renderer_->mirrored_nominal_pose(25.0, -0.5, 1.0);
  ASSERT_TRUE(renderer_->render(scene, two.view, truth, two.coverage.data()).ok());
  EXPECT_EQ(truth.instrument_count, 2);
  EXPECT_EQ(truth.instruments[1].view, InstrumentView::Visible);
  EXPECT_GT(truth.instruments[1].corners_in_image, 6);
  EXPECT_GT(covered_pixels(two), covered_pixels(one) + 1000.0);
  // Mirrored in x: the second channel exit is on the other side.
  EXPECT_GT(truth.instruments[1].r[solver::kXch], 0.0);
  EXPECT_LT(truth.instruments[0].r[solver::kXch], 0.0);
}

TEST_F(RendererTest, BadInputIsRefused) {
  test::Frame f(720, 576);
  test::Frame small(320, 240);
  SceneSpec scene;
  scene.r = nominal(25.0, 0.0, 30.0);
  GroundTruth truth;
  EXPECT_EQ(renderer_->render(scene, small.view, truth).error(), RenderError::BadImage);
  MutableImageView null_view{};
  EXPECT_EQ(renderer_->render(scene, null_view, truth).error(), RenderError::BadImage);
  scene.r[solver::kTheta] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(renderer_->render(scene, f.view, truth).error(), RenderError::BadScene);
  scene.r[solver::kTheta] = 0.3;
  scene.exposure = -1.0;
  EXPECT_EQ(renderer_->render(scene, f.view, truth).error(), RenderError::BadScene);
  scene.exposure = 1.0;
  scene.second_instrument = true;
  scene.r2[0] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(renderer_->render(scene, f.view, truth).error(), RenderError::BadScene);
  RenderSettings bad;
  bad.supersample = 0;
  EXPECT_EQ(Renderer::create(*camera_, test::default_instrument(), bad).error(), RenderError::BadSettings);
  bad.supersample = 4;
  bad.segments_per_stripe = 1000;
  EXPECT_EQ(Renderer::create(*camera_, test::default_instrument(), bad).error(), RenderError::BadSettings);
  EXPECT_EQ(Renderer::create(solver::CameraModel{}, test::default_instrument(), RenderSettings{}).error(),
            RenderError::BadImage);
}

// Memory running out at each of create()'s allocations in turn (the
// renderer, its ray tables, scratch and textures): OutOfMemory, everything
// taken before freed.
// Verifies: REQ-ERR-007
TEST_F(RendererTest, CreateReportsOutOfMemoryAtAnyOfItsAllocations) {
  if (!tcpest::test::malloc_hook_active()) {
    GTEST_SKIP() << "malloc belongs to the sanitizer's runtime in this build";
  }
  RenderError error = RenderError::BadImage;
  const auto create = [&]() {
    const auto renderer = Renderer::create(*camera_, test::default_instrument(), RenderSettings{});
    error = renderer.ok() ? RenderError::BadImage : renderer.error();
    return renderer.ok();  // released here: only the count matters
  };
  const std::size_t allocations = tcpest::test::run_out_of_memory_at_each_allocation(create, [&](const tcpest::test::OutOfMemoryOutcome& o) {
    ASSERT_FALSE(o.succeeded) << "allocation " << o.nth;
    EXPECT_EQ(error, RenderError::OutOfMemory) << "allocation " << o.nth;
    EXPECT_EQ(o.leaked, 0U) << "out of memory at allocation " << o.nth;
  });
  EXPECT_GE(allocations, 10U);
}

TEST_F(RendererTest, AbsurdButFiniteConfigurationsRenderWithoutHarm) {
  test::Frame f(720, 576);
  const double values[] = {0.0, -1e6, 1e-300, 1e12, 250.0};
  int i = 0;
  for (double a : values) {
    for (double b : values) {
      SceneSpec scene;
      scene.r << a, -b, a * 0.01, b, b, a, a * 0.1;
      scene.seed = static_cast<std::uint64_t>(++i);
      scene.hard_cases = (i % 2 == 0) ? kAllHardCases : 0U;
      GroundTruth truth;
      ASSERT_TRUE(renderer_->render(scene, f.view, truth, f.coverage.data()).ok()) << scene.r.transpose();
    }
  }
}

TEST(RendererFold, PixelsBeyondTheFoldAreBlackAndNothingBreaks) {
  // An HD endoscope calibration whose polynomial folds inside the image's
  // corners: those pixels have no ray and stay black.
  solver::CameraIntrinsics k;
  k.width = 640;
  k.height = 360;
  k.fx = 300.0;
  k.fy = 300.0;
  k.cx = 319.5;
  k.cy = 179.5;
  k.k1 = -0.45;
  k.k2 = 0.05;
  const auto created = solver::CameraModel::create(k);
  ASSERT_TRUE(created.ok());
  const auto& camera = created.value();
  ASSERT_TRUE(std::isfinite(camera.max_r2()));
  auto renderer = test::make_renderer(camera);
  ASSERT_NE(renderer, nullptr);
  test::Frame f(640, 360);
  SceneSpec scene;
  scene.r = nominal(25.0, 0.0, 30.0);
  GroundTruth truth;
  ASSERT_TRUE(renderer->render(scene, f.view, truth).ok());
  solver::Vec2 ray;
  ASSERT_FALSE(camera.undistort(solver::Vec2(0.0, 0.0), ray));
  EXPECT_EQ(f.pixels[0], 0U);
  EXPECT_EQ(f.pixels[1], 0U);
  EXPECT_EQ(f.pixels[2], 0U);
  const std::size_t centre = (180U * 640U + 320U) * 3U;
  EXPECT_GT(static_cast<int>(f.pixels[centre]) + f.pixels[centre + 1] + f.pixels[centre + 2], 30);
}

}  // namespace
}  // namespace render
}  // namespace tcpest
