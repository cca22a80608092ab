// tcpest estimate / evaluate / train-colors on a tiny rendered dataset: exit
// codes, a bad image in the middle of a run, the overlay file, the JSON line,
// several datasets pooled.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.hpp"
#include "cli/setup.hpp"
#include "cli/vision_run.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/render/sidecar.hpp"

namespace tcpest {
namespace cli {
namespace {

int run(std::vector<std::string> words) {
  std::vector<std::vector<char>> storage;
  std::vector<char*> argv;
  for (const std::string& w : words) {
    storage.emplace_back(w.begin(), w.end());
    storage.back().push_back('\0');
  }
  for (auto& s : storage) {
    argv.push_back(s.data());
  }
  int count = 0;
  const Command* table = commands(count);
  for (int i = 0; i < count; ++i) {
    if (std::strcmp(table[i].name, argv[0]) == 0) {
      return table[i].run(static_cast<int>(argv.size()), argv.data());
    }
  }
  return -1;
}

bool exists(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0;
}

// Two rendered frames (PPM) with their sidecars in a fresh directory.
std::string make_dataset(const char* name, std::uint32_t hard_cases = 0U) {
  const std::string dir = ::testing::TempDir() + name;
  mkdir(dir.c_str(), 0755);
  ModelSetup setup;
  EXPECT_TRUE(load_model_setup("test", nullptr, nullptr, setup));
  auto created = render::Renderer::create(setup.camera, setup.instrument, render::RenderSettings{});
  auto renderer = std::move(created.value());
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(setup.camera.width() * setup.camera.height() * 3));
  const MutableImageView out{pixels.data(), setup.camera.width(), setup.camera.height(),
                             static_cast<std::size_t>(setup.camera.width()) * 3U};
  const double joints[2][3] = {{25.0, 0.5, 0.6}, {30.0, -0.3, -0.8}};
  for (int i = 0; i < 2; ++i) {
    render::SceneSpec spec;
    spec.r = setup.instrument.geometry().nominal_pose(joints[i][0], joints[i][1], joints[i][2]);
    spec.seed = static_cast<std::uint64_t>(i + 3);
    spec.hard_cases = hard_cases;
    render::GroundTruth truth;
    EXPECT_TRUE(renderer->render(spec, out, truth).ok());
    char stem[32];
    std::snprintf(stem, sizeof stem, "%04d", i);
    EXPECT_TRUE(render::write_ppm_file(out.view(), (dir + "/" + stem + ".ppm").c_str()).ok());
    render::Sidecar sidecar = render::make_sidecar(truth, spec, render::RenderSettings{}, setup.camera.width(),
                                                   setup.camera.height());
    std::snprintf(sidecar.image, sizeof sidecar.image, "%s.ppm", stem);
    sidecar.has_prior = true;
    sidecar.prior = {{joints[i][0], joints[i][1], joints[i][2]}};
    EXPECT_TRUE(render::write_sidecar_file((dir + "/" + stem + ".json").c_str(), sidecar));
  }
  return dir;
}

// Verifies: REQ-ERR-004
TEST(VisionCommands, UsageErrorsAndHelp) {
  EXPECT_EQ(run({"estimate", "--help"}), kExitOk);
  EXPECT_EQ(run({"evaluate", "--help"}), kExitOk);
  EXPECT_EQ(run({"train-colors", "--help"}), kExitOk);
  EXPECT_EQ(run({"estimate"}), kExitUsage);
  EXPECT_EQ(run({"estimate", "--prior", "1,2", "x.jpg"}), kExitUsage);
  EXPECT_EQ(run({"estimate", "--colors", "/nonexistent.json", "x.jpg"}), kExitConfig);
  EXPECT_EQ(run({"evaluate"}), kExitUsage);
  EXPECT_EQ(run({"evaluate", "/nonexistent-dir"}), kExitConfig);
  EXPECT_EQ(run({"train-colors"}), kExitUsage);
  EXPECT_EQ(run({"estimate", "--guided-rounds", "5", "x.jpg"}), kExitUsage);
  // The option of the fallback seeds that were removed (docs/decisions/0053) is unknown.
  EXPECT_EQ(run({"estimate", "--fallback-seeds", "1", "x.jpg"}), kExitUsage);
  EXPECT_EQ(run({"evaluate", "--fallback-seeds", "1", "/tmp"}), kExitUsage);
  // A bad value is a usage error whatever the directory holds (before, an
  // empty or missing one answered first, with the configuration's code).
  EXPECT_EQ(run({"evaluate", "--guided-rounds", "9", "/nonexistent-dir"}), kExitUsage);
}

// Verifies: REQ-ERR-006
TEST(VisionCommands, EstimateGoesOnAfterABadImageAndWritesOverlays) {
  const std::string dir = make_dataset("vision_cli_estimate");
  const std::string bad = dir + "/corrupt.jpg";
  std::FILE* f = std::fopen(bad.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::fputs("\xff\xd8 not really a jpeg", f);
  std::fclose(f);
  // The bad image in the middle: the run goes on, and reports failure.
  EXPECT_EQ(run({"estimate", "--json", "--overlay", dir, dir + "/0000.ppm", bad, dir + "/0001.ppm"}), kExitFailure);
  EXPECT_TRUE(exists(dir + "/0000.ppm.overlay.jpg"));
  EXPECT_TRUE(exists(dir + "/0001.ppm.overlay.jpg"));
  EXPECT_EQ(run({"estimate", "--prior", "25,0.5,0.6", "--fixed-model", dir + "/0000.ppm"}), kExitOk);
}

TEST(VisionCommands, EvaluateAndTrainColorsOnARenderedDataset) {
  const std::string dir = make_dataset("vision_cli_evaluate");
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", dir}), kExitOk);
  const std::string summary = testing::internal::GetCapturedStdout();
  // The summary reports the valid estimates and, apart, the degraded ones
  // (the robot receives those too, flagged).
  EXPECT_NE(summary.find("valid estimates: "), std::string::npos) << summary;
  EXPECT_NE(summary.find("degraded estimates: "), std::string::npos) << summary;
  EXPECT_NE(summary.find("over 5 mm: "), std::string::npos) << summary;
  // ... and on the same frames the TCP of the pose the corners were read at.
  EXPECT_NE(summary.find("the image fit's pose instead ("), std::string::npos) << summary;
  EXPECT_EQ(summary.find("the image fit's pose instead (0 of the valid"), std::string::npos) << summary;
  // ... with its valid frames' count beyond 3 mm, as the solve's (docs/results.md compares the two).
  const std::size_t fit_line = summary.find("the image fit's pose instead (");
  const std::string fit_text = summary.substr(fit_line, summary.find('\n', fit_line) - fit_line);
  EXPECT_NE(fit_text.find(" mm, over 3 mm: "), std::string::npos) << fit_text;
  // One line per row of the estimation policy, in the table's order: the
  // frames it ran on, and those whose estimate it gave.
  std::size_t at = 0U;
  for (const vision::PolicyStep& row : vision::kEstimationPolicy) {
    const std::string line = std::string("policy row ") + row.name + ": ran on ";
    const std::size_t found = summary.find(line, at);
    ASSERT_NE(found, std::string::npos) << line << summary;
    at = found;
  }
  EXPECT_NE(summary.find("policy row stage4-solve: ran on 2 frames"), std::string::npos) << summary;
  EXPECT_EQ(run({"evaluate", "--no-prior", "--max", "1", dir}), kExitOk);
  EXPECT_EQ(run({"evaluate", "--true-prior", "--max", "1", dir}), kExitOk);
  EXPECT_EQ(run({"evaluate", "--true-prior", "--no-prior", dir}), kExitUsage);
  // Without a model-guided round there is no image fit's pose to compare.
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", "--guided-rounds", "0", dir}), kExitOk);
  const std::string unguided = testing::internal::GetCapturedStdout();
  EXPECT_NE(unguided.find("the image fit's pose instead (0 of the valid, 0 of the degraded"), std::string::npos)
      << unguided;
  const std::string model = dir + "/colors.json";
  ASSERT_EQ(run({"train-colors", "--sidecars", dir, "--out", model}), kExitOk);
  // The trained model is readable and close to the shipped one.
  vision::ColorModel trained;
  ASSERT_TRUE(load_color_model("test", model.c_str(), trained));
  const vision::ColorModel shipped = vision::default_color_model();
  EXPECT_NEAR(trained.blue.mean_b, shipped.blue.mean_b, 10.0);
  EXPECT_NEAR(trained.yellow.mean_b, shipped.yellow.mean_b, 10.0);
  EXPECT_EQ(run({"evaluate", "--colors", model, dir}), kExitOk);
}

// Several datasets are pooled into one score, with a frame-success line per
// dataset; the corner rows then name each image with its directory (the
// same names recur); every directory is checked before any image is run.
TEST(VisionCommands, EvaluatePoolsSeveralDatasets) {
  const std::string first = make_dataset("vision_cli_pool_a");
  const std::string second = make_dataset("vision_cli_pool_b");
  const std::string csv = first + "/corners.csv";
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", "--corners-csv", csv, first, second}), kExitOk);
  const std::string summary = testing::internal::GetCapturedStdout();
  EXPECT_NE(summary.find("dataset " + first + ": frame success "), std::string::npos) << summary;
  EXPECT_NE(summary.find("dataset " + second + ": frame success "), std::string::npos) << summary;
  EXPECT_NE(summary.find("pooled over 2 datasets: 4 images scored (0 unreadable)"), std::string::npos) << summary;
  std::FILE* f = std::fopen(csv.c_str(), "r");
  ASSERT_NE(f, nullptr);
  std::string rows;
  char line[512];
  while (std::fgets(line, sizeof line, f) != nullptr) {
    rows += line;
  }
  std::fclose(f);
  EXPECT_NE(rows.find("\n" + first + "/0000.ppm,0,"), std::string::npos);
  EXPECT_NE(rows.find("\n" + second + "/0001.ppm,11,"), std::string::npos);
  // --max counts the pooled images; --verbose names them as the rows do.
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", "--max", "3", "--verbose", first, second}), kExitOk);
  const std::string limited = testing::internal::GetCapturedStdout();
  EXPECT_NE(limited.find("pooled over 2 datasets: 3 images scored"), std::string::npos) << limited;
  EXPECT_NE(limited.find(second + "/0000.ppm: "), std::string::npos) << limited;
  EXPECT_EQ(limited.find(second + "/0001.ppm: "), std::string::npos) << limited;
  // Each line gives the image fit's pose's TCP error beside the solve's.
  EXPECT_NE(limited.find(" mm (image fit's pose "), std::string::npos) << limited;
  // A directory that cannot be read fails the run before any image is.
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", first, "/nonexistent-dir"}), kExitConfig);
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
}

namespace {

// The "frames not succeeding" line that a --corners-csv file implies: per
// image, the visible corners, those found within 1.5 px, those reported
// at all, and the estimate's status; a frame fails below 80 % found.
std::string failing_line_from_rows(const std::string& csv) {
  struct Frame {
    int visible = 0;
    int found_ok = 0;
    int reported = 0;
    std::string status;
  };
  std::vector<std::pair<std::string, Frame>> frames;
  std::FILE* f = std::fopen(csv.c_str(), "r");
  EXPECT_NE(f, nullptr);
  if (f == nullptr) {
    return "";
  }
  char line[512];
  bool header = true;
  while (std::fgets(line, sizeof line, f) != nullptr) {
    if (header) {
      header = false;
      continue;
    }
    // image,k,visible,truth_u,truth_v,found,u,v,confidence,error_px,status,...
    std::vector<std::string> fields;
    std::string field;
    for (const char* c = line; *c != '\0' && *c != '\n'; ++c) {
      if (*c == ',') {
        fields.push_back(field);
        field.clear();
      } else {
        field += *c;
      }
    }
    fields.push_back(field);
    EXPECT_GE(fields.size(), 11U);
    if (fields.size() < 11U) {
      break;
    }
    if (frames.empty() || frames.back().first != fields[0]) {
      frames.emplace_back(fields[0], Frame{});
    }
    Frame& frame = frames.back().second;
    const bool visible = fields[2] == "1";
    const bool found = fields[5] == "1";
    frame.visible += visible ? 1 : 0;
    frame.reported += found ? 1 : 0;
    frame.found_ok += visible && found && std::strtod(fields[9].c_str(), nullptr) <= 1.5 ? 1 : 0;
    frame.status = fields[10];
  }
  std::fclose(f);
  int failing = 0, none = 0, none_no_corner = 0, degraded = 0, valid = 0;
  for (const auto& named : frames) {
    const Frame& frame = named.second;
    if (frame.visible == 0 || frame.found_ok * 10 >= frame.visible * 8) {
      continue;
    }
    ++failing;
    none += frame.status == "none" ? 1 : 0;
    none_no_corner += frame.status == "none" && frame.reported == 0 ? 1 : 0;
    degraded += frame.status == "degraded" ? 1 : 0;
    valid += frame.status == "valid" ? 1 : 0;
  }
  char out[160];
  std::snprintf(out, sizeof out,
                "frames not succeeding: %d (no estimate %d, of which %d report no corner; degraded %d; valid %d)\n",
                failing, none, none_no_corner, degraded, valid);
  return out;
}

}  // namespace

// evaluate counts the frames that do not succeed by the estimate's status,
// and among those without a pose the ones with no corner at all: the same
// counts as the corner rows give, with guided rounds and with stage 4's
// corners alone (most frames fail there).
TEST(VisionCommands, EvaluateCountsTheFramesThatDoNotSucceedByStatus) {
  const std::string lab = make_dataset("vision_cli_failing_lab");
  const std::string hard =
      make_dataset("vision_cli_failing_hard", render::kHardOccluder | render::kHardMotionBlur | render::kHardHaze);
  const std::string csv = lab + "/failing.csv";
  for (const bool guided : {true, false}) {
    testing::internal::CaptureStdout();
    EXPECT_EQ(run({"evaluate", "--corners-csv", csv, "--guided-rounds", guided ? "1" : "0", lab, hard}), kExitOk);
    const std::string summary = testing::internal::GetCapturedStdout();
    const std::string expected = failing_line_from_rows(csv);
    EXPECT_NE(summary.find(expected), std::string::npos) << expected << summary;
    if (!guided) {
      EXPECT_EQ(expected.find("frames not succeeding: 0 "), std::string::npos) << expected;
    }
  }
}

// With sidecars that carry the motion blur's streak, evaluate reports how
// well the image fit read it; without blur there is no such line.
TEST(VisionCommands, EvaluateReportsTheStreakReadingUnderMotionBlur) {
  const std::string blurred = make_dataset("vision_cli_blur", render::kHardMotionBlur);
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", blurred}), kExitOk);
  const std::string summary = testing::internal::GetCapturedStdout();
  EXPECT_NE(summary.find("motion-blur streak read on "), std::string::npos) << summary;
  EXPECT_NE(summary.find(" of 2 blurred frames (length error median "), std::string::npos) << summary;
  EXPECT_NE(summary.find(") and on 0 of 0 others"), std::string::npos) << summary;
  const std::string sharp = make_dataset("vision_cli_sharp");
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", sharp}), kExitOk);
  const std::string plain = testing::internal::GetCapturedStdout();
  EXPECT_EQ(plain.find("motion-blur streak"), std::string::npos) << plain;
}

// A line written into a buffer too short for it keeps what fits, terminated.
template <typename Tally>
void expect_short_buffer_keeps_the_start(void (*format)(const Tally&, char*, std::size_t) noexcept,
                                         const Tally& tally, const char* line) {
  char small[20];
  format(tally, small, sizeof small);
  EXPECT_EQ(std::strlen(small), sizeof small - 1U);
  EXPECT_EQ(std::strncmp(small, line, sizeof small - 1U), 0);
}

// evaluate's line of frame success per hard case: a frame counts under each
// of its cases; no line for a set without hard cases; a short buffer keeps
// what fits.
TEST(VisionCommands, EvaluateTalliesFrameSuccessPerHardCase) {
  HardCaseTally tally;
  char line[512];
  tally.add(0U, true);
  format_hard_case_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "");
  tally.add(render::kHardOccluder | render::kHardHaze, false);
  tally.add(render::kHardOccluder, true);
  format_hard_case_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "frame success by hard case: occluder 50.0 % of 2, haze 0.0 % of 1, none 100.0 % of 1");
  expect_short_buffer_keeps_the_start(format_hard_case_tally, tally, line);
}

TEST(VisionCommands, EvaluateTalliesFrameSuccessByVisibleCorners) {
  VisibleCornersTally tally;
  char line[512];
  format_visible_corners_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "");
  tally.add(0, true);  // no visible corner: not counted
  format_visible_corners_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "");
  for (const int visible : {1, 3, 4, 7, 8, 12}) {
    tally.add(visible, visible != 3);
  }
  tally.add(12, false);
  format_visible_corners_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "frame success by visible corners: 1-3 50.0 % of 2, 4-5 100.0 % of 1, 6-7 100.0 % of 1, "
                     "8-12 66.7 % of 3");
  expect_short_buffer_keeps_the_start(format_visible_corners_tally, tally, line);
}

// evaluate's line of frame success by the truth's insertion: 5 mm bins on
// model.md's grid, a lambda beyond it in the end bin, a non-finite one left
// out, empty bins not printed.
TEST(VisionCommands, EvaluateTalliesFrameSuccessByInsertion) {
  InsertionTally tally;
  char line[512];
  format_insertion_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "");
  tally.add(std::numeric_limits<double>::quiet_NaN(), true);
  format_insertion_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "");
  tally.add(10.0, true);
  tally.add(12.4, false);   // the 10 mm bin
  tally.add(12.6, true);    // the 15 mm bin
  tally.add(3.0, true);     // below the grid: the first bin
  tally.add(40.0, false);
  tally.add(55.0, true);    // beyond it: the last
  format_insertion_tally(tally, line, sizeof line);
  EXPECT_STREQ(line, "frame success by insertion (mm): 10 66.7 % of 3, 15 100.0 % of 1, 40 50.0 % of 2");
  expect_short_buffer_keeps_the_start(format_insertion_tally, tally, line);
}

// The image shows the shape, not which of the equivalent joints, (phi,
// theta), (phi + pi, -theta) or phi + 2 pi n, the robot holds: the estimate
// reports the prior's (what JOINTS sends and the encoders compare with).
// Lab seed 1 frame 188 (true phi 0, theta -0.35 rad; encoders 0.09, -0.17)
// is one whose solve ended on the other turn (phi -3.26, theta 0.31).
// Verifies: REQ-MODEL-004
TEST(VisionCommands, EstimateReportsTheJointsInThePriorsRepresentation) {
  const std::string dir = ::testing::TempDir() + "vision_cli_joints";
  ASSERT_EQ(run({"render", "--set", "lab", "--seed", "1", "--start", "188", "--n", "1", "--quiet", "--out", dir}),
            kExitOk);
  const auto sidecar = render::read_sidecar_file((dir + "/0188.json").c_str());
  ASSERT_TRUE(sidecar.ok());
  ASSERT_TRUE(sidecar.value().has_prior);
  ModelSetup setup;
  ASSERT_TRUE(load_model_setup("test", nullptr, nullptr, setup));
  EstimatePipeline pipeline;
  ASSERT_TRUE(pipeline.init("test", setup, vision::default_color_model(), loop::LoopConfig{}));
  ImageReader reader;
  ASSERT_TRUE(reader.init(setup.camera.width(), setup.camera.height()));
  std::vector<std::uint8_t> pixels;
  ImageView view{};
  char error[256];
  ASSERT_TRUE(reader.read((dir + "/0188.jpg").c_str(), pixels, view, error, sizeof error)) << error;
  const std::array<double, 3>& encoders = sidecar.value().prior;
  const double priors[3][3] = {{encoders[0], encoders[1], encoders[2]},
                               {encoders[0], encoders[1] + solver::kPi, -encoders[2]},
                               {encoders[0], encoders[1] - 4.0 * solver::kPi, encoders[2]}};
  solver::Vec3 first_tcp = solver::Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    pipeline.reset_sequence();
    const EstimateResult result = pipeline.process(view, priors[i]);
    ASSERT_NE(result.status, solver::EstimateQuality::None) << i;
    EXPECT_NEAR(result.r[solver::kPhi], priors[i][1], 0.3) << i;
    EXPECT_NEAR(result.r[solver::kTheta], priors[i][2], 0.3) << i;
    if (i == 0) {
      first_tcp = result.tcp;
    } else {
      EXPECT_NEAR((result.tcp - first_tcp).norm(), 0.0, 0.05) << i;  // the same instrument
    }
  }
}

// An extraction with corner k found at `pixel`, and nothing else.
vision::Extraction one_corner(std::size_t k, vision::Point pixel, double confidence = 0.9) {
  vision::Extraction extraction;
  extraction.corners[k].found = true;
  extraction.corners[k].pixel = pixel;
  extraction.corners[k].confidence = confidence;
  return extraction;
}

TEST(VisionCommands, EstimateJsonLineHasEveryMember) {
  EstimateResult result;
  const vision::Extraction extraction = one_corner(3U, vision::Point{12.5, 40.25});
  result.extraction_ok = true;
  char line[4096];
  format_estimate_json("a \"quoted\" name.jpg", result, extraction, line, sizeof line);
  const std::string s(line);
  for (const char* key : {"\"image\": \"a \\\"quoted\\\" name.jpg\"", "\"status\": \"none\"", "\"tcp\": null",
                          "\"r\": null", "\"corners\": [null, null, null, [12.500, 40.250], null",
                          "\"corner_confidence\": [null, null, null, 0.90, null", "\"rms_px\"",
                          "\"iterations\"", "\"time_us\""}) {
    EXPECT_NE(s.find(key), std::string::npos) << key << " in " << s;
  }
}

// A corner's confidence travels with it: null exactly where its position is.
TEST(VisionCommands, EstimateJsonGivesAConfidenceWithEachReportedCorner) {
  vision::Extraction extraction = one_corner(11U, vision::Point{3.0, 4.0}, 0.5);
  extraction.corners[2].found = true;
  extraction.corners[2].confidence = 0.9;
  struct Case {
    bool extraction_ok;  // false: this frame's extraction failed and no round re-measured the corners
    const char* expected;
  };
  const Case cases[] = {
      {false, "\"corner_confidence\": [null, null, null, null, null, null, null, null, null, null, null, null]"},
      {true, "\"corner_confidence\": [null, null, 0.90, null, null, null, null, null, null, null, null, 0.50]"},
  };
  for (const Case& c : cases) {
    EstimateResult result;
    result.extraction_ok = c.extraction_ok;
    char line[4096];
    format_estimate_json("x.jpg", result, extraction, line, sizeof line);
    EXPECT_NE(std::string(line).find(c.expected), std::string::npos) << line;
  }
}

// Corners are reported when stages 1-4 found them, or when the guided
// rounds re-measured them after a failed stage 3 or 4 (the estimate was
// solved from them); never otherwise.
TEST(VisionCommands, CornersAreReportedWhenFoundThisFrame) {
  EstimateResult result;
  vision::Extraction extraction = one_corner(0U, vision::Point{7.0, 9.5});
  result.extraction_ok = false;
  EXPECT_FALSE(corner_reported(result, extraction, 0U));
  extraction.refined = true;
  EXPECT_TRUE(corner_reported(result, extraction, 0U));
  EXPECT_FALSE(corner_reported(result, extraction, 1U));  // not found
  EXPECT_FALSE(corner_reported(result, extraction, static_cast<std::size_t>(solver::kNumCorners)));
  char line[4096];
  format_estimate_json("x.jpg", result, extraction, line, sizeof line);
  EXPECT_NE(std::string(line).find("\"corners\": [[7.000, 9.500], null"), std::string::npos) << line;
  extraction.refined = false;
  result.extraction_ok = true;
  EXPECT_TRUE(corner_reported(result, extraction, 0U));
}

// The corners measured on the image: all of stage 4's; after a guided
// round only those above the predicted corners' confidence.
TEST(VisionCommands, MeasuredCornersLeaveOutThePredictedOnes) {
  const vision::ExtractorConfig config;
  vision::Extraction e = one_corner(0U, vision::Point{1.0, 2.0}, 0.9);
  e.corners[1].found = true;
  e.corners[1].confidence = 0.46;  // stage 4's, low but read
  EXPECT_EQ(measured_corner_count(e, config), 2);
  e.refined = true;
  e.corners[1].confidence = config.refiner.refine_predicted_confidence;
  e.corners[2].found = true;
  e.corners[2].confidence = config.refiner.refine_predicted_confidence;
  EXPECT_EQ(measured_corner_count(e, config), 1);
  e.corners[0].found = false;
  EXPECT_EQ(measured_corner_count(e, config), 0);
}

// The dense stage's rule: on every frame where the pipeline's image fit
// read a motion streak (unless turned off); otherwise on a valid estimate
// where at most max_measured_corners_valid corners were measured, and on
// the others where at most max_measured_corners were, or where the
// encoders contradict the estimate (there it would end none) unless that
// is turned off. By default: every frame not valid, and the valid ones
// from 7 corners measured or fewer.
TEST(VisionCommands, DenseStageAppliesWhereFewCornersWereMeasuredTheEncodersDisagreeOrAStreakWasRead) {
  using Q = solver::EstimateQuality;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  vision::DenseOptions options;
  ASSERT_TRUE(options.run_when_encoders_disagree);
  ASSERT_TRUE(options.run_where_streak_read);
  for (const double no_streak_px : {0.0, vision::DenseFit::kMinStreakPx, nan}) {
    for (int measured = 0; measured <= vision::kNumCorners; ++measured) {
      EXPECT_TRUE(dense_stage_applies(Q::Degraded, measured, false, no_streak_px, options)) << measured;
      EXPECT_TRUE(dense_stage_applies(Q::None, measured, false, no_streak_px, options)) << measured;
      EXPECT_EQ(dense_stage_applies(Q::Valid, measured, false, no_streak_px, options), measured <= 7) << measured;
      EXPECT_EQ(dense_stage_applies(Q::Valid, measured, true, no_streak_px, options), measured <= 7) << measured;
    }
  }
  options.max_measured_corners = 2;
  options.max_measured_corners_valid = -1;
  for (const double no_streak_px : {0.0, vision::DenseFit::kMinStreakPx, nan}) {
    EXPECT_FALSE(dense_stage_applies(Q::Valid, 0, true, no_streak_px, options));
    EXPECT_FALSE(dense_stage_applies(Q::Valid, 0, false, no_streak_px, options));
    for (const Q q : {Q::Degraded, Q::None}) {
      EXPECT_TRUE(dense_stage_applies(q, 0, false, no_streak_px, options));
      EXPECT_TRUE(dense_stage_applies(q, 2, false, no_streak_px, options));
      EXPECT_FALSE(dense_stage_applies(q, 3, false, no_streak_px, options));
      EXPECT_TRUE(dense_stage_applies(q, 3, true, no_streak_px, options));
      EXPECT_TRUE(dense_stage_applies(q, 12, true, no_streak_px, options));
    }
  }
  // A streak read: whatever the estimate and the corners measured.
  for (const Q q : {Q::Valid, Q::Degraded, Q::None}) {
    EXPECT_TRUE(dense_stage_applies(q, 12, false, 1.5, options));
  }
  options.run_where_streak_read = false;
  EXPECT_FALSE(dense_stage_applies(Q::Valid, 12, false, 9.0, options));
  EXPECT_FALSE(dense_stage_applies(Q::Degraded, 12, false, 9.0, options));
  options.run_when_encoders_disagree = false;
  EXPECT_FALSE(dense_stage_applies(Q::Degraded, 3, true, 0.0, options));
  EXPECT_TRUE(dense_stage_applies(Q::Degraded, 2, true, 0.0, options));
  options.max_measured_corners_valid = 3;
  EXPECT_TRUE(dense_stage_applies(Q::Valid, 3, false, 0.0, options));
  EXPECT_FALSE(dense_stage_applies(Q::Valid, 4, false, 0.0, options));
}

// What the dense stage keeps is degraded, except where it replaced a
// valid estimate, its own solve is valid and the TCP moved within
// max_valid_tcp_change_mm; a failed solve stays none.
TEST(VisionCommands, DenseStageKeepsValidOnlyWhereItAgreesWithAValidEstimate) {
  using Q = solver::EstimateQuality;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  vision::DenseOptions options;
  ASSERT_EQ(options.max_valid_tcp_change_mm, 2.0);
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::Valid, 0.0, options), Q::Valid);
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::Valid, 2.0, options), Q::Valid);
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::Valid, 2.01, options), Q::Degraded);
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::Valid, nan, options), Q::Degraded);
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::Degraded, 0.0, options), Q::Degraded);
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::None, 0.0, options), Q::None);
  for (const Q replaced : {Q::Degraded, Q::None}) {
    EXPECT_EQ(dense_kept_quality(replaced, Q::Valid, 0.0, options), Q::Degraded);
    EXPECT_EQ(dense_kept_quality(replaced, Q::Degraded, 0.0, options), Q::Degraded);
    EXPECT_EQ(dense_kept_quality(replaced, Q::None, 0.0, options), Q::None);
  }
  options.max_valid_tcp_change_mm = 0.0;  // nothing the stage keeps is valid
  EXPECT_EQ(dense_kept_quality(Q::Valid, Q::Valid, 0.0, options), Q::Degraded);
}

// Two pipelines on the test setup, the second to get the dense stage.
class DensePipelines : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(load_model_setup("test", nullptr, nullptr, setup));
    plain.reset(new EstimatePipeline());
    dense.reset(new EstimatePipeline());
    ASSERT_TRUE(plain->init("test", setup, vision::default_color_model(), loop::LoopConfig{}));
    ASSERT_TRUE(dense->init("test", setup, vision::default_color_model(), loop::LoopConfig{}));
    auto created = render::Renderer::create(setup.camera, setup.instrument, render::RenderSettings{});
    ASSERT_TRUE(created.ok());
    renderer = std::move(created.value());
    pixels.assign(static_cast<std::size_t>(setup.camera.width() * setup.camera.height() * 3), 0U);
  }
  // The frame the tests render into.
  MutableImageView frame() {
    return MutableImageView{pixels.data(), setup.camera.width(), setup.camera.height(),
                            static_cast<std::size_t>(setup.camera.width()) * 3U};
  }
  // Renders into `out` the first of a few blurred scenes the plain
  // pipeline makes valid with its streak read (most are), its result in
  // `before`; false: none of them.
  bool render_blurred_valid_frame(const MutableImageView& out, render::SceneSpec& spec, EstimateResult& before) {
    render::GroundTruth truth;
    for (std::uint64_t seed = 21U; seed < 29U; ++seed) {
      spec.r = setup.instrument.geometry().nominal_pose(26.0, 0.3, 0.6);
      spec.seed = seed;
      spec.hard_cases = render::kHardMotionBlur;
      if (!renderer->render(spec, out, truth).ok()) {
        return false;
      }
      plain->reset_sequence();
      before = plain->process(out.view(), nullptr);
      if (before.status == solver::EstimateQuality::Valid && before.streak_px.norm() > vision::DenseFit::kMinStreakPx) {
        return true;
      }
    }
    return false;
  }
  ModelSetup setup;
  std::unique_ptr<EstimatePipeline> plain;
  std::unique_ptr<EstimatePipeline> dense;
  std::unique_ptr<render::Renderer> renderer;
  std::vector<std::uint8_t> pixels;
};

// The dense stage's defaults on small work images with few iterations:
// seconds per frame rather than minutes.
vision::DenseOptions quick_dense_options() {
  vision::DenseOptions options;
  options.coarse_pixels = 3000;
  options.fine_pixels = 8000;
  options.coarse_iterations = 6;
  options.fine_iterations = 8;
  return options;
}

// A blurred frame the pipeline makes valid, its streak read: the dense
// stage runs there too, and its estimate stays valid only where it agrees
// with the pipeline's. The temporal track follows the pipeline's own
// results: a sharp frame after it gives the same result with the stage
// as without.
TEST_F(DensePipelines, RunsWhereAStreakWasReadAndLeavesTheTrackToThePipeline) {
  const vision::DenseOptions options = quick_dense_options();
  ASSERT_TRUE(options.run_where_streak_read);
  ASSERT_TRUE(dense->enable_dense(options));
  const MutableImageView out = frame();
  render::SceneSpec spec;
  EstimateResult before;
  ASSERT_TRUE(render_blurred_valid_frame(out, spec, before));
  const EstimateResult after = dense->process(out.view(), nullptr);
  EXPECT_TRUE(after.dense_ran);
  if (after.dense_kept) {
    const bool agree = (after.tcp - before.tcp).norm() <= options.max_valid_tcp_change_mm;
    EXPECT_TRUE(after.status == solver::EstimateQuality::Degraded || (after.status == solver::EstimateQuality::Valid && agree));
  } else {
    EXPECT_EQ(after.status, before.status);
  }
  // The next frame, sharp: the same priors in both, so the same result.
  spec.r = setup.instrument.geometry().nominal_pose(26.5, 0.32, 0.62);
  spec.seed = 22U;
  spec.hard_cases = 0U;
  render::GroundTruth truth;
  ASSERT_TRUE(renderer->render(spec, out, truth).ok());
  const EstimateResult next_plain = plain->process(out.view(), nullptr);
  const EstimateResult next_dense = dense->process(out.view(), nullptr);
  ASSERT_FALSE(next_dense.dense_ran);
  EXPECT_EQ(next_dense.status, next_plain.status);
  EXPECT_EQ((next_dense.r - next_plain.r).norm(), 0.0);
}

// The encoders reach the dense stage: given them, its fits are held
// within their box (DenseOptions::encoder_box_*), so that encoders wrong
// by more than their accuracy (theta 0.45 rad off the frame's, the box
// 0.2 rad) move what it reports; without them there is no box, and the
// stage with the box and the one without report the same.
TEST_F(DensePipelines, HoldsItsFitsWithinTheEncodersBoxWhenTheyAreGiven) {
  vision::DenseOptions options = quick_dense_options();
  ASSERT_GT(options.encoder_box_angle_rad, 0.0);
  ASSERT_TRUE(dense->enable_dense(options));
  std::unique_ptr<EstimatePipeline> unboxed(new EstimatePipeline());
  ASSERT_TRUE(unboxed->init("test", setup, vision::default_color_model(), loop::LoopConfig{}));
  options.encoder_box_lambda_mm = 0.0;
  ASSERT_TRUE(unboxed->enable_dense(options));
  const MutableImageView out = frame();
  render::SceneSpec spec;
  EstimateResult before;
  ASSERT_TRUE(render_blurred_valid_frame(out, spec, before));  // the stage runs on it, the streak read
  const auto largest_corner_change_px = [&]() {
    const auto& a = dense->extractor().result().corners;
    const auto& b = unboxed->extractor().result().corners;
    double largest = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
      if (a[k].found != b[k].found) {
        return std::numeric_limits<double>::infinity();
      }
      if (a[k].found) {
        largest = std::max(largest, std::hypot(a[k].pixel.x - b[k].pixel.x, a[k].pixel.y - b[k].pixel.y));
      }
    }
    return largest;
  };
  const EstimateResult boxed_free = dense->process(out.view(), nullptr);
  const EstimateResult unboxed_free = unboxed->process(out.view(), nullptr);
  ASSERT_TRUE(boxed_free.dense_ran);
  ASSERT_TRUE(unboxed_free.dense_ran);
  EXPECT_EQ(largest_corner_change_px(), 0.0);
  const double wrong_encoders[3] = {26.0, 0.3, 0.6 - 0.45};
  dense->reset_sequence();
  unboxed->reset_sequence();
  const EstimateResult boxed = dense->process(out.view(), wrong_encoders);
  const EstimateResult free = unboxed->process(out.view(), wrong_encoders);
  ASSERT_TRUE(boxed.dense_ran);
  ASSERT_TRUE(free.dense_ran);
  EXPECT_GT(largest_corner_change_px(), 1.0);
}

// What the dense stage reports is its corners blended with the
// pipeline's: each corner both report within the gate moves the weight's
// share of the way to the pipeline's, and the others are the stage's own
// (vision::blend_pipeline_corners, wired between the stage and its solve).
TEST_F(DensePipelines, ReportsItsCornersBlendedWithThePipelines) {
  vision::DenseOptions options = quick_dense_options();
  ASSERT_GT(options.pipeline_corner_weight, 0.0);
  ASSERT_TRUE(dense->enable_dense(options));
  std::unique_ptr<EstimatePipeline> unblended(new EstimatePipeline());
  ASSERT_TRUE(unblended->init("test", setup, vision::default_color_model(), loop::LoopConfig{}));
  options.pipeline_corner_weight = 0.0;
  ASSERT_TRUE(unblended->enable_dense(options));
  const MutableImageView out = frame();
  // A blurred frame the pipeline makes valid with its streak read: the
  // stage runs there, and the pipeline reports corners to blend with.
  render::SceneSpec spec;
  EstimateResult before;
  ASSERT_TRUE(render_blurred_valid_frame(out, spec, before));
  const EstimateResult after = dense->process(out.view(), nullptr);
  const EstimateResult alone = unblended->process(out.view(), nullptr);
  ASSERT_TRUE(after.dense_kept);
  ASSERT_TRUE(alone.dense_kept);
  const auto& pipeline_corners = plain->extractor().result().corners;
  const auto& stage_corners = unblended->extractor().result().corners;
  const auto& reported = dense->extractor().result().corners;
  const double w = quick_dense_options().pipeline_corner_weight;
  const double gate_px = quick_dense_options().pipeline_corner_gate_px;
  int blended = 0;
  for (std::size_t k = 0; k < reported.size(); ++k) {
    ASSERT_EQ(reported[k].found, stage_corners[k].found) << k;
    if (!reported[k].found) {
      continue;
    }
    const vision::Point& d = stage_corners[k].pixel;
    const vision::Point& p = pipeline_corners[k].pixel;
    const bool within = pipeline_corners[k].found && std::hypot(p.x - d.x, p.y - d.y) < gate_px;
    const double ex = within ? d.x + w * (p.x - d.x) : d.x;
    const double ey = within ? d.y + w * (p.y - d.y) : d.y;
    EXPECT_NEAR(reported[k].pixel.x, ex, 1e-9) << k;
    EXPECT_NEAR(reported[k].pixel.y, ey, 1e-9) << k;
    blended += within ? 1 : 0;
  }
  EXPECT_GE(blended, 1);
}

// --dense: the dense stage runs on the frames the pipeline leaves without
// a valid estimate, on the valid ones where it measured at most 7 corners
// and on those where it read a motion streak; what it keeps is reported
// degraded, or valid where it replaced a valid estimate and agrees with
// it; the other frames are left as they are. Out-of-range options are
// refused; evaluate reports the stage's frames.
TEST_F(DensePipelines, RunsOnFramesNotValidOrBlurredAndLeavesTheOthers) {
  vision::DenseOptions options;
  options.fine_pixels = 100;  // below the smallest work image
  EXPECT_FALSE(dense->enable_dense(options));
  // Stage 4's corners alone on hard frames: most are not valid there.
  loop::LoopConfig stage4_only;
  stage4_only.loop.estimator.guided.rounds = 0;
  for (EstimatePipeline* p : {plain.get(), dense.get()}) {
    ASSERT_TRUE(p->init("test", setup, vision::default_color_model(), stage4_only));
  }
  options = quick_dense_options();
  ASSERT_EQ(options.max_measured_corners, vision::kNumCorners);  // every frame not valid
  ASSERT_TRUE(dense->enable_dense(options));
  const MutableImageView out = frame();
  int ran = 0;
  int valid = 0;
  for (int i = 0; i < 4; ++i) {
    const double joints[3] = {24.0 + 2.0 * i, 0.4 - 0.3 * i, 0.7 - 0.1 * i};
    render::SceneSpec spec;
    spec.r = setup.instrument.geometry().nominal_pose(joints[0], joints[1], joints[2]);
    spec.seed = static_cast<std::uint64_t>(11 + i);
    spec.hard_cases = i < 3 ? (render::kHardOccluder | render::kHardHaze | render::kHardMotionBlur) : 0U;
    render::GroundTruth truth;
    ASSERT_TRUE(renderer->render(spec, out, truth).ok());
    plain->reset_sequence();
    dense->reset_sequence();
    const EstimateResult before = plain->process(out.view(), joints);
    const EstimateResult after = dense->process(out.view(), joints);
    const bool streak_read = before.streak_px.norm() > vision::DenseFit::kMinStreakPx;
    EXPECT_EQ(after.measured_corners, before.measured_corners) << i;
    const bool few_measured = before.measured_corners <= options.max_measured_corners_valid;
    EXPECT_EQ(after.dense_ran, before.status != solver::EstimateQuality::Valid || streak_read || few_measured) << i;
    if (after.dense_kept && after.status == solver::EstimateQuality::Valid) {
      EXPECT_EQ(before.status, solver::EstimateQuality::Valid) << i;
      EXPECT_LE((after.tcp - before.tcp).norm(), options.max_valid_tcp_change_mm) << i;
    }
    if (!after.dense_ran) {
      EXPECT_EQ(after.status, before.status) << i;
      EXPECT_EQ((after.tcp - before.tcp).norm(), 0.0) << i;
      ++valid;
    }
    ran += after.dense_ran ? 1 : 0;
  }
  EXPECT_GE(ran, 1);
  EXPECT_GE(valid, 1);

  const std::string hard = make_dataset("vision_cli_dense", render::kHardOccluder | render::kHardHaze);
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"evaluate", "--dense", "--guided-rounds", "0", "--max", "1", hard}),
            kExitOk);
  const std::string summary = testing::internal::GetCapturedStdout();
  const bool reported = summary.find("dense stage: ran on ") != std::string::npos;
  const bool none_to_run = summary.find("frames not succeeding: 0 (no estimate 0, of which 0 report no corner; "
                                        "degraded 0; valid 0)") != std::string::npos;
  EXPECT_TRUE(reported || none_to_run) << summary;
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"estimate", "--dense", "--json", hard + "/0000.ppm"}), kExitOk);
  const std::string line = testing::internal::GetCapturedStdout();
  EXPECT_NE(line.find("\"status\": "), std::string::npos) << line;
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
