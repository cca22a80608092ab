// The frame estimator and the track: what they guarantee on constructed
// inputs (a rendered frame with its exact truth, hand-made estimates),
// not which path a frame took.
#include "tcpest/vision/frame_estimator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <limits>
#include <memory>
#include <vector>

#include "tcpest/render/renderer.hpp"
#include "tcpest/test/alloc_counter.hpp"
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {
namespace {

struct Models {
  solver::CameraModel camera = solver::CameraModel::create(solver::default_pal_camera()).value();
  solver::InstrumentModel model = solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
};

// Records the order in which the steps end.
class StepLog final : public StepObserver {
 public:
  void step_done(EstimationStep step) noexcept override {
    if (count < static_cast<int>(steps.size())) {
      steps[static_cast<std::size_t>(count)] = step;
    }
    ++count;
  }
  std::array<EstimationStep, 16> steps{};
  int count = 0;
};

// Verifies: REQ-VISION-012
TEST(EstimatorConfig, TheDefaultsAreValidAndOutOfRangeFieldsAreRefused) {
  EXPECT_TRUE(config_valid(EstimatorConfig{}));
  EstimatorConfig c;
  c.encoder_check.bend_tolerance_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(config_valid(c));
  c = EstimatorConfig{};
  c.guided.rounds = kMaxGuidedRounds + 1;
  EXPECT_FALSE(config_valid(c));
  c = EstimatorConfig{};
  c.guided.rounds = -1;
  EXPECT_FALSE(config_valid(c));
  c = EstimatorConfig{};
  c.classify_step = 3;
  EXPECT_FALSE(config_valid(c));
  c = EstimatorConfig{};
  c.solve.min_corners_valid = 2;
  EXPECT_FALSE(config_valid(c));
  const Models m;
  EXPECT_EQ(FrameEstimator::create(m.camera, m.model, default_color_model(), c).error(), VisionError::BadParameter);
}

class FrameEstimatorOnARenderedFrame : public testing::Test {
 protected:
  void SetUp() override {
    auto renderer = render::Renderer::create(m.camera, m.model, render::RenderSettings{});
    ASSERT_TRUE(renderer.ok());
    pixels.resize(static_cast<std::size_t>(m.camera.width() * m.camera.height() * 3));
    render::SceneSpec spec;
    spec.r = m.model.geometry().nominal_pose(26.0, 0.3, 0.5);
    spec.seed = 5U;
    const MutableImageView out{pixels.data(), m.camera.width(), m.camera.height(),
                               static_cast<std::size_t>(m.camera.width()) * 3U};
    ASSERT_TRUE(renderer.value()->render(spec, out, truth).ok());
    image = out.view();
    auto created = FrameEstimator::create(m.camera, m.model, default_color_model(), EstimatorConfig{});
    ASSERT_TRUE(created.ok());
    estimator = std::move(created.value());
  }
  FramePrior encoders_prior() const {
    FramePrior prior;
    prior.source = PriorSource::kEncoder;
    prior.r = m.model.geometry().nominal_pose(26.0 + 2.0, 0.3 - 0.1, 0.5 + 0.1);  // within the encoders' accuracy
    return prior;
  }
  Models m;
  std::vector<std::uint8_t> pixels;
  render::GroundTruth truth;
  ImageView image{};
  std::unique_ptr<FrameEstimator> estimator;
};

// Verifies: REQ-VISION-008
TEST_F(FrameEstimatorOnARenderedFrame, GivesAValidEstimateNearTheTruthWithEveryStepReportedInOrder) {
  StepLog log;
  const FrameEstimate e = estimator->estimate(image, encoders_prior(), &log);
  ASSERT_EQ(e.estimate.quality, solver::EstimateQuality::Valid);
  EXPECT_TRUE(e.extraction_ok);
  EXPECT_EQ(e.prior, PriorSource::kEncoder);
  EXPECT_FALSE(e.encoder_disagrees);
  EXPECT_LT((e.tcp_mm - truth.instruments[0].tcp).norm(), 1.5);
  EXPECT_LT((e.tcp_mm - m.model.tcp(e.estimate.r)).norm(), 1e-12);
  ASSERT_EQ(log.count, kNumEstimationSteps);
  for (int i = 0; i < kNumEstimationSteps; ++i) {
    EXPECT_EQ(log.steps[static_cast<std::size_t>(i)], static_cast<EstimationStep>(i));
  }
  int reported = 0;
  for (const EstimatedCorner& c : e.corners) {
    if (c.source != CornerSource::kNone) {
      ++reported;
      EXPECT_GT(c.confidence, 0.0);
      EXPECT_LE(c.confidence, 1.0);
    }
  }
  EXPECT_GE(reported, 8);
  EXPECT_EQ(e.corners_detected > 0, true);
}

// Same frames, same priors, same estimator state: the same bits (the loop's
// and the offline commands' results can be compared byte for byte), and no
// heap after start-up.
// Verifies: REQ-VISION-009
TEST_F(FrameEstimatorOnARenderedFrame, IsDeterministicAndAllocationFree) {
  const FrameEstimate a = estimator->estimate(image, encoders_prior(), nullptr);
  estimator->drop_track();
  estimator->reset_appearance();
  FrameEstimate b;
  {
    test::AllocationScope scope;
    b = estimator->estimate(image, encoders_prior(), nullptr);
    EXPECT_EQ(scope.count(), 0U);
  }
  ASSERT_EQ(a.estimate.quality, b.estimate.quality);
  for (int i = 0; i < solver::kNumParams; ++i) {
    EXPECT_EQ(a.estimate.r[i], b.estimate.r[i]) << i;
  }
}

// An image with no instrument: no pose, the failed step named, no corner reported.
// Verifies: REQ-VISION-007
TEST_F(FrameEstimatorOnARenderedFrame, AnEmptyImageGivesNoEstimateAndNamesTheFailedStep) {
  std::vector<std::uint8_t> grey(pixels.size(), 128U);
  const ImageView blank{grey.data(), m.camera.width(), m.camera.height(),
                        static_cast<std::size_t>(m.camera.width()) * 3U};
  FramePrior generic;
  generic.r = m.model.geometry().nominal_pose(kGenericLambdaMm, 0.0, 0.0);
  const FrameEstimate e = estimator->estimate(blank, generic, nullptr);
  EXPECT_FALSE(e.solved());
  EXPECT_FALSE(e.extraction_ok);
  EXPECT_LE(e.failed_step, EstimationStep::kCorners);
  for (const EstimatedCorner& c : e.corners) {
    EXPECT_EQ(c.source, CornerSource::kNone);
  }
}

// Encoders far from what the image shows: the estimate loses one level.
// Verifies: REQ-SOLVER-010
TEST_F(FrameEstimatorOnARenderedFrame, EncodersBeyondTheirAccuracyDemoteTheEstimate) {
  FramePrior far = encoders_prior();
  far.r[solver::kLambda] += 9.0;
  const FrameEstimate e = estimator->estimate(image, far, nullptr);
  ASSERT_TRUE(e.solved());
  EXPECT_TRUE(e.encoder_disagrees);
  EXPECT_EQ(e.estimate.quality, solver::EstimateQuality::Degraded);
}

FrameEstimate solved_at(const solver::PoseVector& r) {
  FrameEstimate e;
  e.estimate.quality = solver::EstimateQuality::Valid;
  e.estimate.r = r;
  return e;
}

// Verifies: REQ-VISION-011
// PartWidths: nothing until kMinFrames valid frames; then the median of
// the window when the frames agree on it (beyond twice its standard
// error), 0 when they scatter around nothing; readings that are not a
// part's (NaN, beyond kMaxWidthPx) are ignored; the window forgets; reset
// forgets everything.
// Verifies: REQ-VISION-013
TEST(PartWidths, LearnsTheMedianTheFramesAgreeOnAndForgets) {
  PartWidths widths;
  ImageFitSummary fit;
  fit.shaft_width_px = 1.0;
  fit.grasper_width_px = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < PartWidths::kMinFrames - 1; ++i) {
    widths.learn(fit);
  }
  EXPECT_EQ(widths.shaft_px(), 0.0);
  fit.shaft_width_px = 1.2;
  widths.learn(fit);
  EXPECT_DOUBLE_EQ(widths.shaft_px(), 1.0);
  EXPECT_EQ(widths.grasper_px(), 0.0);  // never read on both sides
  fit.shaft_width_px = 2.0 * PartWidths::kMaxWidthPx;
  widths.learn(fit);
  EXPECT_DOUBLE_EQ(widths.shaft_px(), 1.0);  // no silhouette of the shaft: ignored
  // Scattered around nothing: not significant.
  PartWidths scattered;
  for (int i = 0; i < PartWidths::kWindow; ++i) {
    fit.shaft_width_px = (i % 2 == 0 ? 1.0 : -1.0) * (0.2 + 0.1 * i);
    scattered.learn(fit);
  }
  EXPECT_EQ(scattered.shaft_px(), 0.0);
  // A new width replaces the old one within a window.
  for (int i = 0; i < PartWidths::kWindow; ++i) {
    fit.shaft_width_px = -0.5 + 0.01 * (i % 3);
    widths.learn(fit);
  }
  EXPECT_NEAR(widths.shaft_px(), -0.49, 1e-12);
  widths.reset();
  EXPECT_EQ(widths.shaft_px(), 0.0);
}

// A grasper wider and a shaft narrower than model.md's rendering defaults
// (a real instrument's need not be those): the valid frames teach the
// estimator how much wider and narrower their silhouettes read, the
// estimate stays valid near the truth, and reset_appearance() forgets it.
// Verifies: REQ-VISION-013
TEST(PartWidthsOnRenderedFrames, AreLearnedFromValidFramesAndForgottenAtAReset) {
  Models m;
  auto renderer = render::Renderer::create(m.camera, m.model, render::RenderSettings{});
  ASSERT_TRUE(renderer.ok());
  auto created = FrameEstimator::create(m.camera, m.model, default_color_model(), EstimatorConfig{});
  ASSERT_TRUE(created.ok());
  FrameEstimator& estimator = *created.value();
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(m.camera.width() * m.camera.height() * 3));
  const MutableImageView out{pixels.data(), m.camera.width(), m.camera.height(),
                             static_cast<std::size_t>(m.camera.width()) * 3U};
  for (int i = 0; i < PartWidths::kMinFrames + 2; ++i) {
    render::SceneSpec spec;
    spec.r = m.model.geometry().nominal_pose(24.0 + i, 0.2 + 0.1 * i, 0.6);
    spec.seed = 40U + static_cast<std::uint64_t>(i);
    spec.appearance.grasper_radius_scale = 1.25;
    spec.appearance.shaft_radius_scale = 0.9;
    render::GroundTruth truth;
    ASSERT_TRUE(renderer.value()->render(spec, out, truth).ok());
    FramePrior prior;
    prior.source = PriorSource::kEncoder;
    prior.r = m.model.geometry().nominal_pose(24.0 + i + 1.0, 0.2 + 0.1 * i - 0.05, 0.6 + 0.05);
    const FrameEstimate e = estimator.estimate(out.view(), prior, nullptr);
    ASSERT_EQ(e.estimate.quality, solver::EstimateQuality::Valid) << i;
    EXPECT_LT((e.tcp_mm - truth.instruments[0].tcp).norm(), 1.5) << i;
  }
  // 0.25 * 1.5 mm wider on each side at 50-70 mm: about a pixel; the shaft 0.9 narrower.
  EXPECT_GT(estimator.extractor().part_widths().grasper_px(), 0.4);
  EXPECT_LT(estimator.extractor().part_widths().shaft_px(), estimator.extractor().part_widths().grasper_px());
  estimator.reset_appearance();
  EXPECT_EQ(estimator.extractor().part_widths().grasper_px(), 0.0);
  EXPECT_EQ(estimator.extractor().part_widths().shaft_px(), 0.0);
}

TEST(Track, ChoosesEncodersThenTheTrackThenTheGenericPrior) {
  const Models m;
  Track track(m.model, 3);
  const solver::PoseVector generic = m.model.geometry().nominal_pose(kGenericLambdaMm, 0.0, 0.0);
  FramePrior p = track.choose(nullptr);
  EXPECT_EQ(p.source, PriorSource::kGeneric);
  EXPECT_EQ(p.r, generic);
  solver::PoseVector seen = m.model.geometry().nominal_pose(30.0, 0.2, 0.4);
  seen[solver::kXch] += 0.5;
  EXPECT_FALSE(track.update(solved_at(seen)));
  EXPECT_TRUE(track.alive());
  p = track.choose(nullptr);
  EXPECT_EQ(p.source, PriorSource::kTemporal);
  EXPECT_EQ(p.r, seen);
  // The encoders' joints on the track's channel pose.
  const double joints[3] = {31.0, 0.25, 0.45};
  p = track.choose(joints);
  EXPECT_EQ(p.source, PriorSource::kEncoder);
  EXPECT_EQ(p.r[solver::kXch], seen[solver::kXch]);
  EXPECT_EQ(p.r[solver::kLambda], 31.0);
  EXPECT_EQ(p.r[solver::kPhi], 0.25);
  EXPECT_EQ(p.r[solver::kTheta], 0.45);
}

// Verifies: REQ-VISION-011
TEST(Track, IsDroppedAfterTheConfiguredFailuresAndKeepsItsLastPoseForAHeldFrame) {
  const Models m;
  Track track(m.model, 3);
  const solver::PoseVector seen = m.model.geometry().nominal_pose(30.0, 0.2, 0.4);
  ASSERT_FALSE(track.update(solved_at(seen)));
  EXPECT_FALSE(track.update(FrameEstimate{}));  // no pose
  EXPECT_FALSE(track.frame_failed());           // a dropped frame
  EXPECT_TRUE(track.update(FrameEstimate{}));   // the third: dropped now, once
  EXPECT_FALSE(track.alive());
  EXPECT_FALSE(track.update(FrameEstimate{}));
  EXPECT_TRUE(track.has_estimate());
  EXPECT_EQ(track.last_r(), seen);
  EXPECT_EQ(track.choose(nullptr).source, PriorSource::kGeneric);
  // A success in between starts the count again.
  ASSERT_FALSE(track.update(solved_at(seen)));
  EXPECT_FALSE(track.update(FrameEstimate{}));
  EXPECT_FALSE(track.update(solved_at(seen)));
  EXPECT_FALSE(track.update(FrameEstimate{}));
  EXPECT_FALSE(track.update(FrameEstimate{}));
  EXPECT_TRUE(track.alive());
  track.reset();
  EXPECT_FALSE(track.alive());
  EXPECT_FALSE(track.has_estimate());
}

}  // namespace
}  // namespace vision
}  // namespace tcpest

namespace tcpest {
namespace vision {
namespace {

// docs/estimation.md shows the policy table: its rows are the table's, in
// the table's order (the page cannot drift from the code unnoticed).
TEST(EstimationPolicy, TheDocsListTheTableInItsOrder) {
  std::ifstream page(std::string(TCPEST_TEST_DATA_DIR) + "/../../docs/estimation.md");
  ASSERT_TRUE(page.good());
  std::vector<std::string> listed;
  std::string line;
  while (std::getline(page, line)) {
    if (line.rfind("| `", 0) == 0) {
      const std::size_t end = line.find('`', 3U);
      const std::string name = line.substr(3U, end - 3U);
      if (name.find('-') != std::string::npos || name == "stage4-solve") {
        listed.push_back(name);
      }
    }
  }
  ASSERT_EQ(listed.size(), kEstimationPolicy.size());
  for (std::size_t i = 0U; i < kEstimationPolicy.size(); ++i) {
    EXPECT_EQ(listed[i], kEstimationPolicy[i].name) << i;
  }
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
