// tcpest render end to end: files and sidecars written, same seed -> same
// bytes, bad input refused with the documented exit codes.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "cli/commands.hpp"
#include "tcpest/render/sidecar.hpp"

namespace tcpest {
namespace cli {
namespace {

int run(std::vector<std::string> words) {
  words.insert(words.begin(), "render");
  std::vector<char*> argv;
  for (auto& w : words) {
    argv.push_back(&w[0]);
  }
  return cmd_render(static_cast<int>(argv.size()), argv.data());
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

std::string temp_dir(const std::string& name) { return ::testing::TempDir() + name; }

TEST(CmdRender, LabWritesImagesAndSidecarsDeterministically) {
  const std::string a = temp_dir("render_lab_a");
  const std::string b = temp_dir("render_lab_b");
  ASSERT_EQ(run({"--set", "lab", "--n", "2", "--start", "150", "--seed", "4", "--out", a, "--quiet"}), kExitOk);
  ASSERT_EQ(run({"--set", "lab", "--n", "2", "--start", "150", "--seed", "4", "--out", b, "--quiet"}), kExitOk);
  for (const char* stem : {"/0150", "/0151"}) {
    const std::string image = slurp(a + stem + ".jpg");
    ASSERT_GT(image.size(), 1000U);
    EXPECT_EQ(image, slurp(b + stem + ".jpg"));
    const auto sidecar = render::read_sidecar_file((a + stem + ".json").c_str());
    ASSERT_TRUE(sidecar.ok()) << sidecar.error().message;
    EXPECT_TRUE(sidecar.value().has_prior);
    EXPECT_TRUE(sidecar.value().instrument.has_r);
    EXPECT_STREQ(sidecar.value().set, "lab");
    EXPECT_EQ(sidecar.value().dataset_seed, 4U);
  }
  const std::string c = temp_dir("render_lab_c");
  ASSERT_EQ(run({"--set", "lab", "--n", "1", "--start", "150", "--seed", "5", "--out", c, "--quiet"}), kExitOk);
  EXPECT_NE(slurp(a + "/0150.jpg"), slurp(c + "/0150.jpg"));
}

// --randomise: the same seed gives the same bytes, the sidecar holds the
// look and the JPEG settings it was written with, the truth is the plain
// render's, the images of a set share one build (radii, lamp) but not one
// look; --clean excludes it.
// Verifies: REQ-HAL-009
TEST(CmdRender, RandomisedLooksAreDeterministicAndRecorded) {
  const std::string a = temp_dir("render_rand_a");
  const std::string b = temp_dir("render_rand_b");
  const std::string plain = temp_dir("render_rand_plain");
  for (const std::string& dir : {a, b}) {
    ASSERT_EQ(run({"--set", "lab", "--n", "2", "--start", "40", "--seed", "6", "--randomise", "--out", dir, "--quiet"}),
              kExitOk);
  }
  ASSERT_EQ(run({"--set", "lab", "--n", "2", "--start", "40", "--seed", "6", "--out", plain, "--quiet"}), kExitOk);
  for (const char* stem : {"/0040", "/0041"}) {
    const std::string image = slurp(a + stem + ".jpg");
    ASSERT_GT(image.size(), 1000U);
    EXPECT_EQ(image, slurp(b + stem + ".jpg"));
    EXPECT_NE(image, slurp(plain + stem + ".jpg"));
    const auto looked = render::read_sidecar_file((a + stem + ".json").c_str());
    const auto unlooked = render::read_sidecar_file((plain + stem + ".json").c_str());
    ASSERT_TRUE(looked.ok() && unlooked.ok());
    EXPECT_TRUE(looked.value().has_appearance);
    EXPECT_FALSE(unlooked.value().has_appearance);
    EXPECT_GE(looked.value().jpeg_quality, 70);
    EXPECT_LE(looked.value().jpeg_quality, 95);
    for (std::size_t k = 0; k < solver::kNumCorners; ++k) {
      EXPECT_EQ(looked.value().instrument.corners[k], unlooked.value().instrument.corners[k]) << k;
    }
  }
  const auto first = render::read_sidecar_file((a + "/0040.json").c_str());
  const auto second = render::read_sidecar_file((a + "/0041.json").c_str());
  ASSERT_TRUE(first.ok() && second.ok());
  const render::Appearance& one = first.value().scene.appearance;
  const render::Appearance& two = second.value().scene.appearance;
  EXPECT_NE(one.blue_albedo, two.blue_albedo);
  EXPECT_EQ(one.shaft_radius_scale, two.shaft_radius_scale);
  EXPECT_EQ(one.grasper_radius_scale, two.grasper_radius_scale);
  EXPECT_EQ(one.lamp_offset_mm, two.lamp_offset_mm);
  EXPECT_EQ(run({"--set", "lab", "--n", "1", "--randomise", "--clean", "--out", a}), kExitUsage);
}

TEST(CmdRender, SingleBehindTheCameraIsAValidImageSaidInTheSidecar) {
  const std::string dir = temp_dir("render_behind");
  ASSERT_EQ(run({"--set", "single", "--r-deg=-13.3,6.2,180,0,25,0,30", "--raw", "--out", dir}), kExitOk);
  EXPECT_GT(slurp(dir + "/0000.ppm").size(), 720U * 576U * 3U);
  const auto sidecar = render::read_sidecar_file((dir + "/0000.json").c_str());
  ASSERT_TRUE(sidecar.ok());
  EXPECT_EQ(sidecar.value().instrument.view, render::InstrumentView::BehindCamera);
}

TEST(CmdRender, HardAndSeqAndTwoInstruments) {
  const std::string dir = temp_dir("render_hard");
  ASSERT_EQ(run({"--set", "hard", "--n", "2", "--out", dir, "--two-instruments", "--quiet"}), kExitOk);
  const auto sidecar = render::read_sidecar_file((dir + "/0001.json").c_str());
  ASSERT_TRUE(sidecar.ok());
  EXPECT_NE(sidecar.value().hard_cases, 0U);
  EXPECT_TRUE(sidecar.value().has_second);
  const std::string seq = temp_dir("render_seq");
  ASSERT_EQ(run({"--set", "seq", "--n", "2", "--out", seq, "--quiet", "--quality", "75"}), kExitOk);
  const auto frame = render::read_sidecar_file((seq + "/0001.json").c_str());
  ASSERT_TRUE(frame.ok());
  EXPECT_TRUE(frame.value().has_time);
  EXPECT_DOUBLE_EQ(frame.value().time_s, 0.04);
  EXPECT_EQ(frame.value().jpeg_quality, 75);
}

TEST(CmdRender, BadInputIsRefusedClearly) {
  const std::string dir = temp_dir("render_bad");
  EXPECT_EQ(run({"--set", "everything", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "lab"}), kExitUsage);
  EXPECT_EQ(run({"--set", "single", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "single", "--r", "1,2,3", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "lab", "--quality", "0", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "lab", "--hard", "rain", "--out", dir}), kExitUsage);
  // A start past the grid used to write nothing and exit 0.
  EXPECT_EQ(run({"--set", "lab", "--start", "1000000", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "hard", "--start", "294", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "seq", "--start", "1000001", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "seq", "--n", "0", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "seq", "--fps", "1e308", "--out", dir}), kExitUsage);
  EXPECT_EQ(run({"--set", "lab", "--supersample", "4294967297", "--out", dir}), kExitUsage);
  const std::string calib = temp_dir("bad_camera.yaml");
  {
    std::ofstream out(calib);
    out << "image_width: 720\nimage_height: 576\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
           "  data: [0, 0, 359.5, 0, 400, 287.5, 0, 0, 1]\n";
  }
  EXPECT_EQ(run({"--set", "lab", "--n", "1", "--calib", calib, "--out", dir}), kExitConfig);
  EXPECT_EQ(run({"--set", "lab", "--n", "1", "--calib", temp_dir("missing.yaml"), "--out", dir}), kExitConfig);
}

// --out a/b/c makes the missing a and a/b too (the help says the directory
// is created); a parent that is a file is refused, the message naming it.
// Verifies: REQ-ERR-010
TEST(CmdRender, CreatesNestedOutputDirectories) {
  const std::string root = temp_dir("render_nested_" + std::to_string(::getpid()));
  const std::string nested = root + "/a//b/c/";
  ASSERT_EQ(run({"--set", "lab", "--n", "1", "--start", "150", "--out", nested, "--quiet"}), kExitOk);
  EXPECT_FALSE(slurp(root + "/a/b/c/0150.json").empty());
  // Again into the same (now existing) directories.
  ASSERT_EQ(run({"--set", "lab", "--n", "1", "--start", "150", "--out", nested, "--quiet"}), kExitOk);
  {
    std::ofstream file(root + "/a/file");
    file << "not a directory\n";
  }
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"--set", "lab", "--n", "1", "--out", root + "/a/file/d/e", "--quiet"}), kExitFailure);
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("'" + root + "/a/file': Not a directory"), std::string::npos) << said;
  // Deeper than the bound: refused before anything is made.
  std::string deep = root + "/deep";
  for (int i = 0; i < 40; ++i) {
    deep += "/d";
  }
  EXPECT_EQ(run({"--set", "lab", "--n", "1", "--out", deep, "--quiet"}), kExitFailure);
  EXPECT_TRUE(slurp(root + "/deep/d").empty());
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
