#include "tcpest/render/image_io.hpp"

#include <gtest/gtest.h>
#include <turbojpeg.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace tcpest {
namespace render {
namespace {

std::vector<std::uint8_t> gradient(int w, int h) {
  std::vector<std::uint8_t> p(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3U);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      std::uint8_t* q = &p[(static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)) * 3U];
      q[0] = static_cast<std::uint8_t>(x * 255 / (w - 1));
      q[1] = static_cast<std::uint8_t>(y * 255 / (h - 1));
      q[2] = 128U;
    }
  }
  return p;
}

std::string slurp(const std::string& path) {
  std::string data;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    return data;
  }
  char buffer[65536];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) {
    data.append(buffer, n);
  }
  std::fclose(f);
  return data;
}

TEST(Jpeg, EncodesDecodablyAndDeterministically) {
  const int w = 96;
  const int h = 64;
  const auto pixels = gradient(w, h);
  const ImageView view{pixels.data(), w, h, static_cast<std::size_t>(w) * 3U};
  auto encoder = JpegEncoder::create(w, h);
  ASSERT_TRUE(encoder.ok());
  ASSERT_TRUE(encoder.value()->encode(view, 95).ok());
  const std::vector<std::uint8_t> first(encoder.value()->data(), encoder.value()->data() + encoder.value()->size());
  ASSERT_TRUE(encoder.value()->encode(view, 95).ok());
  EXPECT_EQ(first, std::vector<std::uint8_t>(encoder.value()->data(), encoder.value()->data() + encoder.value()->size()));
  // Decode and compare.
  tjhandle decoder = tjInitDecompress();
  ASSERT_NE(decoder, nullptr);
  int dw = 0;
  int dh = 0;
  int subsampling = 0;
  int colorspace = 0;
  ASSERT_EQ(tjDecompressHeader3(decoder, first.data(), first.size(), &dw, &dh, &subsampling, &colorspace), 0);
  EXPECT_EQ(dw, w);
  EXPECT_EQ(dh, h);
  std::vector<std::uint8_t> decoded(pixels.size());
  ASSERT_EQ(tjDecompress2(decoder, first.data(), first.size(), decoded.data(), w, w * 3, h, TJPF_RGB, 0), 0);
  tjDestroy(decoder);
  double max_error = 0.0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    max_error = std::max(max_error, std::abs(static_cast<double>(pixels[i]) - decoded[i]));
  }
  EXPECT_LT(max_error, 12.0);
  // Lower quality: smaller file.
  ASSERT_TRUE(encoder.value()->encode(view, 30).ok());
  EXPECT_LT(encoder.value()->size(), first.size());
}

TEST(Jpeg, BadInputIsRefused) {
  auto encoder = JpegEncoder::create(32, 32);
  ASSERT_TRUE(encoder.ok());
  const auto pixels = gradient(64, 64);
  const ImageView too_big{pixels.data(), 64, 64, 64U * 3U};
  EXPECT_EQ(encoder.value()->encode(too_big, 90).error(), ImageIoError::BadImage);
  const ImageView ok{pixels.data(), 32, 32, 64U * 3U};
  EXPECT_EQ(encoder.value()->encode(ok, 0).error(), ImageIoError::BadQuality);
  EXPECT_EQ(encoder.value()->encode(ok, 101).error(), ImageIoError::BadQuality);
  EXPECT_EQ(encoder.value()->encode(ImageView{}, 90).error(), ImageIoError::BadImage);
  EXPECT_EQ(encoder.value()->write_file(ok, 90, "/nonexistent-dir/x.jpg").error(), ImageIoError::OpenFailed);
  EXPECT_FALSE(JpegEncoder::create(0, 10).ok());
}

TEST(PpmAndPng, WriteExpectedBytes) {
  const int w = 5;
  const int h = 3;
  const auto pixels = gradient(w, h);
  const ImageView view{pixels.data(), w, h, static_cast<std::size_t>(w) * 3U};
  const std::string ppm = ::testing::TempDir() + "image_io_test.ppm";
  ASSERT_TRUE(write_ppm_file(view, ppm.c_str()).ok());
  const std::string data = slurp(ppm);
  ASSERT_EQ(data.substr(0, 11), "P6\n5 3\n255\n");
  EXPECT_EQ(data.substr(11), std::string(pixels.begin(), pixels.end()));
  const std::string png = ::testing::TempDir() + "image_io_test.png";
  ASSERT_TRUE(write_png_file(view, png.c_str()).ok());
  const std::string p = slurp(png);
  ASSERT_GT(p.size(), 8U);
  EXPECT_EQ(p.substr(1, 3), "PNG");
  EXPECT_EQ(p.substr(p.size() - 8, 4), "IEND");
  // Stored deflate: every row's bytes appear verbatim after its filter byte.
  EXPECT_NE(p.find(std::string(pixels.begin(), pixels.begin() + 15)), std::string::npos);
  EXPECT_EQ(write_ppm_file(view, "/nonexistent-dir/x.ppm").error(), ImageIoError::OpenFailed);
  std::remove(ppm.c_str());
  std::remove(png.c_str());
}

}  // namespace
}  // namespace render
}  // namespace tcpest
