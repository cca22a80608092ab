#include "jpeg_test_images.hpp"

#include <cstdio>
#include <cstdlib>

extern "C" {
#include <jpeglib.h>
}

namespace tcpest {
namespace hal {
namespace testing {

std::vector<std::uint8_t> make_pattern(int width, int height, int seed) {
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3U);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t i = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3U;
      rgb[i] = static_cast<std::uint8_t>((x * 255) / (width > 1 ? width - 1 : 1));
      rgb[i + 1U] = static_cast<std::uint8_t>((y * 255) / (height > 1 ? height - 1 : 1));
      rgb[i + 2U] = static_cast<std::uint8_t>((x + y + seed * 37) & 0xFF);
    }
  }
  return rgb;
}

std::vector<std::uint8_t> encode_jpeg(const std::vector<std::uint8_t>& rgb, int width, int height,
                                      const EncodeOptions& options) {
  jpeg_compress_struct cinfo{};
  jpeg_error_mgr jerr{};
  cinfo.err = jpeg_std_error(&jerr);
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = static_cast<JDIMENSION>(width);
  cinfo.image_height = static_cast<JDIMENSION>(height);
  cinfo.input_components = 3;
  cinfo.in_color_space = JCS_RGB;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, options.quality, TRUE);
  if (options.grayscale) {
    jpeg_set_colorspace(&cinfo, JCS_GRAYSCALE);
  }
  if (options.progressive) {
    jpeg_simple_progression(&cinfo);
  }
  if (!options.grayscale) {
    cinfo.comp_info[0].h_samp_factor = options.luma_h_samp;
    cinfo.comp_info[0].v_samp_factor = options.luma_v_samp;
  }
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = const_cast<JSAMPROW>(rgb.data() + static_cast<std::size_t>(cinfo.next_scanline) *
                                                         static_cast<std::size_t>(width) * 3U);
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  std::vector<std::uint8_t> out(buffer, buffer + size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return out;
}

}  // namespace testing
}  // namespace hal
}  // namespace tcpest
