// Sub-pixel colour sampling shared by the vision stages (private header).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "tcpest/common/dmath.hpp"
#include "tcpest/common/image.hpp"

namespace tcpest {
namespace vision {
namespace detail {

struct Rgb {
  double r = 0.0, g = 0.0, b = 0.0;
};

// Bilinear RGB at a sub-pixel position; false outside the image.
inline bool sample(const ImageView& image, double x, double y, Rgb& out) noexcept {
  if (!(x >= 0.0) || !(y >= 0.0) || x > static_cast<double>(image.width - 1) ||
      y > static_cast<double>(image.height - 1)) {
    return false;
  }
  int x0 = static_cast<int>(x);
  int y0 = static_cast<int>(y);
  if (x0 >= image.width - 1) {
    x0 = image.width - 2;
  }
  if (y0 >= image.height - 1) {
    y0 = image.height - 2;
  }
  if (x0 < 0 || y0 < 0) {
    return false;  // a one-pixel-wide image
  }
  const double fx = x - static_cast<double>(x0);
  const double fy = y - static_cast<double>(y0);
  const std::uint8_t* a = image.row(y0) + static_cast<std::ptrdiff_t>(3) * x0;
  const std::uint8_t* b = image.row(y0 + 1) + static_cast<std::ptrdiff_t>(3) * x0;
  const double w00 = (1.0 - fx) * (1.0 - fy);
  const double w10 = fx * (1.0 - fy);
  const double w01 = (1.0 - fx) * fy;
  const double w11 = fx * fy;
  out.r = w00 * a[0] + w10 * a[3] + w01 * b[0] + w11 * b[3];
  out.g = w00 * a[1] + w10 * a[4] + w01 * b[1] + w11 * b[4];
  out.b = w00 * a[2] + w10 * a[5] + w01 * b[2] + w11 * b[5];
  return true;
}

// sRGB code values (0-255) to linear light (0-1): the decoding curve of
// the 256 codes (IEC 61966-2-1); interpolated samples linear between them.
// One table for the unit (linear_light()): the colour model's L*a*b* and
// the model-guided readings.
class LinearLight {
 public:
  LinearLight() noexcept {
    for (std::size_t i = 0U; i < table_.size(); ++i) {
      const double c = static_cast<double>(i) / 255.0;
      table_[i] = c <= 0.04045 ? c / 12.92 : dmath::pow_positive((c + 0.055) / 1.055, 2.4);  // IEC 61966-2-1
    }
  }
  double operator()(double code) const noexcept {
    const double v = code > 0.0 ? (code < 255.0 ? code : 255.0) : 0.0;  // NaN: 0
    const auto i = static_cast<std::size_t>(v >= 254.0 ? 254.0 : v);
    const double f = v - static_cast<double>(i);
    return table_[i] + f * (table_[i + 1U] - table_[i]);
  }
  double of_code(std::uint8_t code) const noexcept { return table_[code]; }  // exact

 private:
  std::array<double, 256> table_{};
};

// The unit's table, built on first use: FeatureExtractor::create builds the
// classifier's lookup table through srgb_to_lab, so at start-up.
inline const LinearLight& linear_light() noexcept {
  static const LinearLight table;
  return table;
}

inline std::uint8_t to_byte(double v) noexcept {
  const double c = v < 0.0 ? 0.0 : (v > 255.0 ? 255.0 : v);
  return static_cast<std::uint8_t>(std::lround(c));
}

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
