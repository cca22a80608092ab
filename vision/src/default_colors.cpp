// The colour model shipped in config/colors.json, built in (regenerate both
// with `tcpest train-colors`, see docs/vision.md; a test checks they agree).
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {

ColorModel default_color_model() noexcept {
  ColorModel m;
  m.min_lightness = 8.0;
  m.blue = ColorGaussian{4.320735, -44.864997, 23.093389, -16.173945, 34.959442, 6.0};
  m.yellow = ColorGaussian{-11.72294, 58.703289, 9.804949, -27.692832, 149.177529, 4.76};
  return m;
}

}  // namespace vision
}  // namespace tcpest
