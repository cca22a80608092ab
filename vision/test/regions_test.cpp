#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "tcpest/test/alloc_counter.hpp"
#include "drawn_canvas.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace {

using testing::Canvas;
using testing::kBlue;
using testing::kTissue;
using testing::kYellow;
using testing::make;
using testing::make_finder;

// Verifies: REQ-VISION-002
TEST(Regions, RectanglesGiveAreaCentroidAxesAndOrientation) {
  Canvas canvas(200, 120);
  canvas.fill_rect(10, 20, 70, 40, kBlue);     // 60 x 20
  canvas.fill_rect(100, 10, 120, 90, kYellow);  // 20 x 80
  auto finder = make_finder(200, 120);
  RegionSet set;
  ASSERT_TRUE(finder->find(canvas.view(), set).ok());
  ASSERT_EQ(set.regions.size(), 2U);
  EXPECT_FALSE(set.too_many_regions);
  for (const Region& r : set.regions) {
    if (r.cls == PixelClass::Blue) {
      EXPECT_EQ(r.area, 1200);
      EXPECT_NEAR(r.centroid.x, 39.5, 1e-9);
      EXPECT_NEAR(r.centroid.y, 29.5, 1e-9);
      // Uniform rectangle: half axes l / sqrt(3) with the pixel footprint.
      EXPECT_NEAR(r.half_major, 60.0 / std::sqrt(3.0), 0.05);
      EXPECT_NEAR(r.half_minor, 20.0 / std::sqrt(3.0), 0.05);
      EXPECT_NEAR(std::fabs(r.orientation_rad), 0.0, 1e-6);
      EXPECT_EQ(r.x_min, 10);
      EXPECT_EQ(r.x_max, 69);
      EXPECT_EQ(r.y_min, 20);
      EXPECT_EQ(r.y_max, 39);
    } else {
      EXPECT_EQ(r.cls, PixelClass::Yellow);
      EXPECT_EQ(r.area, 1600);
      EXPECT_NEAR(std::fabs(r.orientation_rad), solver::kPi / 2.0, 1e-6);
    }
  }
}

// Verifies: REQ-VISION-002
TEST(Regions, DiagonalNeighboursAreConnectedAndColoursSeparate) {
  Canvas canvas(50, 50);
  // A staircase of blue pixels touching only by corners: one region (8-connected).
  for (int i = 0; i < 20; ++i) {
    canvas.fill_rect(5 + i, 5 + i, 6 + i, 6 + i, kBlue);
  }
  // A yellow block touching a blue block: two regions.
  canvas.fill_rect(30, 30, 40, 40, kBlue);
  canvas.fill_rect(40, 30, 45, 40, kYellow);
  auto finder = make_finder(50, 50);
  RegionSet set;
  ASSERT_TRUE(finder->find(canvas.view(), set).ok());
  ASSERT_EQ(set.regions.size(), 3U);
}

// Verifies: REQ-VISION-003
TEST(Regions, TooManyRegionsIsReportedNotACrash) {
  Canvas canvas(400, 400);
  // 40 x 40 blobs of 4 x 4 pixels, well above the minimum area: 1600 regions.
  for (int by = 0; by < 40; ++by) {
    for (int bx = 0; bx < 40; ++bx) {
      canvas.fill_rect(bx * 10, by * 10, bx * 10 + 4, by * 10 + 4, (bx + by) % 2 == 0 ? kBlue : kYellow);
    }
  }
  RegionsConfig c;
  c.max_width = 400;
  c.max_height = 400;
  c.min_region_area = 4;
  auto created = RegionFinder::create(c, default_color_model());
  ASSERT_TRUE(created.ok());
  RegionSet set;
  ASSERT_TRUE(created.value()->find(canvas.view(), set).ok());
  EXPECT_TRUE(set.too_many_regions);
  EXPECT_EQ(set.regions.size(), kMaxRegions);
  // The largest are kept: every blob is 16 px.
  for (const Region& r : set.regions) {
    EXPECT_EQ(r.area, 16);
  }
}

// A frame fragmented beyond the run buffer (blue and yellow alternating
// pixel by pixel: one run per pixel, the buffer holds half of them) is an
// error value, not a crash, and the next frame is read as usual.
// Verifies: REQ-VISION-003
TEST(Regions, AFrameTooFragmentedForTheRunBufferIsAnError) {
  auto fx = make(64, 64);
  Canvas shredded(64, 64);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      shredded.fill_rect(x, y, x + 1, y + 1, (x + y) % 2 == 0 ? kBlue : kYellow);
    }
  }
  const auto refused = fx->find_regions(shredded.view());
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error(), VisionError::TooManyRuns);
  EXPECT_TRUE(fx->result().regions.too_many_regions);
  EXPECT_FALSE(fx->interpret(MarkerPriors{}).ok());  // the stages after it fail cleanly
  Canvas calm(64, 64);
  calm.fill_rect(10, 10, 30, 30, kBlue);
  ASSERT_TRUE(fx->find_regions(calm.view()).ok());
  EXPECT_FALSE(fx->result().regions.too_many_regions);
  EXPECT_EQ(fx->result().regions.regions.size(), 1U);
}

// Verifies: REQ-VISION-003
TEST(Regions, BadAndOversizedImagesAreErrors) {
  auto fx = make(64, 64);
  EXPECT_EQ(fx->find_regions(ImageView{}).error(), VisionError::BadImage);
  Canvas big(100, 20);
  EXPECT_EQ(fx->find_regions(big.view()).error(), VisionError::ImageTooLarge);
  // Stages after a failed stage 1 fail cleanly too.
  EXPECT_FALSE(fx->interpret(MarkerPriors{}).ok());
  EXPECT_FALSE(fx->fit_borders(big.view()).ok());
  EXPECT_FALSE(fx->find_corners(big.view()).ok());
}


// Pseudo-random colours (a fixed LCG): every branch of the row classifier,
// ambiguous cells included, on an odd-sized image (the last pixel of a row
// and the last row are special cases of the wide loads and of the grid).
Canvas random_canvas(int w, int h) {
  Canvas canvas(w, h);
  std::uint32_t state = 12345U;
  for (std::uint8_t& v : canvas.px) {
    state = state * 1664525U + 1013904223U;
    v = static_cast<std::uint8_t>(state >> 24U);
  }
  // Some marker colours too, so that there are runs to cut.
  canvas.fill_rect(3, 2, 20, 9, kBlue);
  canvas.fill_rect(21, 10, w, 14, kYellow);
  return canvas;
}

// Verifies: REQ-VISION-001
TEST(Regions, ClassImageIsTheLookupTableClassOfEveryPixel) {
  const Canvas canvas = random_canvas(37, 23);
  auto fx = make_finder(37, 23, 1);
  RegionSet set;
  ASSERT_TRUE(fx->find(canvas.view(), set).ok());
  EXPECT_EQ(fx->classify_step(), 1);
  int ambiguous = 0;
  for (int y = 0; y < canvas.h; ++y) {
    for (int x = 0; x < canvas.w; ++x) {
      const std::uint8_t* p = &canvas.px[static_cast<std::size_t>((y * canvas.w + x) * 3)];
      ambiguous += fx->lut().table()[ClassifierLut::index(p[0], p[1], p[2])] == ClassifierLut::kAmbiguous ? 1 : 0;
      ASSERT_EQ(fx->class_image()[y * canvas.w + x], static_cast<std::uint8_t>(fx->lut().classify(p[0], p[1], p[2])))
          << "pixel " << x << ", " << y;
    }
  }
  EXPECT_GT(ambiguous, 0);  // the second level was exercised
}

// Verifies: REQ-VISION-001
TEST(Regions, StepTwoClassImageRepeatsTheGridClassOverEachBlock) {
  const Canvas canvas = random_canvas(37, 23);
  auto fx = make_finder(37, 23, 2);
  RegionSet set;
  ASSERT_TRUE(fx->find(canvas.view(), set).ok());
  EXPECT_EQ(fx->classify_step(), 2);
  for (int y = 0; y < canvas.h; ++y) {
    for (int x = 0; x < canvas.w; ++x) {
      const int gx = x - x % 2;
      const int gy = y - y % 2;
      const std::uint8_t* p = &canvas.px[static_cast<std::size_t>((gy * canvas.w + gx) * 3)];
      ASSERT_EQ(fx->class_image()[y * canvas.w + x], static_cast<std::uint8_t>(fx->lut().classify(p[0], p[1], p[2])))
          << "pixel " << x << ", " << y;
    }
  }
}

// Verifies: REQ-VISION-002
TEST(Regions, StepTwoRegionsKeepAreaCentroidAxesInPixels) {
  Canvas canvas(200, 120);
  canvas.fill_rect(10, 20, 70, 40, kBlue);      // 60 x 20
  canvas.fill_rect(101, 11, 121, 91, kYellow);  // 20 x 80, odd offsets
  auto fx = make_finder(200, 120, 2);
  RegionSet set;
  ASSERT_TRUE(fx->find(canvas.view(), set).ok());
  ASSERT_EQ(set.regions.size(), 2U);
  for (const Region& r : set.regions) {
    if (r.cls == PixelClass::Blue) {
      // Even-aligned: 30 x 10 grid points of 2 x 2 pixels.
      EXPECT_EQ(r.area, 1200);
      EXPECT_NEAR(r.centroid.x, 39.5, 0.5);
      EXPECT_NEAR(r.centroid.y, 29.5, 0.5);
      EXPECT_NEAR(r.half_major, 60.0 / std::sqrt(3.0), 0.05);
      EXPECT_NEAR(r.half_minor, 20.0 / std::sqrt(3.0), 0.05);
      EXPECT_EQ(r.x_min, 10);
      EXPECT_EQ(r.x_max, 69);
      EXPECT_EQ(r.y_min, 20);
      EXPECT_EQ(r.y_max, 39);
    } else {
      EXPECT_EQ(r.cls, PixelClass::Yellow);
      EXPECT_NEAR(r.area, 1600, 200);
      EXPECT_NEAR(r.centroid.x, 110.5, 0.5);
      EXPECT_NEAR(r.centroid.y, 50.5, 0.5);
      EXPECT_NEAR(r.half_major, 80.0 / std::sqrt(3.0), 1.2);
      EXPECT_NEAR(r.half_minor, 20.0 / std::sqrt(3.0), 1.2);
      EXPECT_NEAR(std::fabs(r.orientation_rad), solver::kPi / 2.0, 1e-6);
    }
  }
}

// Verifies: REQ-VISION-002
TEST(Regions, AutoStepIsTwoFromFourPalFramesOfPixelsOn) {
  EXPECT_EQ(classify_step_for(0, 720, 576), 1);
  EXPECT_EQ(classify_step_for(0, 1280, 720), 1);
  EXPECT_EQ(classify_step_for(0, 1440, 1152), 2);  // exactly 4 x PAL
  EXPECT_EQ(classify_step_for(0, 1920, 1080), 2);
  EXPECT_EQ(classify_step_for(1, 1920, 1080), 1);
  EXPECT_EQ(classify_step_for(2, 720, 576), 2);
  auto fx = make_finder(1920, 1080);
  Canvas hd(1920, 1080);
  RegionSet set;
  ASSERT_TRUE(fx->find(hd.view(), set).ok());
  EXPECT_EQ(fx->classify_step(), 2);
}

// Memory running out at each of create()'s allocations in turn (the
// extractor, the colour table's, every buffer): OutOfMemory, not a
// configuration error, with everything taken before freed.
// Verifies: REQ-ERR-007
TEST(Regions, CreateReportsOutOfMemoryAtAnyOfItsAllocations) {
  if (!test::malloc_hook_active()) {
    GTEST_SKIP() << "malloc belongs to the sanitizer's runtime in this build";
  }
  ExtractorConfig c;
  c.regions.max_width = 320;
  c.regions.max_height = 240;
  VisionError error = VisionError::BadImage;
  const auto create = [&]() {
    const auto result = FeatureExtractor::create(c, default_color_model());
    if (!result.ok()) {
      error = result.error();
    }
    return result.ok();  // the extractor is released here: only the count matters
  };
  const std::size_t allocations = test::run_out_of_memory_at_each_allocation(create, [&](const test::OutOfMemoryOutcome& o) {
    ASSERT_FALSE(o.succeeded) << "allocation " << o.nth;
    EXPECT_EQ(error, VisionError::OutOfMemory) << "allocation " << o.nth;
    EXPECT_EQ(o.leaked, 0U) << "out of memory at allocation " << o.nth;
  });
  EXPECT_GE(allocations, 10U);
  EXPECT_TRUE(FeatureExtractor::create(c, default_color_model()).ok());
}

// The region finder refuses what it cannot size or classify, and the
// extractor composes it: its class image and grid step are the finder's.
// Verifies: REQ-VISION-012
TEST(Regions, TheFinderRejectsBadConfigurationAndTheExtractorComposesIt) {
  RegionsConfig c;
  for (const int bad_width : {0, -3, 8193}) {
    c.max_width = bad_width;
    EXPECT_EQ(RegionFinder::create(c, default_color_model()).error(), VisionError::BadParameter) << bad_width;
  }
  c = RegionsConfig{};
  c.min_region_area = 0;
  EXPECT_EQ(RegionFinder::create(c, default_color_model()).error(), VisionError::BadParameter);
  ColorModel bad = default_color_model();
  bad.blue.cov_aa = -1.0;
  EXPECT_EQ(RegionFinder::create(RegionsConfig{}, bad).error(), VisionError::BadParameter);
  Canvas canvas(64, 48);
  canvas.fill_rect(8, 8, 40, 20, kBlue);
  auto fx = make(64, 48);
  ASSERT_TRUE(fx->find_regions(canvas.view()).ok());
  EXPECT_EQ(fx->class_image(), fx->region_finder().class_image());
  EXPECT_EQ(fx->classify_step(), fx->region_finder().classify_step());
  EXPECT_EQ(fx->region_finder().image().data, canvas.view().data);
  ASSERT_EQ(fx->result().regions.regions.size(), 1U);
  EXPECT_EQ(fx->result().regions.regions[0].area, 32 * 12);
}

// Verifies: REQ-VISION-012
TEST(Regions, CreateRejectsBadConfiguration) {
  ExtractorConfig c;
  c.regions.max_width = 0;
  EXPECT_FALSE(FeatureExtractor::create(c, default_color_model()).ok());
  ColorModel bad = default_color_model();
  bad.blue.cov_aa = -1.0;
  EXPECT_FALSE(FeatureExtractor::create(ExtractorConfig{}, bad).ok());
  ExtractorConfig step;
  step.regions.classify_step = 3;
  EXPECT_FALSE(FeatureExtractor::create(step, default_color_model()).ok());
  step.regions.classify_step = -1;
  EXPECT_FALSE(FeatureExtractor::create(step, default_color_model()).ok());
  // The IRLS scale: estimated at least once (else every weight divides by
  // zero), and not in more iterations than the fit runs.
  ExtractorConfig irls;
  for (const int bad_scale_iterations : {0, -1, irls.borders.irls_iterations + 1}) {
    irls.borders.irls_scale_iterations = bad_scale_iterations;
    EXPECT_FALSE(FeatureExtractor::create(irls, default_color_model()).ok()) << bad_scale_iterations;
  }
  irls.borders.irls_scale_iterations = irls.borders.irls_iterations;
  EXPECT_TRUE(FeatureExtractor::create(irls, default_color_model()).ok());
  // The tip arc's share of a smear: 0 (off) to one half, never NaN.
  ExtractorConfig tip;
  for (const double bad_share : {-0.01, 0.51, std::nan("")}) {
    tip.refiner.refine_smear_tip_bias = bad_share;
    EXPECT_FALSE(FeatureExtractor::create(tip, default_color_model()).ok()) << bad_share;
  }
  tip.refiner.refine_smear_tip_bias = 0.0;
  EXPECT_TRUE(FeatureExtractor::create(tip, default_color_model()).ok());
  // The streak read where the arcs stay sharp: a boundary count the model
  // has, a length that is not negative or NaN.
  ExtractorConfig streak;
  streak.refiner.refine_streak_unsmeared_min_boundaries = kNumBoundaries + 1;
  EXPECT_FALSE(FeatureExtractor::create(streak, default_color_model()).ok());
  streak.refiner.refine_streak_unsmeared_min_boundaries = -1;
  EXPECT_FALSE(FeatureExtractor::create(streak, default_color_model()).ok());
  streak.refiner.refine_streak_unsmeared_min_boundaries = 4;
  streak.refiner.refine_streak_unsmeared_min_px = std::nan("");
  EXPECT_FALSE(FeatureExtractor::create(streak, default_color_model()).ok());
  // The arcs' retry under a streak: its length gate not negative or NaN.
  ExtractorConfig retry;
  for (const double bad_min : {-1.0, std::nan("")}) {
    retry.refiner.refine_streak_arc_retry_min_px = bad_min;
    EXPECT_FALSE(FeatureExtractor::create(retry, default_color_model()).ok()) << bad_min;
  }
  retry.refiner.refine_streak_arc_retry_min_px = 0.0;
  EXPECT_TRUE(FeatureExtractor::create(retry, default_color_model()).ok());
  // The base-rim scan: a positive step, a range it covers within
  // kMaxRimScanSteps steps each way, never NaN.
  ExtractorConfig rim;
  for (const double bad_step : {0.0, -0.5, std::nan("")}) {
    rim.refiner.refine_rim_scan_step_mm = bad_step;
    EXPECT_FALSE(FeatureExtractor::create(rim, default_color_model()).ok()) << bad_step;
  }
  rim.refiner.refine_rim_scan_step_mm = 0.5;
  for (const double bad_range : {-1.0, 0.5 * FeatureExtractor::kMaxRimScanSteps + 0.01, std::nan("")}) {
    rim.refiner.refine_rim_scan_range_mm = bad_range;
    EXPECT_FALSE(FeatureExtractor::create(rim, default_color_model()).ok()) << bad_range;
  }
  rim.refiner.refine_rim_scan_range_mm = 0.5 * FeatureExtractor::kMaxRimScanSteps;
  EXPECT_TRUE(FeatureExtractor::create(rim, default_color_model()).ok());
  // The blurred edge's smear search: 0 (the read smear alone) to
  // kMaxStreakEdgeSmearSearchPx, never NaN.
  ExtractorConfig edge;
  for (const double bad_search : {-1.0, kMaxStreakEdgeSmearSearchPx + 0.5, std::nan("")}) {
    edge.refiner.refine_streak_edge_smear_search_px = bad_search;
    EXPECT_FALSE(FeatureExtractor::create(edge, default_color_model()).ok()) << bad_search;
  }
  edge.refiner.refine_streak_edge_smear_search_px = 0.0;
  EXPECT_TRUE(FeatureExtractor::create(edge, default_color_model()).ok());
}

}  // namespace
}  // namespace vision
}  // namespace tcpest
