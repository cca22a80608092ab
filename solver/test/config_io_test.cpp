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

Result<CameraIntrinsics, Diagnostic> camera_file(const std::string& path) {
  return load_camera_info(path.c_str(), scratch());
}

// The same camera bit for bit: the same model, hence the same estimates.
void expect_same_camera(const CameraIntrinsics& a, const CameraIntrinsics& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  const double pa[9] = {a.fx, a.fy, a.cx, a.cy, a.k1, a.k2, a.p1, a.p2, a.k3};
  const double pb[9] = {b.fx, b.fy, b.cx, b.cy, b.k1, b.k2, b.p1, b.p2, b.k3};
  for (int i = 0; i < 9; ++i) {
    EXPECT_EQ(std::memcmp(&pa[i], &pb[i], sizeof(double)), 0) << "parameter " << i;
  }
  const auto ma = CameraModel::create(a);
  const auto mb = CameraModel::create(b);
  ASSERT_TRUE(ma.ok() && mb.ok());
  EXPECT_EQ(ma.value().max_r2(), mb.value().max_r2());
  Vec2 ua;
  Vec2 ub;
  const Vec3 point(3.0, -2.0, 40.0);
  ASSERT_TRUE(ma.value().project(point, ua) && mb.value().project(point, ub));
  EXPECT_EQ(ua.x(), ub.x());
  EXPECT_EQ(ua.y(), ub.y());
}

// The shipped PAL camera as ROS and as OpenCV's FileStorage write it: the
// same camera.
TEST(ConfigIo, OpenCvAndRosFormsOfOneCalibrationAreTheSameCamera) {
  const auto ros = camera_file(TCPEST_TEST_DATA_DIR "/../../config/pal_camera.yaml");
  ASSERT_TRUE(ros.ok());
  const auto opencv = camera_file(TCPEST_TEST_DATA_DIR "/../../config/pal_camera_opencv.yaml");
  ASSERT_TRUE(opencv.ok()) << opencv.error().message;
  expect_same_camera(ros.value(), opencv.value());
}

// OpenCV's calibration sample with -op -oe: its image points (4 views of a
// 9 x 6 board, 432 numbers), extrinsics and per-view errors are skipped as
// the file is parsed; the numbers as %.16e, with the emitter's line wraps.
TEST(ConfigIo, ReadsTheCalibrationSampleOutput) {
  const auto cam = camera_file(TCPEST_TEST_DATA_DIR "/calib/calibration_sample_4x9x6.yaml");
  ASSERT_TRUE(cam.ok()) << cam.error().message;
  const CameraIntrinsics& k = cam.value();
  EXPECT_EQ(k.width, 720);
  EXPECT_EQ(k.height, 576);
  EXPECT_DOUBLE_EQ(k.fx, 5.2034567890123458e+02);
  EXPECT_DOUBLE_EQ(k.fy, 5.1987654321098762e+02);
  EXPECT_DOUBLE_EQ(k.cx, 3.5987654321098768e+02);
  EXPECT_DOUBLE_EQ(k.cy, 2.8812345678901232e+02);
  EXPECT_DOUBLE_EQ(k.k1, -2.9876543210987655e-01);
  EXPECT_DOUBLE_EQ(k.k2, 1.0123456789012344e-01);
  EXPECT_DOUBLE_EQ(k.p1, 1.2345678901234567e-04);
  EXPECT_DOUBLE_EQ(k.p2, -2.3456789012345677e-04);
  EXPECT_DOUBLE_EQ(k.k3, -1.2345678901234568e-02);
  EXPECT_FALSE(scratch().has("image_points.data"));  // skipped, not stored
  // Without the key set the image points do not fit an entry: the reason
  // the reader skips them.
  const std::string text = test::read_text_file(TCPEST_TEST_DATA_DIR "/calib/calibration_sample_4x9x6.yaml");
  const auto whole = scratch().parse(text.data(), text.size(), "sample.yaml");
  ASSERT_FALSE(whole.ok());
  EXPECT_STREQ(whole.error().field, "image_points.data");
  // Another program's spelling (cameraMatrix / distCoeffs, 1 x 5) and
  // OpenCV 4's shortest round-trip numbers: the same camera.
  const auto spelled = camera_file(TCPEST_TEST_DATA_DIR "/calib/opencv_cameraMatrix_distCoeffs.yaml");
  ASSERT_TRUE(spelled.ok()) << spelled.error().message;
  expect_same_camera(k, spelled.value());
}

Result<CameraIntrinsics, Diagnostic> opencv_camera_from(const std::string& text) {
  const auto parsed = scratch().parse(text.data(), text.size(), "cam.yml", camera_info_keys());
  if (!parsed.ok()) {
    return Result<CameraIntrinsics, Diagnostic>::failure(parsed.error());
  }
  return read_camera_info(scratch());
}

const char* kOpenCv =
    "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
    "   data: [ 5.2e+02, 0., 3.6e+02, 0., 5.2e+02, 2.8e+02, 0., 0., 1. ]\n"
    "distortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n"
    "   data: [ -0.2, 0.1, 0., 0., 0. ]\nimage_width: 720\nimage_height: 576\n";

// Every damaged OpenCV file is refused with the field, the line and what is
// wrong named.
TEST(ConfigIo, NamesWhatIsWrongInAnOpenCvFile) {
  const auto good = opencv_camera_from(kOpenCv);
  ASSERT_TRUE(good.ok()) << good.error().message;
  EXPECT_DOUBLE_EQ(good.value().fx, 520.0);
  EXPECT_DOUBLE_EQ(good.value().k1, -0.2);
  struct Damage {
    const char* from;
    const char* to;
    const char* field;
    unsigned line;
    const char* message;  // a part of it
  };
  const Damage damages[] = {
      {"   rows: 3\n   cols: 3", "   rows: 3\n   cols: 2", "camera_matrix.data", 7U, "3 x 2, but data has 9"},
      {"   rows: 5\n   cols: 1", "   rows: 4\n   cols: 1", "distortion_coefficients.data", 12U, "but data has 5"},
      {"   dt: d\n   data: [ 5.2e", "   dt: u\n   data: [ 5.2e", "camera_matrix.dt", 6U, "d (double) or f"},
      {"   cols: 3\n   dt: d\n", "   cols: 3\n", "distortion_model", 0U, "dt"},  // then read as ROS
      {"rows: 5\n   cols: 1\n   dt: d\n   data: [ -0.2, 0.1, 0., 0., 0. ]",
       "rows: 8\n   cols: 1\n   dt: d\n   data: [ -0.2, 0.1, 0., 0., 0., 0.01, 0., 0. ]",
       "distortion_coefficients.data", 12U, "8 coefficients with k4.. not zero"},
      {"rows: 5\n   cols: 1\n   dt: d\n   data: [ -0.2, 0.1, 0., 0., 0. ]",
       "rows: 8\n   cols: 1\n   dt: d\n   data: [ -0.2, 0.1, 0., 0., 0., 0., 0., 0. ]", "", 0U, ""},  // zeros: plumb_bob
      {"rows: 5\n   cols: 1\n   dt: d\n   data: [ -0.2, 0.1, 0., 0., 0. ]",
       "rows: 1\n   cols: 6\n   dt: d\n   data: [ -0.2, 0.1, 0., 0., 0., 0. ]", "distortion_coefficients.data", 12U,
       "6 coefficients"},
      {"camera_matrix: !!opencv-matrix", "intrinsics: !!opencv-matrix", "camera_matrix.data", 0U,
       "missing (also read as cameraMatrix"},
      {"distortion_coefficients: !!opencv-matrix", "distCoeffs: !!opencv-matrix", "", 0U, ""},  // accepted
      {"image_width: 720\n", "image_width: 720\ncameraMatrix: 1\n", "cameraMatrix", 14U, "also given as"},
      {"5.2e+02, 0., 3.6e+02, 0., 5.2e+02", "5.2e+09, 0., 3.6e+02, 0., 5.2e+02", "camera_matrix.data", 7U,
       "fx = 5.2e+09 is outside"},
      {"[ -0.2, 0.1, 0., 0., 0. ]", "[ -0.2, 0.1, 3., 0., 0. ]", "distortion_coefficients.data", 12U, "p1 = 3"},
  };
  for (const Damage& d : damages) {
    std::string text(kOpenCv);
    const std::size_t at = text.find(d.from);
    ASSERT_NE(at, std::string::npos) << d.from;
    text.replace(at, std::strlen(d.from), d.to);
    const auto cam = opencv_camera_from(text);
    if (d.field[0] == '\0') {
      EXPECT_TRUE(cam.ok()) << text;
      continue;
    }
    ASSERT_FALSE(cam.ok()) << text;
    EXPECT_STREQ(cam.error().field, d.field) << text;
    EXPECT_EQ(cam.error().line, d.line) << text;
    EXPECT_NE(std::strstr(cam.error().message, d.message), nullptr) << d.message << " / " << cam.error().message;
  }
  // A ROS file that lost its distortion_model says what either form needs.
  std::string ros(kGood);
  ros.replace(ros.find("distortion_model: plumb_bob\n"), 28, "");
  const auto no_model = camera_from(ros.c_str());
  ASSERT_FALSE(no_model.ok());
  EXPECT_STREQ(no_model.error().field, "distortion_model");
  EXPECT_NE(std::strstr(no_model.error().message, "dt"), nullptr) << no_model.error().message;
}

// Seeded damage to the shipped files: each damaged file is refused with
// the field named, or it is usable as it reads (a camera model that
// projects, a geometry that validates). Never a crash or a half-read value.
// Verifies: REQ-ERR-002
TEST(ConfigIo, DamagedFilesAreRefusedOrUsable) {
  const std::string camera_text = test::read_text_file(TCPEST_TEST_DATA_DIR "/../../config/pal_camera.yaml");
  const std::string geometry_text = test::read_text_file(TCPEST_TEST_DATA_DIR "/../../config/instrument.yaml");
  const std::string opencv_text = test::read_text_file(TCPEST_TEST_DATA_DIR "/calib/calibration_sample_4x9x6.yaml");
  ASSERT_FALSE(camera_text.empty());
  ASSERT_FALSE(geometry_text.empty());
  ASSERT_FALSE(opencv_text.empty());
  test::Mutator mutator(20261127U);
  int refused = 0;
  for (int i = 0; i < 20000; ++i) {
    // Even: a camera, every other one in OpenCV's form (parsed as the loader does).
    const bool opencv = i % 4 == 2;
    const std::string text = mutator.damage(i % 2 == 1 ? geometry_text : opencv ? opencv_text : camera_text);
    const auto parsed = scratch().parse(text.data(), text.size(), "damaged.yaml",
                                        opencv ? camera_info_keys() : yaml::KeySet{});
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
