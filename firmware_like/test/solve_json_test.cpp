// The JSON paths of tcpest project / solve / study: parsing corners, the
// output lines, a stream with malformed lines, the commands' exit codes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "cli/commands.hpp"
#include "cli/corners_json.hpp"
#include "cli/play_study.hpp"
#include "cli/setup.hpp"
#include "tcpest/test/mutate.hpp"

namespace tcpest {
namespace cli {
namespace {

ModelSetup default_setup() {
  ModelSetup setup;
  EXPECT_TRUE(load_model_setup("test", nullptr, nullptr, setup));
  return setup;
}

std::string corners_line(const solver::CornerSet& c, const char* extra) {
  char buffer[4096];
  EXPECT_TRUE(format_project_json(c, buffer, sizeof buffer));
  // Reuse the projection's "corners" member as solver input.
  std::string text(buffer);
  const auto end = text.find("], \"corners_3d\"");
  std::string line = text.substr(0, end + 1) + extra + "}";
  return line;
}

std::string read_all(std::FILE* f) {
  std::rewind(f);
  std::string out;
  char chunk[512];
  std::size_t n = 0;
  while ((n = std::fread(chunk, 1, sizeof chunk, f)) > 0) {
    out.append(chunk, n);
  }
  return out;
}

TEST(CornersJson, ParsesCornersNullsAndPrior) {
  const char* text =
      "{\"corners\": [[1, 2], null, [3.5, -4], null, null, null, null, null, null, null, null, [700, 500]],"
      " \"prior\": [20, -0.5, 1.25], \"image\": \"ignored.jpg\"}";
  CornersInput in;
  char error[128];
  ASSERT_TRUE(parse_corners_json(text, std::strlen(text), in, error, sizeof error)) << error;
  EXPECT_EQ(in.observed.count_visible(), 3);
  EXPECT_TRUE(in.observed.visible[0]);
  EXPECT_FALSE(in.observed.visible[1]);
  EXPECT_DOUBLE_EQ(in.observed.pixel[2].y(), -4.0);
  EXPECT_DOUBLE_EQ(in.observed.pixel[11].x(), 700.0);
  ASSERT_TRUE(in.has_prior);
  EXPECT_DOUBLE_EQ(in.prior[1], -0.5);
}

// Verifies: REQ-ERR-005
TEST(CornersJson, RefusesMalformedInputWithAMessage) {
  const char* bad[] = {
      "",
      "[1, 2]",
      "{\"prior\": [1, 2, 3]}",
      "{\"corners\": [[1, 2]]}",
      "{\"corners\": [[1], null, null, null, null, null, null, null, null, null, null, null]}",
      "{\"corners\": [[1, \"a\"], null, null, null, null, null, null, null, null, null, null, null]}",
      "{\"corners\": [null, null, null, null, null, null, null, null, null, null, null, null], \"prior\": [1, 2]}",
      "{\"corners\": [null, null, null, null, null, null, null, null, null, null, null, null]",
  };
  for (const char* text : bad) {
    CornersInput in;
    char error[128] = "";
    EXPECT_FALSE(parse_corners_json(text, std::strlen(text), in, error, sizeof error)) << text;
    EXPECT_GT(std::strlen(error), 5U) << text;
  }
}

// Seeded damage to a valid input line: refused with a message, or every
// corner it marks visible and its prior finite (what the solver may take).
// Verifies: REQ-ERR-005
TEST(CornersJson, DamagedInputIsRefusedOrFinite) {
  const std::string valid =
      "{\"corners\": [[1, 2], null, [3.5, -4], null, [10, 20], null, null, null, null, null, null, [700, 500]],"
      " \"prior\": [20, -0.5, 1.25], \"image\": \"ignored.jpg\"}";
  test::Mutator mutator(5U);
  int refused = 0;
  for (int i = 0; i < 20000; ++i) {
    const std::string text = mutator.damage(valid);
    CornersInput in;
    char error[128] = "";
    if (!parse_corners_json(text.data(), text.size(), in, error, sizeof error)) {
      EXPECT_GT(std::strlen(error), 5U) << text;
      ++refused;
      continue;
    }
    for (int k = 0; k < solver::kNumCorners; ++k) {
      EXPECT_TRUE(!in.observed.visible[k] || in.observed.pixel[k].allFinite()) << text;
    }
    EXPECT_TRUE(!in.has_prior || (std::isfinite(in.prior[0]) && std::isfinite(in.prior[1]) &&
                                  std::isfinite(in.prior[2])))
        << text;
  }
  EXPECT_GT(refused, 2000);
  EXPECT_GT(20000 - refused, 400);
}

// Verifies: REQ-ERR-005
TEST(CornersJson, SolveLineHasEveryMemberAndNullsForRefusedInput) {
  solver::SolveSummary s;
  s.status = solver::SolveStatus::ConvergedGradient;
  s.iterations = 7;
  s.corners_used = 12;
  s.rms_px = 0.25;
  solver::PoseVector r;
  r << -13.3, 6.2, 0.17, 0.0, 20.0, -0.5, 1.0;
  char line[1024];
  ASSERT_TRUE(format_solve_json(s, r, solver::Vec3(1.0, -2.0, 40.0), line, sizeof line));
  EXPECT_STREQ(line,
               "{\"status\": \"converged_gradient\", \"tcp\": [1, -2, 40], \"r\": [-13.3, 6.2, 0.17, 0, 20, -0.5, 1], "
               "\"rms_px\": 0.25, \"iterations\": 7, \"corners_used\": 12}\n");
  s.status = solver::SolveStatus::NonFiniteCorner;
  s.corners_used = 0;
  s.iterations = 0;
  ASSERT_TRUE(format_solve_json(s, r, solver::Vec3::Zero(), line, sizeof line));
  EXPECT_STREQ(line,
               "{\"status\": \"non_finite_corner\", \"tcp\": null, \"r\": null, \"rms_px\": null, \"iterations\": 0, "
               "\"corners_used\": 0}\n");
  char small[16];
  EXPECT_FALSE(format_solve_json(s, r, solver::Vec3::Zero(), small, sizeof small));
  ASSERT_TRUE(format_error_json("a \"quoted\" word", 3, line, sizeof line));
  EXPECT_STREQ(line, "{\"error\": \"a \\\"quoted\\\" word\", \"line\": 3}\n");
  // Input quoted in a message (any bytes): escaped, the line stays JSON.
  ASSERT_TRUE(format_error_json("bad key 'a\\b\tc\xFF'", 4, line, sizeof line));
  EXPECT_STREQ(line, "{\"error\": \"bad key 'a\\\\b\\tc\\ufffd'\", \"line\": 4}\n");
  EXPECT_FALSE(format_error_json("a long message that does not fit", 1, small, sizeof small));
}

TEST(CornersJson, ProjectLineListsTwelveCornersAndTheTcp) {
  const ModelSetup setup = default_setup();
  solver::PoseVector r;
  r << -13.3, 6.2, 0.1745, 0.0, 20.0, 0.3, 0.8;
  solver::CornerSet c;
  setup.instrument.corners(setup.camera, r, c);
  char line[4096];
  ASSERT_TRUE(format_project_json(c, line, sizeof line));
  const std::string text(line);
  EXPECT_EQ(text.rfind("{\"corners\": [[", 0), 0U);
  EXPECT_NE(text.find("\"corners_3d\": [["), std::string::npos);
  EXPECT_NE(text.find("\"tcp\": ["), std::string::npos);
  // Behind the camera: every corner null.
  r[solver::kPsi] = solver::kPi;
  setup.instrument.corners(setup.camera, r, c);
  ASSERT_TRUE(format_project_json(c, line, sizeof line));
  EXPECT_NE(std::string(line).find("\"corners\": [null, null, null, null, null, null, null, null, null, null, null, "
                                   "null]"),
            std::string::npos);
}

// project -> solve round trip through the stream, with malformed lines in
// between: each line gets its own answer and the run goes on.
// Verifies: REQ-ERR-005
TEST(SolveStream, EachLineSolvedIndependentlyAndMalformedLinesReported) {
  const ModelSetup setup = default_setup();
  solver::PoseVector truth;
  truth << -13.3, 6.2, solver::deg_to_rad(10.0), 0.0, 22.0, 0.4, 0.9;
  solver::CornerSet c;
  setup.instrument.corners(setup.camera, truth, c);
  const std::string good = corners_line(c, ", \"prior\": [24, 0.5, 0.75]");
  const std::string no_prior = corners_line(c, "");
  std::FILE* in = std::tmpfile();
  std::FILE* out = std::tmpfile();
  ASSERT_NE(in, nullptr);
  ASSERT_NE(out, nullptr);
  std::fprintf(in, "%s\nnot json\n\n{\"corners\": []}\n%s\n", good.c_str(), no_prior.c_str());
  std::fputs("{\"corners\": [null, null, null, null, null, null, null, null, null, null, null, null]}", in);
  std::rewind(in);
  const double prior[3] = {25.0, 0.3, 0.7};
  const SolveStreamResult result = solve_stream(in, out, setup, solver::SolveMode::Adaptive, prior);
  EXPECT_EQ(result.solved, 3U);
  EXPECT_EQ(result.malformed, 2U);
  const std::string text = read_all(out);
  std::fclose(in);
  std::fclose(out);
  std::size_t lines = 0;
  for (char ch : text) {
    lines += (ch == '\n') ? 1U : 0U;
  }
  EXPECT_EQ(lines, 5U) << text;
  EXPECT_EQ(text.rfind("{\"status\": \"converged_", 0), 0U) << text;
  EXPECT_NE(text.find("\"line\": 2}"), std::string::npos) << text;
  EXPECT_NE(text.find("\"line\": 4}"), std::string::npos) << text;
  EXPECT_NE(text.find("\"status\": \"too_few_corners\", \"tcp\": null"), std::string::npos) << text;
  // The TCP of the first answer is the truth's (mm).
  const auto tcp_at = text.find("\"tcp\": [") + 8;
  double x = 0.0, y = 0.0, z = 0.0;
  ASSERT_EQ(std::sscanf(text.c_str() + tcp_at, "%lf, %lf, %lf", &x, &y, &z), 3);
  EXPECT_NEAR(x, c.tcp.x(), 1e-4);
  EXPECT_NEAR(y, c.tcp.y(), 1e-4);
  EXPECT_NEAR(z, c.tcp.z(), 1e-4);
}

// The shipped PAL camera in OpenCV's FileStorage form gives the estimates
// of its ROS form, to the last digit printed.
TEST(SolveStream, OpenCvAndRosCalibrationsGiveTheSameEstimates) {
  ModelSetup ros;
  ModelSetup opencv;
  ASSERT_TRUE(load_model_setup("test", TCPEST_TEST_DATA_DIR "/../../config/pal_camera.yaml", nullptr, ros));
  ASSERT_TRUE(load_model_setup("test", TCPEST_TEST_DATA_DIR "/../../config/pal_camera_opencv.yaml", nullptr, opencv));
  solver::PoseVector truth;
  truth << -13.3, 6.2, solver::deg_to_rad(10.0), 0.0, 22.0, 0.4, 0.9;
  solver::CornerSet c;
  ros.instrument.corners(ros.camera, truth, c);
  for (std::size_t k = 0; k < c.pixel.size(); ++k) {
    c.pixel[k] += solver::Vec2(0.3 * std::cos(1.7 * static_cast<double>(k)), 0.3 * std::sin(2.3 * static_cast<double>(k)));
  }
  const std::string line = corners_line(c, ", \"prior\": [24, 0.5, 0.75]") + "\n" + corners_line(c, "") + "\n";
  std::string answers[2];
  const ModelSetup* setups[2] = {&ros, &opencv};
  for (int i = 0; i < 2; ++i) {
    std::FILE* in = std::tmpfile();
    std::FILE* out = std::tmpfile();
    ASSERT_NE(in, nullptr);
    ASSERT_NE(out, nullptr);
    std::fputs(line.c_str(), in);
    std::rewind(in);
    const double prior[3] = {25.0, 0.3, 0.7};
    const SolveStreamResult result = solve_stream(in, out, *setups[i], solver::SolveMode::Adaptive, prior);
    EXPECT_EQ(result.solved, 2U);
    answers[i] = read_all(out);
    std::fclose(in);
    std::fclose(out);
  }
  EXPECT_FALSE(answers[0].empty());
  EXPECT_EQ(answers[0], answers[1]);
}

int run(std::initializer_list<const char*> words) {
  char storage[16][128];
  char* argv[16];
  int argc = 0;
  for (const char* w : words) {
    std::snprintf(storage[argc], sizeof storage[argc], "%s", w);
    argv[argc] = storage[argc];
    ++argc;
  }
  int count = 0;
  const Command* table = commands(count);
  for (int i = 0; i < count; ++i) {
    if (std::strcmp(table[i].name, argv[0]) == 0) {
      return table[i].run(argc, argv);
    }
  }
  return -1;
}

// Verifies: REQ-ERR-004
TEST(Commands, UsageErrorsAndHelp) {
  EXPECT_EQ(run({"project", "--help"}), kExitOk);
  EXPECT_EQ(run({"solve", "--help"}), kExitOk);
  EXPECT_EQ(run({"study", "--help"}), kExitOk);
  EXPECT_EQ(run({"project"}), kExitUsage);
  EXPECT_EQ(run({"project", "--r", "1,2,3"}), kExitUsage);
  EXPECT_EQ(run({"project", "--r", "1,2,3,4,5,6,nan"}), kExitUsage);
  EXPECT_EQ(run({"project", "--r", "-13.3,6.2,0.17,0,20,-0.5,1"}), kExitOk);
  EXPECT_EQ(run({"project", "--r=-13.3,6.2,0.17,0,20,-0.5,1"}), kExitOk);
  EXPECT_EQ(run({"project", "--r", "-13.3,6.2,0.17,0,20,-0.5,1", "--calib", "/nonexistent.yaml"}), kExitConfig);
  EXPECT_EQ(run({"solve"}), kExitUsage);
  EXPECT_EQ(run({"solve", "--corners", "/nonexistent.json"}), kExitConfig);
  EXPECT_EQ(run({"solve", "--corners", "x.json", "--prior", "1,2"}), kExitUsage);
  EXPECT_EQ(run({"study"}), kExitUsage);
  EXPECT_EQ(run({"study", "other"}), kExitUsage);
  EXPECT_EQ(run({"study", "play", "--noise", "-1"}), kExitUsage);
  EXPECT_EQ(run({"study", "play", "--seed", "x"}), kExitUsage);
}

TEST(Commands, SolveReadsAFile) {
  const ModelSetup setup = default_setup();
  solver::PoseVector truth;
  truth << -13.3, 6.2, solver::deg_to_rad(10.0), 0.0, 22.0, 0.4, 0.9;
  solver::CornerSet c;
  setup.instrument.corners(setup.camera, truth, c);
  const std::string path = ::testing::TempDir() + "corners.json";
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::fputs(corners_line(c, ", \"prior\": [21, 0.3, 1.0]").c_str(), f);
  std::fclose(f);
  EXPECT_EQ(run({"solve", "--corners", path.c_str()}), kExitOk);
  EXPECT_EQ(run({"solve", "--corners", path.c_str(), "--fixed-model"}), kExitOk);
  f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::fputs("{\"corners\": 5}", f);
  std::fclose(f);
  EXPECT_EQ(run({"solve", "--corners", path.c_str()}), kExitConfig);
}

std::string write_temp(const char* name, const char* text) {
  const std::string path = ::testing::TempDir() + name;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  EXPECT_NE(f, nullptr);
  if (f != nullptr) {
    std::fputs(text, f);
    std::fclose(f);
  }
  return path;
}

// Bad calibration and configuration files are refused at load with exit 3
// (the loaders' own tests check the file/line/field of each message).
// Verifies: REQ-ERR-004
TEST(Commands, RefuseBadCameraAndConfigFiles) {
  const char* head = "image_width: 720\nimage_height: 576\ncamera_matrix:\n  data: ";
  const char* tail = "\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  data: [-0.32, 0.11, 0, 0, 0]\n";
  const std::string zero_focal =
      write_temp("zero_focal.yaml", (std::string(head) + "[0, 0, 359.5, 0, 0, 287.5, 0, 0, 1]" + tail).c_str());
  const std::string singular =
      write_temp("singular.yaml", (std::string(head) + "[400, 0, 359.5, 0, 400, 287.5, 0, 0, 0]" + tail).c_str());
  const std::string good =
      write_temp("good.yaml", (std::string(head) + "[400, 0, 359.5, 0, 400, 287.5, 0, 0, 1]" + tail).c_str());
  const std::string negative = write_temp("negative.yaml", "instrument:\n  bend_length_mm: -18.5\n");
  const std::string fat = write_temp("fat.yaml", "instrument:\n  radius_mm: 12\n");
  const char* r = "--r=-13.3,6.2,0.17,0,20,-0.5,1";
  EXPECT_EQ(run({"project", r, "--calib", good.c_str()}), kExitOk);
  EXPECT_EQ(run({"project", r, "--calib", zero_focal.c_str()}), kExitConfig);
  EXPECT_EQ(run({"project", r, "--calib", singular.c_str()}), kExitConfig);
  EXPECT_EQ(run({"project", r, "--config", negative.c_str()}), kExitConfig);
  EXPECT_EQ(run({"project", r, "--config", fat.c_str()}), kExitConfig);
  EXPECT_EQ(run({"solve", "--corners", "-", "--calib", zero_focal.c_str()}), kExitConfig);
  EXPECT_EQ(run({"study", "play", "--config", fat.c_str()}), kExitConfig);
}

// NaN cannot be written in JSON; out-of-range numbers and corners far
// outside the image reach the solver and get their status.
// Verifies: REQ-ERR-005
TEST(SolveStream, BadCornerValuesGetAStatusLine) {
  const ModelSetup setup = default_setup();
  std::FILE* in = std::tmpfile();
  std::FILE* out = std::tmpfile();
  ASSERT_NE(in, nullptr);
  ASSERT_NE(out, nullptr);
  std::fputs("{\"corners\": [[1e999, 2], [1, 2], [3, 4], [5, 6], null, null, null, null, null, null, null, null]}\n", in);
  std::fputs("{\"corners\": [[5000, 2], [1, 2], [3, 4], [5, 6], null, null, null, null, null, null, null, null]}\n", in);
  std::fputs("{\"corners\": [[NaN, 2], [1, 2], [3, 4], [5, 6], null, null, null, null, null, null, null, null]}\n", in);
  std::rewind(in);
  const double prior[3] = {25.0, 0.0, 0.0};
  const SolveStreamResult result = solve_stream(in, out, setup, solver::SolveMode::Adaptive, prior);
  const std::string text = read_all(out);
  std::fclose(in);
  std::fclose(out);
  EXPECT_EQ(result.solved + result.malformed, 3U) << text;
  EXPECT_NE(text.find("corner_far_outside_image"), std::string::npos) << text;
  EXPECT_NE(text.find("\"line\": 3}"), std::string::npos) << text;  // NaN is not JSON
  // 1e999 is either refused by the reader or reaches the solver as infinity.
  EXPECT_TRUE(text.find("non_finite_corner") != std::string::npos || text.find("\"line\": 1}") != std::string::npos)
      << text;
}

// A prior far outside the model's bounds is refused with its own status
// (it used to come back as converged_step echoing the prior); twelve
// identical corners, fitted only by an instrument pushed far past
// lambda_max, give no estimate.
// Verifies: REQ-SOLVER-005, REQ-ERR-005
TEST(SolveStream, AbsurdPriorAndImpossibleCornersGiveNoEstimate) {
  const ModelSetup setup = default_setup();
  solver::PoseVector truth;
  truth << -13.3, 6.2, solver::deg_to_rad(10.0), 0.0, 22.0, 0.4, 0.9;
  solver::CornerSet c;
  setup.instrument.corners(setup.camera, truth, c);
  const std::string absurd = corners_line(c, ", \"prior\": [30, 1e308, 1e308]");
  const std::string beyond = corners_line(c, ", \"prior\": [61, 0.4, 0.9]");
  std::string same = "{\"corners\": [";
  for (int k = 0; k < solver::kNumCorners; ++k) {
    same += (k == 0) ? "[359.5, 287.5]" : ", [359.5, 287.5]";
  }
  same += "]}";
  std::FILE* in = std::tmpfile();
  std::FILE* out = std::tmpfile();
  ASSERT_NE(in, nullptr);
  ASSERT_NE(out, nullptr);
  std::fprintf(in, "%s\n%s\n%s\n", absurd.c_str(), beyond.c_str(), same.c_str());
  std::rewind(in);
  const double prior[3] = {30.0, 0.0, 0.0};
  const SolveStreamResult result = solve_stream(in, out, setup, solver::SolveMode::Adaptive, prior);
  const std::string text = read_all(out);
  std::fclose(in);
  std::fclose(out);
  EXPECT_EQ(result.solved, 3U) << text;
  EXPECT_EQ(text.find("converged"), std::string::npos) << text;
  EXPECT_EQ(text.find("1e+308"), std::string::npos) << text;
  const std::size_t second = text.find('\n') + 1U;
  EXPECT_EQ(text.rfind("{\"status\": \"start_outside_bounds\", \"tcp\": null, \"r\": null", 0), 0U) << text;
  EXPECT_EQ(text.find("{\"status\": \"start_outside_bounds\", \"tcp\": null", second), second) << text;
  EXPECT_NE(text.find("\"tcp\": null", text.find('\n', second)), std::string::npos) << text;
}

// Verifies: REQ-SOLVER-003
TEST(PlayStudy, OneNoiseLevelGivesConsistentStatistics) {
  const ModelSetup setup = default_setup();
  static PlayStudyResult result;
  const double noise[1] = {1.0};
  ASSERT_TRUE(run_play_study(setup.camera, setup.instrument, 3U, noise, 1, solver::SolverOptions{}, result));
  EXPECT_EQ(result.configurations, 294);
  EXPECT_GT(result.kept, 250);
  ASSERT_EQ(result.rows, 1);
  EXPECT_EQ(result.row[0].adaptive.solves, result.kept);
  EXPECT_GT(result.row[0].adaptive.converged_share, 0.9);
  // Fixed model worse than adaptive on the same features (the study's point).
  EXPECT_GT(result.row[0].fixed_model.rms_mm[2], result.row[0].adaptive.rms_mm[2]);
  const double bad_noise[1] = {-1.0};
  EXPECT_FALSE(run_play_study(setup.camera, setup.instrument, 3U, bad_noise, 1, solver::SolverOptions{}, result));
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
