// The colour model shipped in config/colors.json, built in (regenerate both
// with `tcpest train-colors`, see docs/vision.md; a test checks they agree).
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {

ColorModel default_color_model() noexcept {
  ColorModel m;
  m.min_lightness = 8.0;
  m.blue = ColorGaussian{4.87894, -45.203866, 20.584684, -13.051775, 28.716138, 6.0};
  m.yellow = ColorGaussian{-11.563884, 58.979005, 9.725526, -26.885446, 141.256348, 4.88};
  return m;
}

}  // namespace vision
}  // namespace tcpest
