// The colour model shipped in config/colors.json, built in (regenerate both
// with `tcpest train-colors`, see docs/vision.md; a test checks they agree).
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {

ColorModel default_color_model() noexcept {
  ColorModel m;
  m.min_lightness = 8.0;
  m.blue = ColorGaussian{21.766150, -49.065541, 20.292616, -29.867263, 52.827461, 3.3200};
  m.yellow = ColorGaussian{-1.282914, 54.793367, 6.843494, -1.354576, 55.745274, 3.4200};
  return m;
}

}  // namespace vision
}  // namespace tcpest
