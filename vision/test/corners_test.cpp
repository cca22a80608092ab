// Stage 4, the corners (corners.hpp), on its own: a CornerFinder created
// alone, given drawn stripes, a labelling made without stage 2 and borders
// drawn by hand on the tube's edges (no stage 3), finds each internal
// boundary's two corners where the colours change on the edges.
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "drawn_canvas.hpp"
#include "tcpest/vision/corners.hpp"

namespace tcpest {
namespace vision {
namespace {

using testing::Canvas;
using testing::draw_in_line;
using testing::in_line_interpretation;
using testing::kFirstX;
using testing::kStripeLength;
using testing::kStripeWidth;
using testing::kTop;
using testing::make_finder;

// A straight border along y from x0 to x1, with edge points every 4 px.
Border straight_border(double y, double x0, double x1) {
  Border b;
  b.valid = true;
  b.curve = Bezier{Point{x0, y}, Point{0.5 * (x0 + x1), y}, Point{x1, y}};
  for (double x = x0; x <= x1 && !b.points.full(); x += 4.0) {
    static_cast<void>(b.points.push_back(EdgePoint{Point{x, y}, 1.0, (x - x0) / (x1 - x0)}));
  }
  return b;
}

// Verifies: REQ-VISION-006
TEST(CornerFinder, TheCornersOfDrawnStripesAreWhereTheColoursChangeOnTheEdges) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 0, kNumMarkers - 1);
  auto finder = make_finder(canvas.w, canvas.h);
  RegionSet regions;
  ASSERT_TRUE(finder->find(canvas.view(), regions).ok());
  const Interpretation in = in_line_interpretation(regions, 0, kNumMarkers - 1);
  // The tube's edges (side 0 above, side 1 below), a little past both ends.
  const double top = kTop - 0.5;
  const double bottom = kTop + kStripeWidth - 0.5;
  const std::array<Border, 2> borders{
      {straight_border(top, kFirstX - 10.0, kFirstX + kNumMarkers * kStripeLength + 10.0),
       straight_border(bottom, kFirstX - 10.0, kFirstX + kNumMarkers * kStripeLength + 10.0)}};
  auto created = CornerFinder::create(CornersConfig{}, default_color_model());
  ASSERT_TRUE(created.ok());
  std::array<Corner, kNumCorners> corners{};
  int count = -1;
  ASSERT_TRUE(created.value()->find(canvas.view(), in, borders, corners, count).ok());
  // Boundary j (1..4) between markers j-1 and j: the colour changes
  // between pixel columns 40 + 30 j - 1 and 40 + 30 j.
  int internal = 0;
  for (int j = 1; j < kNumMarkers; ++j) {
    for (int side = 0; side < 2; ++side) {
      const Corner& c = corners[static_cast<std::size_t>(2 * j + side)];
      ASSERT_TRUE(c.found) << "boundary " << j << " side " << side;
      EXPECT_NEAR(c.pixel.x, kFirstX + kStripeLength * j - 0.5, 0.5) << "boundary " << j << " side " << side;
      EXPECT_NEAR(c.pixel.y, side == 0 ? top : bottom, 0.5) << "boundary " << j << " side " << side;
      EXPECT_GE(c.confidence, CornersConfig{}.min_corner_confidence);
      EXPECT_LE(c.confidence, 1.0);
      ++internal;
    }
  }
  EXPECT_GE(count, internal);
}

// Verifies: REQ-VISION-006
TEST(CornerFinder, WithoutBordersOrMarkersThereAreNoCorners) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 0, kNumMarkers - 1);
  auto finder = make_finder(canvas.w, canvas.h);
  RegionSet regions;
  ASSERT_TRUE(finder->find(canvas.view(), regions).ok());
  auto corner_finder = CornerFinder::create(CornersConfig{}, default_color_model());
  ASSERT_TRUE(corner_finder.ok());
  std::array<Corner, kNumCorners> corners{};
  corners[3].found = true;  // a previous frame's: cleared
  int count = 7;
  const std::array<Border, 2> none{};
  EXPECT_EQ(corner_finder.value()
                ->find(canvas.view(), in_line_interpretation(regions, 0, kNumMarkers - 1), none, corners, count)
                .error(),
            VisionError::NoInstrument);
  EXPECT_EQ(count, 0);
  EXPECT_FALSE(corners[3].found);
  const std::array<Border, 2> borders{{straight_border(39.5, 30.0, 200.0), straight_border(79.5, 30.0, 200.0)}};
  EXPECT_EQ(corner_finder.value()->find(canvas.view(), Interpretation{}, borders, corners, count).error(),
            VisionError::NoInstrument);
}

// Verifies: REQ-VISION-012
TEST(CornerFinder, CreateRejectsBadConfiguration) {
  CornersConfig samples;
  samples.profile_samples = static_cast<int>(kMaxProfileSamples) + 1;
  EXPECT_EQ(CornerFinder::create(samples, default_color_model()).error(), VisionError::BadParameter);
  CornersConfig irls;
  irls.irls_scale_iterations = 0;
  EXPECT_EQ(CornerFinder::create(irls, default_color_model()).error(), VisionError::BadParameter);
  ColorModel bad = default_color_model();
  bad.blue.cov_aa = -1.0;
  EXPECT_EQ(CornerFinder::create(CornersConfig{}, bad).error(), VisionError::BadParameter);
  EXPECT_TRUE(CornerFinder::create(CornersConfig{}, default_color_model()).ok());
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
