// Drawing the extraction over the frame, like the paper's figures 8 and 9:
// border points, the fitted Bezier borders, corners as crosses (coloured by
// side), the model re-projected at the estimate and the TCP as a dot. Draws in
// place into a caller-owned RGB buffer; no allocation.
#pragma once

#include <array>

#include "tcpest/common/image.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

// The model at the estimate: its corners (present / pixel) and TCP pixel.
struct ReprojectedModel {
  bool valid = false;
  std::array<bool, kNumCorners> present{};
  std::array<Point, kNumCorners> corners{};
  bool tcp_valid = false;
  Point tcp{};
};

void draw_extraction(const MutableImageView& image, const Extraction& extraction,
                     const ReprojectedModel& model) noexcept;

// Primitives (clipped to the image).
void draw_pixel(const MutableImageView& image, int x, int y, std::uint8_t r, std::uint8_t g, std::uint8_t b) noexcept;
void draw_line(const MutableImageView& image, Point a, Point b, std::uint8_t r, std::uint8_t g,
               std::uint8_t bl) noexcept;
void draw_cross(const MutableImageView& image, Point p, int half_size, std::uint8_t r, std::uint8_t g,
                std::uint8_t b) noexcept;
void draw_disc(const MutableImageView& image, Point p, int radius, std::uint8_t r, std::uint8_t g,
               std::uint8_t b) noexcept;

}  // namespace vision
}  // namespace tcpest
