// Stage 2, the interpretation tree (the paper's section 2.3), on drawn
// stripes: each of the rules on its own. Levels are the markers 1..5
// from the base (blue, yellow, blue, yellow, blue); a link only between
// adjacent regions of the next level's colour turning the skeleton by less
// than 60 deg; virtual nodes merging two regions of a level; empty leading
// levels; and the temporal priors (the last 5 successful frames).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "drawn_canvas.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

using testing::Canvas;
using testing::draw_in_line;
using testing::draw_stripe;
using testing::kBlue;
using testing::kStripeLength;
using testing::kStripeWidth;
using testing::kTissue;
using testing::kTop;
using testing::kYellow;
using testing::make_finder;

// Stripes kStripeLength = 30 px along the tube and kStripeWidth = 40 px
// across it (drawn_canvas.hpp). Level m's stripe, drawn in line from the
// base at x = 40, has its centroid at x = 54.5 + 30 m.

// Priors that know each stripe's size loosely and where the chain in line
// from x = 40 puts each level, within 60 px: enough to tell the base from
// the tip, which the colours alone do not (both ends are blue).
MarkerPriors in_line_priors() {
  MarkerPriors p;
  for (int m = 0; m < kNumMarkers; ++m) {
    MarkerPrior& mp = p.marker[static_cast<std::size_t>(m)];
    mp.half_major = kStripeWidth / std::sqrt(3.0);
    mp.half_major_sd = 0.6 * mp.half_major + 3.0;
    mp.half_minor = kStripeLength / std::sqrt(3.0);
    mp.half_minor_sd = 0.6 * mp.half_minor + 3.0;
    mp.parent_distance = kStripeLength;
    mp.parent_distance_sd = 0.6 * kStripeLength + 3.0;
    mp.centroid = Point{54.5 + 30.0 * m, kTop + 19.5};
    mp.centroid_sd = 60.0;
  }
  return p;
}

// Stages 1 and 2 on their own: the regions of `canvas`, interpreted by an
// Interpreter of the default configuration.
Interpretation interpret(const Canvas& canvas) {
  auto finder = make_finder(canvas.w, canvas.h);
  RegionSet regions;
  EXPECT_TRUE(finder->find(canvas.view(), regions).ok());
  auto interpreter = Interpreter::create(InterpretationConfig{});
  EXPECT_TRUE(interpreter.ok());
  Interpretation in;
  EXPECT_TRUE(interpreter.value()->interpret(regions, canvas.view(), in_line_priors(), in).ok());
  return in;
}

// A region as stage 1 would give a stripe of `cls` whose bounding box is
// [x0, x0 + length) x [y0, y0 + width): a uniform rectangle's moments.
Region stripe_region(PixelClass cls, double x0, double y0, double length, double width) {
  Region r;
  r.cls = cls;
  r.area = static_cast<std::int32_t>(length * width);
  r.centroid = Point{x0 + 0.5 * (length - 1.0), y0 + 0.5 * (width - 1.0)};
  r.cov_xx = length * length / 12.0;
  r.cov_yy = width * width / 12.0;
  r.x_min = static_cast<std::int32_t>(x0);
  r.x_max = static_cast<std::int32_t>(x0 + length) - 1;
  r.y_min = static_cast<std::int32_t>(y0);
  r.y_max = static_cast<std::int32_t>(y0 + width) - 1;
  r.update_shape();
  return r;
}

// The interpreter alone, on a region set made by hand (no image, no stage
// 1): the five stripes in line, listed out of order and with a stray blue
// region far off, are labelled 1..5 from the base, each by its own region.
// Verifies: REQ-VISION-004
TEST(Interpreter, LabelsAHandMadeRegionSetInLineFromTheBase) {
  RegionSet set;
  const int order[kNumMarkers] = {3, 0, 4, 2, 1};
  for (const int m : order) {
    const PixelClass cls = m % 2 == 0 ? PixelClass::Blue : PixelClass::Yellow;
    ASSERT_TRUE(set.regions.push_back(stripe_region(cls, 40.0 + kStripeLength * m, kTop, kStripeLength, kStripeWidth)));
  }
  ASSERT_TRUE(set.regions.push_back(stripe_region(PixelClass::Blue, 260.0, 120.0, 12.0, 8.0)));
  auto created = Interpreter::create(InterpretationConfig{});
  ASSERT_TRUE(created.ok());
  Interpretation in;
  ASSERT_TRUE(created.value()->interpret(set, ImageView{}, in_line_priors(), in).ok());
  ASSERT_EQ(in.found_count, kNumMarkers);
  EXPECT_EQ(in.first_marker, 0);
  EXPECT_EQ(in.last_marker, kNumMarkers - 1);
  for (int m = 0; m < kNumMarkers; ++m) {
    const MarkerObservation& o = in.markers[static_cast<std::size_t>(m)];
    ASSERT_TRUE(o.found) << m;
    EXPECT_EQ(order[o.region_index[0]], m) << m;
    EXPECT_LT(o.region_index[1], 0) << m;
    EXPECT_NEAR(o.region.centroid.x, 54.5 + 30.0 * m, 1e-9) << m;
  }
  // No region of a marker's colour: nothing to label.
  RegionSet empty;
  EXPECT_EQ(created.value()->interpret(empty, ImageView{}, in_line_priors(), in).error(), VisionError::NoInstrument);
  EXPECT_EQ(in.found_count, 0);
}

// Verifies: REQ-VISION-012
TEST(Interpreter, CreateRejectsBadConfiguration) {
  InterpretationConfig c;
  c.marker_classes[2] = PixelClass::Background;
  EXPECT_EQ(Interpreter::create(c).error(), VisionError::BadParameter);
  InterpretationConfig angle;
  angle.max_link_angle_rad = 0.0;
  EXPECT_EQ(Interpreter::create(angle).error(), VisionError::BadParameter);
  InterpretationConfig reward;
  reward.level_reward = std::nan("");
  EXPECT_EQ(Interpreter::create(reward).error(), VisionError::BadParameter);
  EXPECT_TRUE(Interpreter::create(InterpretationConfig{}).ok());
}

// Verifies: REQ-VISION-004
TEST(Interpretation, FiveAlternatingStripesAreLabelledFromTheBase) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 0, kNumMarkers - 1);
  const Interpretation in = interpret(canvas);
  ASSERT_EQ(in.found_count, kNumMarkers);
  EXPECT_EQ(in.first_marker, 0);
  EXPECT_EQ(in.last_marker, kNumMarkers - 1);
  for (int m = 0; m < kNumMarkers; ++m) {
    const MarkerObservation& o = in.markers[static_cast<std::size_t>(m)];
    ASSERT_TRUE(o.found) << m;
    EXPECT_NEAR(o.region.centroid.x, 54.5 + 30.0 * m, 1e-9) << m;
    EXPECT_EQ(o.region.cls, m % 2 == 0 ? PixelClass::Blue : PixelClass::Yellow) << m;
    EXPECT_LT(o.region_index[1], 0) << m;  // a single region, not a merge
  }
}

// A highlight across a stripe splits it in two regions: the level is a
// virtual node merging both, with their joint statistics.
// Verifies: REQ-VISION-004
TEST(Interpretation, AStripeSplitInTwoIsOneVirtualNode) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 0, kNumMarkers - 1);
  canvas.fill_rect(70, kTop + 18, 100, kTop + 21, kTissue);  // marker 2 (yellow) cut along the tube
  const Interpretation in = interpret(canvas);
  ASSERT_EQ(in.found_count, kNumMarkers);
  const MarkerObservation& split = in.markers[1];
  ASSERT_TRUE(split.found);
  EXPECT_GE(split.region_index[0], 0);
  EXPECT_GE(split.region_index[1], 0);
  EXPECT_EQ(split.region.area, kStripeLength * (kStripeWidth - 3));
  EXPECT_NEAR(split.region.centroid.x, 84.5, 1e-9);
  EXPECT_NEAR(split.region.centroid.y, kTop + 19.5, 0.1);
  EXPECT_TRUE(in.markers[2].found);  // the chain goes on from the merged node
}

// The skeleton may turn by less than 60 deg per link: a stripe 30 deg off
// the chain's line is linked, one at 88 deg is not, and the chain ends
// there (the remaining levels are empty).
// Verifies: REQ-VISION-004
TEST(Interpretation, ALinkTurningBy60DegreesOrMoreIsRefused) {
  {
    Canvas canvas(320, 200);
    draw_in_line(canvas, 0, 2);
    draw_stripe(canvas, 3, 130, kTop + 17);  // centroid link (30, 17): 29.5 deg
    draw_stripe(canvas, 4, 160, kTop + 34);
    const Interpretation in = interpret(canvas);
    EXPECT_EQ(in.found_count, kNumMarkers);
  }
  {
    Canvas canvas(320, 200);
    draw_in_line(canvas, 0, 2);
    // Below marker 3, turning by 88 deg (2 px short of marker 2's corner,
    // which it would otherwise touch and join).
    canvas.fill_rect(102, kTop + kStripeWidth, 130, kTop + kStripeWidth + 30, kYellow);
    canvas.fill_rect(102, kTop + kStripeWidth + 30, 130, kTop + kStripeWidth + 60, kBlue);
    const Interpretation in = interpret(canvas);
    EXPECT_EQ(in.first_marker, 0);
    EXPECT_EQ(in.last_marker, 2);
    EXPECT_EQ(in.found_count, 3);
    EXPECT_FALSE(in.markers[3].found);
  }
}

// The base marker out of the image (or hidden): its level stays empty and
// the chain starts at the second marker.
// Verifies: REQ-VISION-004
TEST(Interpretation, AHiddenBaseLeavesTheFirstLevelEmpty) {
  Canvas canvas(320, 140);
  draw_in_line(canvas, 1, kNumMarkers - 1);
  const Interpretation in = interpret(canvas);
  EXPECT_EQ(in.first_marker, 1);
  EXPECT_EQ(in.last_marker, kNumMarkers - 1);
  EXPECT_EQ(in.found_count, kNumMarkers - 1);
  EXPECT_FALSE(in.markers[0].found);
}

// Links only between adjacent regions: with 21 px of tissue between
// markers 2 and 3 (their centroids 51 px apart, beyond the 49.7 px that
// adjacency allows stripes 30 px long), the chain does not cross the gap,
// though the posterior alone would take the link.
// Verifies: REQ-VISION-004
TEST(Interpretation, AStripeBeyondTheAdjacencyReachIsNotLinked) {
  Canvas canvas(360, 140);
  for (int m = 0; m < kNumMarkers; ++m) {
    draw_stripe(canvas, m, 40 + kStripeLength * m + (m >= 2 ? 21 : 0), kTop);
  }
  const Interpretation in = interpret(canvas);
  EXPECT_EQ(in.found_count, 3);  // markers 3-5, the larger side of the gap
  EXPECT_EQ(in.first_marker, 2);
  EXPECT_FALSE(in.markers[1].found);
}

// The temporal priors: a Gaussian per marker from the last 5 frames whose
// interpretation succeeded, from 2 frames on.
Interpretation chain_with_base_size(double base_half_major) {
  Interpretation in;
  for (int m = 0; m < kNumMarkers; ++m) {
    MarkerObservation& o = in.markers[static_cast<std::size_t>(m)];
    o.found = m < 4;  // the tip's marker never seen
    o.region.half_major = m == 0 ? base_half_major : 20.0;
    o.region.half_minor = 12.0;
    o.region.centroid = Point{100.0 + 30.0 * m, 80.0};
  }
  in.first_marker = 0;
  in.last_marker = 3;
  in.found_count = 4;
  return in;
}

// Verifies: REQ-VISION-004
TEST(TemporalPriors, NeedTwoFramesAndKeepTheLastFive) {
  TemporalPriors temporal;
  MarkerPriors p;
  EXPECT_FALSE(temporal.priors(p));
  temporal.add(chain_with_base_size(10.0));
  EXPECT_FALSE(temporal.priors(p));
  temporal.add(chain_with_base_size(20.0));
  ASSERT_TRUE(temporal.priors(p));
  EXPECT_NEAR(p.marker[0].half_major, 15.0, 1e-12);
  for (const double size : {30.0, 40.0, 50.0, 60.0, 70.0}) {
    temporal.add(chain_with_base_size(size));
  }
  EXPECT_EQ(temporal.frames(), TemporalPriors::kHistory);
  ASSERT_TRUE(temporal.priors(p));
  // The last five: 30..70 px; their spread (variance 200 px^2) and the
  // floor (15 % of the mean + 2 px) add in quadrature.
  EXPECT_NEAR(p.marker[0].half_major, 50.0, 1e-12);
  EXPECT_NEAR(p.marker[0].half_major_sd, std::sqrt(200.0 + 9.5 * 9.5), 1e-9);
  temporal.reset();
  EXPECT_FALSE(temporal.priors(p));
}

// Verifies: REQ-VISION-004
TEST(TemporalPriors, IdenticalFramesGiveTheFloorsAndAnUnseenMarkerNoPrior) {
  TemporalPriors temporal;
  temporal.add(chain_with_base_size(20.0));
  temporal.add(chain_with_base_size(20.0));
  MarkerPriors p;
  ASSERT_TRUE(temporal.priors(p));
  const MarkerPrior& second = p.marker[1];
  EXPECT_TRUE(second.in_image);
  EXPECT_NEAR(second.half_major_sd, 0.15 * 20.0 + 2.0, 1e-12);
  EXPECT_NEAR(second.parent_distance, 30.0, 1e-12);
  EXPECT_NEAR(second.parent_distance_sd, 0.15 * 30.0 + 2.0, 1e-12);
  EXPECT_NEAR(second.centroid.x, 130.0, 1e-12);
  EXPECT_NEAR(second.centroid_sd, 25.0, 1e-12);  // no spread: the floor
  const MarkerPrior& tip = p.marker[4];
  EXPECT_FALSE(tip.in_image);
  EXPECT_GE(tip.half_major_sd, 1e3);  // no information
}

// Priors predicted from a configuration r (the encoders) through the
// models: every marker of a tube in view is expected in the image, at a
// known position, with a size and a distance to the marker before that
// agree with the centroids; a marker the model puts behind the camera is
// not expected in the image and carries no information.
// Verifies: REQ-VISION-004
TEST(ModelPriors, FollowTheModelAndSayNothingOfAMarkerBehindTheCamera) {
  const auto camera = solver::CameraModel::create(solver::default_pal_camera());
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{});
  ASSERT_TRUE(camera.ok() && model.ok());
  const solver::PoseVector ahead = model.value().geometry().nominal_pose(25.0, 0.3, 0.6);
  const MarkerPriors p = model_priors(camera.value(), model.value(), ahead);
  for (std::size_t m = 0U; m < static_cast<std::size_t>(kNumMarkers); ++m) {
    const MarkerPrior& mp = p.marker[m];
    EXPECT_TRUE(mp.in_image) << "marker " << m;
    EXPECT_GT(mp.centroid_sd, 0.0) << "marker " << m;  // the position is known
    EXPECT_GT(mp.half_major, mp.half_minor * 0.2) << "marker " << m;
    EXPECT_LT(mp.half_major_sd, 1e3) << "marker " << m;
    EXPECT_GT(mp.centroid.x, 0.0) << "marker " << m;
    EXPECT_LT(mp.centroid.x, camera.value().width()) << "marker " << m;
  }
  // Consecutive markers' centroids lie about their parent distance apart.
  for (std::size_t m = 1U; m < static_cast<std::size_t>(kNumMarkers); ++m) {
    const double d = std::hypot(p.marker[m].centroid.x - p.marker[m - 1U].centroid.x,
                                p.marker[m].centroid.y - p.marker[m - 1U].centroid.y);
    EXPECT_NEAR(d, p.marker[m].parent_distance, 0.25 * p.marker[m].parent_distance) << "marker " << m;
  }
  // Bent back on itself just out of the channel: the last stripes pass
  // behind the camera.
  const solver::PoseVector behind = model.value().geometry().nominal_pose(0.0, 0.0, 3.1);
  const MarkerPriors q = model_priors(camera.value(), model.value(), behind);
  const MarkerPrior& tip = q.marker[static_cast<std::size_t>(kNumMarkers) - 1U];
  EXPECT_FALSE(tip.in_image);
  EXPECT_GE(tip.half_major_sd, 1e3);
  EXPECT_GE(tip.parent_distance_sd, 1e3);
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
