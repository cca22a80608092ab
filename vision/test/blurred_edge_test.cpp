// The silhouette under a motion-blur streak by the blurred edge's model
// (src/blurred_edge.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "../src/blurred_edge.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

// The fits' tables, as the extractor owns them (allocated once).
BlurredEdgeScratch& scratch() {
  static const std::unique_ptr<BlurredEdgeScratch> tables = std::make_unique<BlurredEdgeScratch>();
  return *tables;
}

struct Levels {
  double tube[3] = {0.30, 0.25, 0.05};     // the tube's linear radiance at its crest
  double offset[3] = {0.02, 0.02, 0.02};   // a veil over the tube (haze)
  double tissue[3] = {0.35, 0.12, 0.08};   // beyond the limb
};

// The sharp profile at depth d px inside an edge of a part of half width h.
double sharp(double d_px, double h_px, const Levels& l, std::size_t ch) {
  if (d_px <= 0.0) {
    return l.tissue[ch];
  }
  const double u = std::min(d_px / h_px, 1.0);
  return l.offset[ch] + l.tube[ch] * std::sqrt(2.0 * u - u * u);
}

// The profile seen with the edge at edge_px, averaged over a smear of
// smear_px across (fine numerical integration, independent of the
// closed form under test), with a ripple of amplitude `noise`.
BlurredEdgeProfile render(double edge_px, double smear_px, double h_px, int half, double noise = 0.0,
                          const Levels& l = Levels{}) {
  BlurredEdgeProfile p;
  p.half = half;
  constexpr int kSub = 2000;
  for (int i = 0; i <= 2 * half; ++i) {
    const double t = kBlurredEdgeSampleStepPx * (i - half);
    for (std::size_t ch = 0U; ch < 3U; ++ch) {
      double sum = 0.0;
      for (int j = 0; j < kSub; ++j) {
        const double tau = smear_px * ((j + 0.5) / kSub - 0.5);
        sum += sharp(edge_px - t - tau, h_px, l, ch);
      }
      p.rgb[static_cast<std::size_t>(i)][ch] = sum / kSub + noise * std::sin(2.3 * i + 1.7 * static_cast<double>(ch));
    }
  }
  return p;
}

TEST(BlurredEdge, FindsTheEdgeAtMidExposureForEverySmear) {
  for (const double smear : {5.0, 8.0, 11.5, 14.0}) {
    for (const double edge : {-2.3, 0.0, 1.1, 3.4}) {
      const int half = static_cast<int>(std::ceil((4.0 + 0.5 * smear + 4.0) / 0.5));
      BlurredEdgeFit found;
      ASSERT_TRUE(fit_blurred_edge(render(edge, smear, 22.0, half), smear, 22.0, 4.0, scratch(), found))
          << "smear " << smear << " edge " << edge;
      EXPECT_NEAR(found.edge_px, edge, 0.05) << "smear " << smear;
      EXPECT_DOUBLE_EQ(found.smear_px, smear);
    }
  }
}

TEST(BlurredEdge, ANarrowPartAndNoiseStillGiveTheEdge) {
  const double smear = 9.0;
  const int half = 25;
  BlurredEdgeFit found;
  ASSERT_TRUE(fit_blurred_edge(render(0.7, smear, 6.0, half), smear, 6.0, 4.0, scratch(), found));  // the crest within reach
  EXPECT_NEAR(found.edge_px, 0.7, 0.05);
  ASSERT_TRUE(fit_blurred_edge(render(-1.2, smear, 20.0, half, 0.01), smear, 20.0, 4.0, scratch(), found));
  EXPECT_NEAR(found.edge_px, -1.2, 0.3);
}

TEST(BlurredEdge, AnEdgeBeyondTheWindowIsNotRead) {
  const double smear = 8.0;
  BlurredEdgeFit found;
  EXPECT_FALSE(fit_blurred_edge(render(9.0, smear, 20.0, 30), smear, 20.0, 4.0, scratch(), found));
  EXPECT_FALSE(fit_blurred_edge_and_smear(render(9.0, smear, 20.0, 30), smear, 3.0, 20.0, 4.0, scratch(), found));
}

TEST(BlurredEdge, BadInputIsRefused) {
  const BlurredEdgeProfile p = render(0.0, 8.0, 20.0, 20);
  BlurredEdgeFit found;
  EXPECT_FALSE(fit_blurred_edge(p, 8.0, 0.5, 4.0, scratch(), found));  // no width to shade
  EXPECT_FALSE(fit_blurred_edge(p, std::numeric_limits<double>::quiet_NaN(), 20.0, 4.0, scratch(), found));
  EXPECT_FALSE(fit_blurred_edge(p, 8.0, std::numeric_limits<double>::infinity(), 4.0, scratch(), found));
  EXPECT_FALSE(fit_blurred_edge(p, 8.0, 20.0, 0.0, scratch(), found));
  BlurredEdgeProfile too_long = p;
  too_long.half = kMaxBlurredEdgeSamples;  // beyond the buffer
  EXPECT_FALSE(fit_blurred_edge(too_long, 8.0, 20.0, 4.0, scratch(), found));
  BlurredEdgeProfile broken = p;
  broken.rgb[3][1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(fit_blurred_edge(broken, 8.0, 20.0, 4.0, scratch(), found));
  EXPECT_FALSE(fit_blurred_edge_and_smear(p, 8.0, -1.0, 20.0, 4.0, scratch(), found));
  EXPECT_FALSE(fit_blurred_edge_and_smear(p, std::numeric_limits<double>::infinity(), 3.0, 20.0, 4.0, scratch(), found));
}

TEST(BlurredEdge, ASmearReadTwoPixelsShortIsFoundBySearching) {
  // The arcs' reading of the streak is a pixel or more off on many frames;
  // the edge under a wrong smear moves with it, the searched one does not.
  const double true_smear = 11.0;
  const double read_smear = 9.0;
  const BlurredEdgeProfile p = render(0.5, true_smear, 18.0, 26);
  BlurredEdgeFit fixed;
  ASSERT_TRUE(fit_blurred_edge(p, read_smear, 18.0, 4.0, scratch(), fixed));
  BlurredEdgeFit searched;
  ASSERT_TRUE(fit_blurred_edge_and_smear(p, read_smear, 3.0, 18.0, 4.0, scratch(), searched));
  EXPECT_DOUBLE_EQ(searched.smear_px, true_smear);
  EXPECT_NEAR(searched.edge_px, 0.5, 0.05);
  EXPECT_LT(searched.residual, fixed.residual);
  EXPECT_GT(std::fabs(fixed.edge_px - 0.5), 0.2);
  // A search of 0 is the read smear alone.
  BlurredEdgeFit none;
  ASSERT_TRUE(fit_blurred_edge_and_smear(p, read_smear, 0.0, 18.0, 4.0, scratch(), none));
  EXPECT_DOUBLE_EQ(none.edge_px, fixed.edge_px);
}

TEST(BlurredEdge, TheLevelsOnEitherSideDoNotMoveTheEdge) {
  // Tissue darker than the tube's crest (the veil and the levels are
  // solved per channel): the edge stays where it is.
  Levels dark_tissue;
  dark_tissue.tissue[0] = 0.05;
  dark_tissue.tissue[1] = 0.04;
  dark_tissue.tissue[2] = 0.03;
  BlurredEdgeFit found;
  ASSERT_TRUE(fit_blurred_edge(render(0.4, 12.0, 18.0, 26, 0.0, dark_tissue), 12.0, 18.0, 4.0, scratch(), found));
  EXPECT_NEAR(found.edge_px, 0.4, 0.05);
}

}  // namespace
}  // namespace detail
}  // namespace vision
}  // namespace tcpest
