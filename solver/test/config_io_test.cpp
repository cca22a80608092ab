#include "tcpest/solver/config_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>

#include "tcpest/test/mutate.hpp"

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

// Verifies: REQ-ERR-002
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

// Verifies: REQ-ERR-002
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

// Verifies: REQ-ERR-002
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

// The matrices the raw image does not use (R, P) and the matrices' sizes,
// when a file gives them, must be well formed: a damaged file is refused,
// not half read. OpenCV's N x 1 distortion vector is accepted.
// Verifies: REQ-ERR-002
TEST(ConfigIo, RefusesDamagedMatricesItDoesNotUse) {
  const std::string good(kGood);
  const std::string full = good +
                           "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
                           "projection_matrix:\n  rows: 3\n  cols: 4\n"
                           "  data: [400, 0, 359.5, 0, 0, 400, 287.5, 0, 0, 0, 1, 0]\n";
  ASSERT_TRUE(camera_from(full.c_str()).ok());
  std::string column = full;
  column.replace(column.find("rows: 1\n  cols: 5"), 17, "rows: 5\n  cols: 1");
  EXPECT_TRUE(camera_from(column.c_str()).ok()) << column;
  struct Damage {
    const char* from;
    const char* to;
    const char* field;
  };
  const Damage damages[] = {
      {"287.5, 0, 0, 0, 1, 0]", "287.5, 0, 0, 0, 1, nan]", "projection_matrix.data"},
      {"0, 400, 287.5, 0, 0, 0, 1, 0]", "0, 400, 287.5, 0, 0, 0, 1]", "projection_matrix.data"},
      {"[1, 0, 0, 0, 1, 0, 0, 0, 1]", "[1, 0, 0, 0, 1, 0, 0, 0, 1e999]", "rectification_matrix.data"},
      {"[1, 0, 0, 0, 1, 0, 0, 0, 1]", "[1, 0, 0, 0, 1, 0, \"0, 0, 1]", "rectification_matrix.data"},
      {"  rows: 3\n  cols: 4", "  rows: 3\n  cols: 5", "projection_matrix.cols"},
      {"camera_matrix:\n  rows: 3", "camera_matrix:\n  rows: 34294967296", "camera_matrix.rows"},
      {"camera_matrix:\n  rows: 3\n  cols: 3", "camera_matrix:\n  rows: 3\n  cols: x", "camera_matrix.cols"},
      {"rows: 1\n  cols: 5", "rows: 1\n  cols: 6", "distortion_coefficients.cols"},
      {"rows: 1\n  cols: 5", "rows: 4611686018427387904\n  cols: 4", "distortion_coefficients.cols"},
  };
  for (const Damage& d : damages) {
    std::string text = full;
    const std::size_t at = text.find(d.from);
    ASSERT_NE(at, std::string::npos) << d.from;
    text.replace(at, std::strlen(d.from), d.to);
    const auto cam = camera_from(text.c_str());
    ASSERT_FALSE(cam.ok()) << text;
    EXPECT_STREQ(cam.error().field, d.field) << text;
    EXPECT_GT(cam.error().line, 0U) << text;
  }
}

// Finite but absurd calibrations (a mistyped exponent, a wrong file) are
// refused with the element and its plausible range named.
// Verifies: REQ-MODEL-005, REQ-ERR-002
TEST(ConfigIo, RefusesAbsurdButFiniteCalibrations) {
  struct Absurd {
    const char* from;
    const char* to;
    const char* field;
    const char* named;  // the element and its range in the message
  };
  const Absurd cases[] = {
      {"[400, 0, 359.5", "[1e308, 0, 359.5", "camera_matrix.data", "fx = 1e+308 is outside its plausible range 1..100000 px"},
      {"[400, 0, 359.5", "[1e-300, 0, 359.5", "camera_matrix.data", "fx = 1e-300 is outside its plausible range 1..100000"},
      {"0, 400, 287.5", "0, 0.5, 287.5", "camera_matrix.data", "fy = 0.5 is outside its plausible range 1..100000"},
      {"0, 359.5, 0", "0, 1e6, 0", "camera_matrix.data", "cx = 1e+06 is outside its plausible range -720..1440"},
      {"400, 287.5, 0", "400, -600, 0", "camera_matrix.data", "cy = -600 is outside its plausible range -576..1152"},
      {"[-0.32, 0.11, 0, 0, 0]", "[1e10, 0.11, 0, 0, 0]", "distortion_coefficients.data",
       "k1 = 1e+10 is outside its plausible range -100..100"},
      {"[-0.32, 0.11, 0, 0, 0]", "[-0.32, -101, 0, 0, 0]", "distortion_coefficients.data", "k2 = -101"},
      {"[-0.32, 0.11, 0, 0, 0]", "[-0.32, 0.11, 2, 0, 0]", "distortion_coefficients.data",
       "p1 = 2 is outside its plausible range -1..1"},
      {"[-0.32, 0.11, 0, 0, 0]", "[-0.32, 0.11, 0, 0, 1e300]", "distortion_coefficients.data", "k3 = 1e+300"},
  };
  for (const Absurd& c : cases) {
    std::string text(kGood);
    const std::size_t at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, std::strlen(c.from), c.to);
    const auto cam = camera_from(text.c_str());
    ASSERT_FALSE(cam.ok()) << text;
    EXPECT_STREQ(cam.error().file, "cam.yaml");
    EXPECT_GT(cam.error().line, 0U) << text;
    EXPECT_STREQ(cam.error().field, c.field) << text;
    EXPECT_NE(std::strstr(cam.error().message, c.named), nullptr) << cam.error().message;
  }
  // The edges of the ranges are accepted.
  std::string edge(kGood);
  edge.replace(edge.find("[-0.32, 0.11, 0, 0, 0]"), 22, "[-100, 100, 1, -1, 0]");
  EXPECT_TRUE(camera_from(edge.c_str()).ok());
}

// Verifies: REQ-ERR-002
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

// Finite but absurd geometry values are refused at their key with the
// plausible range named.
// Verifies: REQ-MODEL-005, REQ-ERR-002
TEST(ConfigIo, RefusesAbsurdButFiniteGeometry) {
  struct Absurd {
    const char* text;
    const char* field;
    const char* named;
  };
  const Absurd cases[] = {
      {"instrument:\n  lambda_max_mm: 1e300\n", "instrument.lambda_max_mm",
       "1e+300 is outside its plausible range (0, 1000] mm"},
      {"instrument:\n  lambda_min_mm: -5\n", "instrument.lambda_min_mm", "-5 is outside its plausible range [0, 1000] mm"},
      {"instrument:\n  bend_length_mm: 1e-320\n  radius_mm: 0\n", "instrument.radius_mm", "(0, 1000] mm"},
      {"instrument:\n  tcp_offset_mm: 5000\n", "instrument.tcp_offset_mm", "(0, 1000] mm"},
      {"instrument:\n  theta_max_deg: 1e308\n", "instrument.theta_max_deg", "(0, 360] deg"},
      {"channel_nominal:\n  x_ch_mm: -1e9\n", "channel_nominal.x_ch_mm", "[-1000, 1000] mm"},
      {"channel_nominal:\n  psi_deg: 400\n", "channel_nominal.psi_deg", "[-360, 360] deg"},
      {"play_penalty:\n  position_k: 1e300\n", "play_penalty.position_k", "[0, 1e+06]"},
      {"play_penalty:\n  angle_scale_deg: 0\n", "play_penalty.angle_scale_deg", "(0, 360] deg"},
  };
  for (const Absurd& c : cases) {
    ASSERT_TRUE(scratch().parse(c.text, std::strlen(c.text), "cfg.yaml").ok()) << c.text;
    const auto read = read_instrument_config(scratch());
    ASSERT_FALSE(read.ok()) << c.text;
    EXPECT_STREQ(read.error().file, "cfg.yaml");
    EXPECT_GT(read.error().line, 1U) << c.text;
    EXPECT_STREQ(read.error().field, c.field) << c.text;
    EXPECT_NE(std::strstr(read.error().message, c.named), nullptr) << read.error().message;
  }
  // The geometry's own consistency still holds within the ranges.
  const char* empty_range = "instrument:\n  lambda_min_mm: 60\n  lambda_max_mm: 60\n";
  ASSERT_TRUE(scratch().parse(empty_range, std::strlen(empty_range), "cfg.yaml").ok());
  EXPECT_FALSE(read_instrument_config(scratch()).ok());
}

// Verifies: REQ-ERR-002
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

// Seeded damage to the shipped files: each damaged file is refused with
// the field named, or it is usable as it reads (a camera model that
// projects, a geometry that validates). Never a crash or a half-read value.
// Verifies: REQ-ERR-002
TEST(ConfigIo, DamagedFilesAreRefusedOrUsable) {
  const std::string camera_text = test::read_text_file(TCPEST_TEST_DATA_DIR "/../../config/pal_camera.yaml");
  const std::string geometry_text = test::read_text_file(TCPEST_TEST_DATA_DIR "/../../config/instrument.yaml");
  ASSERT_FALSE(camera_text.empty());
  ASSERT_FALSE(geometry_text.empty());
  test::Mutator mutator(20261127U);
  int refused = 0;
  for (int i = 0; i < 20000; ++i) {
    const std::string text = mutator.damage(i % 2 == 0 ? camera_text : geometry_text);
    const auto parsed = scratch().parse(text.data(), text.size(), "damaged.yaml");
    if (!parsed.ok()) {
      EXPECT_NE(parsed.error().message[0], '\0') << text;
      ++refused;
      continue;
    }
    if (i % 2 == 0) {
      const auto cam = read_camera_info(scratch());
      if (!cam.ok()) {
        EXPECT_NE(cam.error().field[0], '\0') << text;
        ++refused;
        continue;
      }
      const CameraIntrinsics& k = cam.value();
      EXPECT_TRUE(k.width > 0 && k.height > 0) << text;
      EXPECT_TRUE(std::isfinite(k.fx) && k.fx > 0.0 && std::isfinite(k.fy) && k.fy > 0.0) << text;
      EXPECT_TRUE(CameraModel::create(k).ok()) << text;
    } else {
      const auto geometry = read_instrument_config(scratch());
      if (!geometry.ok()) {
        EXPECT_NE(geometry.error().field[0], '\0') << text;
        ++refused;
        continue;
      }
      EXPECT_TRUE(validate(geometry.value()).ok()) << text;
      EXPECT_TRUE(InstrumentModel::create(geometry.value()).ok()) << text;
    }
  }
  EXPECT_GT(refused, 2000);
  EXPECT_GT(20000 - refused, 400);  // and some damage is harmless (a comment, a digit)  // the damage does reach the readers' checks
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
