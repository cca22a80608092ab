#include "tcpest/solver/config_io.hpp"

#include <gtest/gtest.h>

#include <cstring>

namespace tcpest {
namespace solver {
namespace {

yaml::Document& scratch() {
  static yaml::Document d;
  return d;
}

Result<CameraIntrinsics, Diagnostic> camera_from(const char* text) {
  const auto parsed = scratch().parse(text, std::strlen(text), "cam.yaml");
  if (!parsed.ok()) {
    return Result<CameraIntrinsics, Diagnostic>::failure(parsed.error());
  }
  return read_camera_info(scratch());
}

const char* kGood =
    "image_width: 720\nimage_height: 576\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
    "  data: [400, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\ndistortion_model: plumb_bob\n"
    "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.32, 0.11, 0, 0, 0]\n";

TEST(ConfigIo, ReadsShippedFiles) {
  const auto cam = load_camera_info(TCPEST_TEST_DATA_DIR "/../../config/pal_camera.yaml", scratch());
  ASSERT_TRUE(cam.ok());
  EXPECT_EQ(cam.value().width, 720);
  EXPECT_DOUBLE_EQ(cam.value().k1, -0.32);
  const auto geo = load_instrument_config(TCPEST_TEST_DATA_DIR "/../../config/instrument.yaml", scratch());
  ASSERT_TRUE(geo.ok()) << geo.error().message;
  EXPECT_DOUBLE_EQ(geo.value().nominal_psi_rad, deg_to_rad(10.0));
  EXPECT_DOUBLE_EQ(geo.value().boundaries_mm[3], 11.1);
}

TEST(ConfigIo, ReadsAGoodCamera) {
  const auto cam = camera_from(kGood);
  ASSERT_TRUE(cam.ok());
  EXPECT_DOUBLE_EQ(cam.value().cy, 287.5);
}

struct BadCase {
  const char* text;
  unsigned line;
  const char* field;
};

TEST(ConfigIo, NamesTheFieldOfEveryBadCamera) {
  const BadCase cases[] = {
      {"image_height: 576\ncamera_matrix:\n  data: [400, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\n", 0, "image_width"},
      {"image_width: abc\n", 1, "image_width"},
      {"image_width: 720\nimage_height: 576\ncamera_matrix:\n  data: [0, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\n"
       "distortion_model: plumb_bob\ndistortion_coefficients:\n  data: [0, 0, 0, 0, 0]\n",
       4, "camera_matrix.data"},
      {"image_width: 720\nimage_height: 576\ncamera_matrix:\n  data: [400, 0, 359.5, 0, 400, 287.5]\n", 4,
       "camera_matrix.data"},
      {"image_width: 720\nimage_height: 576\ncamera_matrix:\n  data: [400, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\n"
       "distortion_model: fisheye\n",
       5, "distortion_model"},
      {"image_width: 720\nimage_height: 576\ncamera_matrix:\n  data: [400, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\n"
       "distortion_model: plumb_bob\ndistortion_coefficients:\n  data: [0.1, nan, 0, 0, 0]\n",
       7, "distortion_coefficients.data"},
      {"image_width: 720\nimage_height: 576\ncamera_matrix:\n  data: [400, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\n"
       "distortion_model: plumb_bob\n",
       0, "distortion_coefficients.data"},
  };
  for (const BadCase& c : cases) {
    const auto cam = camera_from(c.text);
    ASSERT_FALSE(cam.ok()) << c.text;
    EXPECT_EQ(cam.error().line, c.line) << c.text;
    EXPECT_STREQ(cam.error().field, c.field) << c.text;
  }
}

TEST(ConfigIo, GeometryDefaultsAndErrors) {
  const char* empty = "other_section:\n  anything: 1\n";
  ASSERT_TRUE(scratch().parse(empty, std::strlen(empty), "cfg.yaml").ok());
  const auto defaults = read_instrument_config(scratch());
  ASSERT_TRUE(defaults.ok());
  EXPECT_DOUBLE_EQ(defaults.value().radius_mm, 1.81);

  const char* typo = "instrument:\n  radius_mn: 2\n";
  ASSERT_TRUE(scratch().parse(typo, std::strlen(typo), "cfg.yaml").ok());
  const auto bad = read_instrument_config(scratch());
  ASSERT_FALSE(bad.ok());
  EXPECT_STREQ(bad.error().field, "instrument.radius_mn");
  EXPECT_STREQ(bad.error().message, "unknown key");

  const char* negative = "instrument:\n  bend_length_mm: -18.5\n";
  ASSERT_TRUE(scratch().parse(negative, std::strlen(negative), "cfg.yaml").ok());
  EXPECT_FALSE(read_instrument_config(scratch()).ok());

  const char* fat = "instrument:\n  radius_mm: 12\n";
  ASSERT_TRUE(scratch().parse(fat, std::strlen(fat), "cfg.yaml").ok());
  const auto too_fat = read_instrument_config(scratch());
  ASSERT_FALSE(too_fat.ok());
  EXPECT_STREQ(too_fat.error().field, "instrument.radius_mm");
  EXPECT_EQ(too_fat.error().line, 2U);
}

TEST(ConfigIo, MarkerColoursAreFiveBlueOrYellow) {
  const char* swapped = "instrument:\n  marker_colors: [yellow, blue, yellow, blue, yellow]\n";
  ASSERT_TRUE(scratch().parse(swapped, std::strlen(swapped), "cfg.yaml").ok());
  const auto read = read_instrument_config(scratch());
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read.value().marker_colors[0], MarkerColor::Yellow);
  EXPECT_EQ(read.value().marker_colors[1], MarkerColor::Blue);
  EXPECT_EQ(read.value().marker_colors[4], MarkerColor::Yellow);

  struct Bad {
    const char* text;
    const char* message;
  };
  const Bad bad_files[] = {
      {"instrument:\n  marker_colors: [blue, red, blue, yellow, blue]\n", "colours are 'blue' or 'yellow'"},
      {"instrument:\n  marker_colors: [blue, yellow, blue, yellow, blue, yellow]\n", "expected 5 colours"},
      {"instrument:\n  marker_colors: [blue, yellow, blue, yellow]\n", "expected a sequence of 5 colours"},
      {"instrument:\n  marker_colors: blue\n", "expected a sequence of 5 colours"},
  };
  for (const Bad& b : bad_files) {
    ASSERT_TRUE(scratch().parse(b.text, std::strlen(b.text), "cfg.yaml").ok()) << b.text;
    const auto result = read_instrument_config(scratch());
    ASSERT_FALSE(result.ok()) << b.text;
    EXPECT_STREQ(result.error().field, "instrument.marker_colors") << b.text;
    EXPECT_STREQ(result.error().message, b.message) << b.text;
    EXPECT_EQ(result.error().line, 2U) << b.text;
  }
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
