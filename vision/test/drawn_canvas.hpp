// Drawn test images for the vision tests: flat marker colours on tissue, an
// extractor sized for them, and stage 1 alone (RegionFinder) for them.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace testing {

constexpr std::uint8_t kBlue[3] = {80, 156, 233};
constexpr std::uint8_t kYellow[3] = {218, 205, 80};
constexpr std::uint8_t kTissue[3] = {185, 95, 85};

struct Canvas {
  int w, h;
  std::vector<std::uint8_t> px;
  Canvas(int width, int height) : w(width), h(height), px(static_cast<std::size_t>(width * height * 3)) {
    fill_rect(0, 0, w, h, kTissue);
  }
  void fill_rect(int x0, int y0, int x1, int y1, const std::uint8_t* c) {
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        for (int k = 0; k < 3; ++k) {
          px[static_cast<std::size_t>((y * w + x) * 3 + k)] = c[k];
        }
      }
    }
  }
  ImageView view() const { return ImageView{px.data(), w, h, static_cast<std::size_t>(w) * 3U}; }
};

// An extractor with the default configuration for images up to w x h.
inline std::unique_ptr<FeatureExtractor> make(int w, int h) {
  ExtractorConfig c;
  c.regions.max_width = w;
  c.regions.max_height = h;
  auto e = FeatureExtractor::create(c, default_color_model());
  EXPECT_TRUE(e.ok());
  return std::move(e.value());
}

// Stage 1 alone, with the default configuration (`step`: classify_step) for
// images up to w x h.
inline std::unique_ptr<RegionFinder> make_finder(int w, int h, int step = 0) {
  RegionsConfig c;
  c.max_width = w;
  c.max_height = h;
  c.classify_step = step;
  auto f = RegionFinder::create(c, default_color_model());
  EXPECT_TRUE(f.ok());
  return std::move(f.value());
}

// Marker m (0-based, from the base) drawn as a stripe kStripeLength px along
// x and kStripeWidth px across, from x = kFirstX + kStripeLength m, y = kTop:
// the chain in line of the stage tests.
constexpr int kStripeLength = 30;
constexpr int kStripeWidth = 40;
constexpr int kTop = 40;
constexpr int kFirstX = 40;

inline const std::uint8_t* colour_of(int level) { return level % 2 == 0 ? kBlue : kYellow; }

inline void draw_stripe(Canvas& c, int level, int x0, int y0) {
  c.fill_rect(x0, y0, x0 + kStripeLength, y0 + kStripeWidth, colour_of(level));
}

// Levels first..last drawn in line, each in its place from x = kFirstX.
inline void draw_in_line(Canvas& c, int first, int last) {
  for (int m = first; m <= last; ++m) {
    draw_stripe(c, m, kFirstX + kStripeLength * m, kTop);
  }
}

// The interpretation of a chain drawn in line: marker m is the region whose
// centroid is nearest to its stripe's middle (stage 2's answer, without
// stage 2).
inline Interpretation in_line_interpretation(const RegionSet& set, int first, int last) {
  Interpretation in;
  for (int m = first; m <= last; ++m) {
    const double x = kFirstX + kStripeLength * m + 0.5 * (kStripeLength - 1);
    double best = 1e30;
    for (std::size_t i = 0U; i < set.regions.size(); ++i) {
      const double d = std::abs(set.regions[i].centroid.x - x);
      if (d < best) {
        best = d;
        MarkerObservation& o = in.markers[static_cast<std::size_t>(m)];
        o = MarkerObservation{true, set.regions[i], {{static_cast<std::int16_t>(i), -1}}, 0.0};
      }
    }
  }
  in.first_marker = first;
  in.last_marker = last;
  in.found_count = last - first + 1;
  return in;
}

}  // namespace testing
}  // namespace vision
}  // namespace tcpest
