// Drawn test images for the vision tests: flat marker colours on tissue, and
// an extractor sized for them.
#pragma once

#include <gtest/gtest.h>

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
  c.max_width = w;
  c.max_height = h;
  auto e = FeatureExtractor::create(c, default_color_model());
  EXPECT_TRUE(e.ok());
  return std::move(e.value());
}

}  // namespace testing
}  // namespace vision
}  // namespace tcpest
