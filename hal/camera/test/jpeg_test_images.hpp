// Test helpers: synthetic RGB images and their JPEG encodings (libjpeg).
#pragma once

#include <cstdint>
#include <vector>

namespace tcpest {
namespace hal {
namespace testing {

// A smooth RGB pattern, width x height, tightly packed.
std::vector<std::uint8_t> make_pattern(int width, int height, int seed);

struct EncodeOptions {
  int quality = 95;
  bool progressive = false;
  bool grayscale = false;
  // The luma's sampling factors (chroma at 1x1): 2x2 is 4:2:0, libjpeg's
  // default. With the two chroma blocks, at most 10 blocks per MCU (e.g.
  // 4x2, not 3x3): libjpeg's encoder exits the process beyond that.
  int luma_h_samp = 2;
  int luma_v_samp = 2;
};

std::vector<std::uint8_t> encode_jpeg(const std::vector<std::uint8_t>& rgb, int width, int height,
                                      const EncodeOptions& options = EncodeOptions{});

}  // namespace testing
}  // namespace hal
}  // namespace tcpest
