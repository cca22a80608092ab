// Stage 3, the borders (borders.hpp), on its own: a BorderFitter created
// alone, given drawn stripes, their classes and a labelling made without
// stage 2, fits each side of the tube where it was drawn.
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "drawn_canvas.hpp"
#include "tcpest/vision/borders.hpp"

namespace tcpest {
namespace vision {
namespace {

using testing::Canvas;
using testing::draw_in_line;
using testing::in_line_interpretation;
using testing::kStripeWidth;
using testing::kTop;
using testing::make_finder;

struct Fitted {
  std::array<Border, 2> borders{};
  std::array<Point, kMaxSkeletonSamples> skeleton{};
  int skeleton_count = 0;
};

// Five stripes drawn in line along x (the tube's top edge between rows 39
// and 40, its bottom edge between rows 79 and 80), and their classes.
// Verifies: REQ-VISION-005
TEST(BorderFitter, TheBordersOfDrawnStripesLieOnTheirEdges) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 0, kNumMarkers - 1);
  auto finder = make_finder(canvas.w, canvas.h);
  RegionSet regions;
  ASSERT_TRUE(finder->find(canvas.view(), regions).ok());
  const Interpretation in = in_line_interpretation(regions, 0, kNumMarkers - 1);
  auto created = BorderFitter::create(BordersConfig{});
  ASSERT_TRUE(created.ok());
  Fitted out;
  ASSERT_TRUE(created.value()
                  ->fit(canvas.view(), finder->classes(), in, out.borders, out.skeleton, out.skeleton_count)
                  .ok());
  EXPECT_EQ(out.skeleton_count, BordersConfig{}.skeleton_samples);
  // Side 1 lies along (-t_y, t_x) of the skeleton's direction (+x): below.
  const double offset = BordersConfig{}.edge_offset_px;  // outwards from the gradient's maximum
  const std::array<double, 2> edge_y{{kTop - 0.5 - offset, kTop + kStripeWidth - 0.5 + offset}};
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Border& b = out.borders[side];
    ASSERT_TRUE(b.valid) << side;
    EXPECT_GE(b.points.size(), 30U) << side;
    for (const double t : {0.0, 0.25, 0.5, 0.75, 1.0}) {
      EXPECT_NEAR(b.curve.at(t).y, edge_y[side], 0.25) << side << " at " << t;
    }
    // The border spans the striped section, from before the first stripe
    // to past the last.
    EXPECT_LT(std::fmin(b.curve.p0.x, b.curve.p2.x), 45.0) << side;
    EXPECT_GT(std::fmax(b.curve.p0.x, b.curve.p2.x), 185.0) << side;
  }
  for (int i = 0; i < out.skeleton_count; ++i) {
    EXPECT_NEAR(out.skeleton[static_cast<std::size_t>(i)].y, kTop + 0.5 * (kStripeWidth - 1), 1e-6) << i;
  }
}

TEST(BorderFitter, ALabellingOfOneMarkerOrAnImageOfAnotherSizeFails) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 0, kNumMarkers - 1);
  auto finder = make_finder(canvas.w, canvas.h);
  RegionSet regions;
  ASSERT_TRUE(finder->find(canvas.view(), regions).ok());
  auto fitter = BorderFitter::create(BordersConfig{});
  ASSERT_TRUE(fitter.ok());
  Fitted out;
  const Interpretation one = in_line_interpretation(regions, 2, 2);
  EXPECT_EQ(fitter.value()->fit(canvas.view(), finder->classes(), one, out.borders, out.skeleton, out.skeleton_count).error(),
            VisionError::BorderFitFailed);
  EXPECT_FALSE(out.borders[0].valid);
  Canvas other(200, 140);
  const Interpretation all = in_line_interpretation(regions, 0, kNumMarkers - 1);
  EXPECT_EQ(fitter.value()->fit(other.view(), finder->classes(), all, out.borders, out.skeleton, out.skeleton_count).error(),
            VisionError::BorderFitFailed);
}

// Verifies: REQ-VISION-012
TEST(BorderFitter, CreateRejectsBadConfiguration) {
  BordersConfig samples;
  samples.skeleton_samples = static_cast<int>(kMaxSkeletonSamples) + 1;
  EXPECT_EQ(BorderFitter::create(samples).error(), VisionError::BadParameter);
  BordersConfig irls;
  irls.irls_scale_iterations = irls.irls_iterations + 1;
  EXPECT_EQ(BorderFitter::create(irls).error(), VisionError::BadParameter);
  BordersConfig tukey;
  tukey.tukey_c = 0.0;
  EXPECT_EQ(BorderFitter::create(tukey).error(), VisionError::BadParameter);
  EXPECT_TRUE(BorderFitter::create(BordersConfig{}).ok());
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
