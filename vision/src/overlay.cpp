#include "tcpest/vision/overlay.hpp"

#include <cmath>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {

void draw_pixel(const MutableImageView& image, int x, int y, std::uint8_t r, std::uint8_t g,
                std::uint8_t b) noexcept {
  if (x < 0 || y < 0 || x >= image.width || y >= image.height) {
    return;
  }
  std::uint8_t* p = image.row(y) + static_cast<std::ptrdiff_t>(3) * x;
  p[0] = r;
  p[1] = g;
  p[2] = b;
}

void draw_line(const MutableImageView& image, Point a, Point b, std::uint8_t r, std::uint8_t g,
               std::uint8_t bl) noexcept {
  const double len = dmath::hypot(b.x - a.x, b.y - a.y);
  if (!std::isfinite(len)) {
    return;
  }
  // Bounded: at most a few image diagonals of steps.
  const double limit = 4.0 * static_cast<double>(image.width + image.height);
  const int steps = static_cast<int>(std::ceil(len < limit ? len : limit)) + 1;
  for (int i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) / static_cast<double>(steps);
    draw_pixel(image, static_cast<int>(std::lround(a.x + t * (b.x - a.x))),
               static_cast<int>(std::lround(a.y + t * (b.y - a.y))), r, g, bl);
  }
}

void draw_cross(const MutableImageView& image, Point p, int half_size, std::uint8_t r, std::uint8_t g,
                std::uint8_t b) noexcept {
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
    return;
  }
  const double h = static_cast<double>(half_size);
  draw_line(image, Point{p.x - h, p.y - h}, Point{p.x + h, p.y + h}, r, g, b);
  draw_line(image, Point{p.x - h, p.y + h}, Point{p.x + h, p.y - h}, r, g, b);
}

void draw_disc(const MutableImageView& image, Point p, int radius, std::uint8_t r, std::uint8_t g,
               std::uint8_t b) noexcept {
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || std::fabs(p.x) > 1e6 || std::fabs(p.y) > 1e6) {
    return;
  }
  const int cx = static_cast<int>(std::lround(p.x));
  const int cy = static_cast<int>(std::lround(p.y));
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      if (dx * dx + dy * dy <= radius * radius) {
        draw_pixel(image, cx + dx, cy + dy, r, g, b);
      }
    }
  }
}

void draw_extraction(const MutableImageView& image, const Extraction& extraction,
                     const ReprojectedModel& model) noexcept {
  if (!image.valid()) {
    return;
  }
  // Model re-projected at the estimate: its corners joined per side (green).
  if (model.valid) {
    for (std::size_t side = 0U; side < 2U; ++side) {
      bool have_prev = false;
      Point prev{};
      for (std::size_t j = 0U; j < static_cast<std::size_t>(kNumBoundaries); ++j) {
        const std::size_t k = 2U * j + side;
        if (!model.present[k]) {
          have_prev = false;
          continue;
        }
        if (have_prev) {
          draw_line(image, prev, model.corners[k], 40, 220, 40);
        }
        draw_disc(image, model.corners[k], 1, 40, 220, 40);
        prev = model.corners[k];
        have_prev = true;
      }
    }
  }
  // Bezier borders (white) and their edge points (inliers cyan, outliers red).
  for (const Border& border : extraction.borders) {
    if (!border.valid) {
      continue;
    }
    constexpr int kSegments = 48;
    Point prev = border.curve.at(0.0);
    for (int i = 1; i <= kSegments; ++i) {
      const Point p = border.curve.at(static_cast<double>(i) / kSegments);
      draw_line(image, prev, p, 255, 255, 255);
      prev = p;
    }
    for (const EdgePoint& e : border.points) {
      const bool inlier = e.weight > 0.0;
      draw_pixel(image, static_cast<int>(std::lround(e.pixel.x)), static_cast<int>(std::lround(e.pixel.y)),
                 inlier ? 0 : 255, inlier ? 255 : 0, inlier ? 255 : 0);
    }
  }
  // Corners: crosses, magenta on side 0 (left), orange on side 1 (right).
  for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
    const Corner& c = extraction.corners[k];
    if (!c.found) {
      continue;
    }
    if ((k % 2U) == 0U) {
      draw_cross(image, c.pixel, 4, 255, 0, 255);
    } else {
      draw_cross(image, c.pixel, 4, 255, 140, 0);
    }
  }
  if (model.tcp_valid) {
    draw_disc(image, model.tcp, 4, 255, 0, 0);
  }
}

}  // namespace vision
}  // namespace tcpest
