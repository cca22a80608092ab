// tcpest train-colors with hand-marked mask images (docs/vision.md, "Colour
// model"): a synthetic frame with known marker colours and a mask written
// here trains a model whose means are those colours and which classifies the
// marked pixels correctly; the same from a rendered frame and a mask made of
// the renderer's pixel labels; PGM masks; the automatic background rule; bad
// masks (wrong size, corrupt, truncated, absurd header, 16 bit) are reported
// and skipped.
#include <gtest/gtest.h>

#include <stdlib.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli/commands.hpp"
#include "cli/setup.hpp"
#include "cli/vision_run.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/vision/color_model.hpp"

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

void write_file(const std::string& path, const std::string& bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr) << path;
  ASSERT_EQ(std::fwrite(bytes.data(), 1U, bytes.size(), f), bytes.size());
  ASSERT_EQ(std::fclose(f), 0);
}

std::string pnm(const char* magic, int width, int height, const std::vector<std::uint8_t>& samples) {
  char header[64];
  std::snprintf(header, sizeof header, "%s\n# test\n%d %d\n255\n", magic, width, height);
  return std::string(header) + std::string(samples.begin(), samples.end());
}

constexpr int kWidth = 160;
constexpr int kHeight = 120;
constexpr std::uint8_t kBlue[3] = {40, 70, 190};
constexpr std::uint8_t kYellow[3] = {205, 180, 45};
constexpr std::uint8_t kBackground[3] = {120, 95, 90};
constexpr std::uint8_t kGreen[3] = {30, 170, 60};  // not marked: must train nothing

enum class Region { Background, Blue, Yellow, Green };

// Two marker rectangles, a green distractor and a reddish background.
Region region_at(int x, int y) {
  if (y >= 40 && y < 80) {
    if (x >= 20 && x < 60) {
      return Region::Blue;
    }
    if (x >= 70 && x < 110) {
      return Region::Yellow;
    }
    if (x >= 120 && x < 150) {
      return Region::Green;
    }
  }
  return Region::Background;
}

// The synthetic frame with a little deterministic noise (+/- 4).
std::vector<std::uint8_t> synthetic_image() {
  std::vector<std::uint8_t> rgb;
  std::uint32_t state = 12345U;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const Region r = region_at(x, y);
      const std::uint8_t* c = r == Region::Blue     ? kBlue
                              : r == Region::Yellow ? kYellow
                              : r == Region::Green  ? kGreen
                                                    : kBackground;
      for (int k = 0; k < 3; ++k) {
        state = state * 1664525U + 1013904223U;
        const int noise = static_cast<int>((state >> 24U) % 9U) - 4;
        rgb.push_back(static_cast<std::uint8_t>(c[k] + noise));
      }
    }
  }
  return rgb;
}

// PPM mask: markers' interiors (2 px inside the rectangles: a hand mark stays
// off the edges) in the mask colours, the green distractor white (unused),
// the rest black (explicit background) unless `with_background` is false.
std::vector<std::uint8_t> ppm_mask(bool with_background) {
  std::vector<std::uint8_t> rgb;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const bool inner = region_at(x - 2, y - 2) == region_at(x, y) && region_at(x + 2, y + 2) == region_at(x, y);
      const Region r = region_at(x, y);
      std::uint8_t c[3] = {255, 255, 255};
      if (r == Region::Blue && inner) {
        c[0] = 20;  // a not-quite-pure blue from an editor's palette
        c[1] = 30;
        c[2] = 230;
      } else if (r == Region::Yellow && inner) {
        c[0] = 255;
        c[1] = 240;
        c[2] = 0;
      } else if (r == Region::Background && with_background) {
        c[0] = c[1] = c[2] = 0;
      }
      rgb.insert(rgb.end(), c, c + 3);
    }
  }
  return rgb;
}

std::vector<std::uint8_t> pgm_mask() {
  std::vector<std::uint8_t> grey;
  const std::vector<std::uint8_t> rgb = ppm_mask(true);
  for (std::size_t i = 0U; i < rgb.size(); i += 3U) {
    grey.push_back(rgb[i + 2U] == 230U ? 1U : rgb[i] == 255U && rgb[i + 2U] == 0U ? 2U : rgb[i] == 0U ? 3U : 0U);
  }
  return grey;
}

struct Fixture {
  std::string dir;
  std::vector<std::uint8_t> image;
};

Fixture make_fixture(const char* name) {
  Fixture f;
  f.dir = ::testing::TempDir() + name;
  mkdir(f.dir.c_str(), 0755);
  f.image = synthetic_image();
  write_file(f.dir + "/frame.ppm", pnm("P6", kWidth, kHeight, f.image));
  return f;
}

std::string masks_json(const Fixture& f, const std::string& frames) {
  const std::string path = f.dir + "/marks.json";
  write_file(path, "{\"frames\": [" + frames + "]}");
  return path;
}

// Trains from `json` with --masks and checks the model against the known colours.
void expect_good_model(const Fixture& f, const std::string& option, const std::string& json) {
  const std::string model_path = f.dir + "/colors.json";
  ASSERT_EQ(run({"train-colors", option, json, "--out", model_path}), kExitOk);
  vision::ColorModel model;
  ASSERT_TRUE(load_color_model("test", model_path.c_str(), model));
  const vision::Lab blue = vision::srgb_to_lab(kBlue[0], kBlue[1], kBlue[2]);
  const vision::Lab yellow = vision::srgb_to_lab(kYellow[0], kYellow[1], kYellow[2]);
  EXPECT_NEAR(model.blue.mean_a, blue.a, 1.5);
  EXPECT_NEAR(model.blue.mean_b, blue.b, 1.5);
  EXPECT_NEAR(model.yellow.mean_a, yellow.a, 1.5);
  EXPECT_NEAR(model.yellow.mean_b, yellow.b, 1.5);
  // Every pixel of the frame (the marked ones and the rest) gets its class.
  int wrong[4] = {0, 0, 0, 0};
  int total[4] = {0, 0, 0, 0};
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const Region r = region_at(x, y);
      const std::uint8_t* c = f.image.data() + (static_cast<std::size_t>(y) * kWidth + static_cast<std::size_t>(x)) * 3U;
      const vision::PixelClass expected = r == Region::Blue     ? vision::PixelClass::Blue
                                          : r == Region::Yellow ? vision::PixelClass::Yellow
                                                                : vision::PixelClass::Background;
      ++total[static_cast<int>(r)];
      if (model.classify(c[0], c[1], c[2]) != expected) {
        ++wrong[static_cast<int>(r)];
      }
    }
  }
  for (int r = 0; r < 3; ++r) {  // the unseen green distractor is not asserted
    EXPECT_LE(wrong[r], total[r] / 100) << "region " << r << ": " << wrong[r] << " of " << total[r];
  }
}

TEST(TrainColorsMasks, PpmMaskWithExplicitBackgroundGivesTheKnownColours) {
  const Fixture f = make_fixture("mask_ppm");
  write_file(f.dir + "/frame.mask.ppm", pnm("P6", kWidth, kHeight, ppm_mask(true)));
  expect_good_model(f, "--masks", masks_json(f, R"({"image": "frame.ppm", "mask": "frame.mask.ppm"})"));
}

TEST(TrainColorsMasks, PgmMaskWorksToo) {
  const Fixture f = make_fixture("mask_pgm");
  write_file(f.dir + "/frame.mask.pgm", pnm("P5", kWidth, kHeight, pgm_mask()));
  expect_good_model(f, "--masks", masks_json(f, R"({"image": "frame.ppm", "mask": "frame.mask.pgm"})"));
}

TEST(TrainColorsMasks, MaskWithoutBackgroundUsesTheAutomaticRuleAndMixesWithPolygons) {
  const Fixture f = make_fixture("mask_auto");
  // Marks only; background = far from the marks. A polygon adds blue pixels.
  write_file(f.dir + "/frame.mask.ppm", pnm("P6", kWidth, kHeight, ppm_mask(false)));
  expect_good_model(f, "--polygons",
                    masks_json(f, R"({"image": "frame.ppm", "mask": "frame.mask.ppm",
                                      "blue": [[[25, 45], [55, 45], [55, 75], [25, 75]]]})"));
}

TEST(TrainColorsMasks, RenderedFrameWithAMaskFromTheRenderersLabels) {
  const std::string dir = ::testing::TempDir() + "mask_rendered";
  mkdir(dir.c_str(), 0755);
  ModelSetup setup;
  ASSERT_TRUE(load_model_setup("test", nullptr, nullptr, setup));
  auto created = render::Renderer::create(setup.camera, setup.instrument, render::RenderSettings{});
  ASSERT_TRUE(created.ok());
  render::Renderer& renderer = *created.value();
  const int w = setup.camera.width();
  const int h = setup.camera.height();
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3U);
  const MutableImageView out{pixels.data(), w, h, static_cast<std::size_t>(w) * 3U};
  render::SceneSpec spec;
  spec.r = setup.instrument.geometry().nominal_pose(25.0, 0.4, 0.5);
  spec.seed = 11U;
  render::GroundTruth truth;
  ASSERT_TRUE(renderer.render(spec, out, truth).ok());
  ASSERT_TRUE(render::write_ppm_file(out.view(), (dir + "/frame.ppm").c_str()).ok());
  // PGM mask: marker pixels 3 px from any other label (a hand mark stays off
  // the edges), background = pixels 3 px from every marker.
  const std::uint8_t* labels = renderer.labels();
  const auto marker = [&](int x, int y) {
    const int l = labels[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)];
    return l > render::kPixelInstrument && l < render::kPixelInstrument + render::kPartGrasperLabel
               ? l - render::kPixelInstrument
               : 0;
  };
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0U);
  for (int y = 3; y < h - 3; ++y) {
    for (int x = 3; x < w - 3; ++x) {
      const int m = marker(x, y);
      bool same = true;
      bool near = false;
      for (int dy = -3; dy <= 3; ++dy) {
        for (int dx = -3; dx <= 3; ++dx) {
          same = same && marker(x + dx, y + dy) == m;
          near = near || marker(x + dx, y + dy) != 0;
        }
      }
      std::uint8_t& code = mask[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)];
      if (m != 0 && same) {
        code = setup.instrument.geometry().marker_colors[static_cast<std::size_t>(m - 1)] == solver::MarkerColor::Blue
                   ? 1U
                   : 2U;
      } else if (!near) {
        code = 3U;
      }
    }
  }
  write_file(dir + "/frame.mask.pgm", pnm("P5", w, h, mask));
  const std::string json = dir + "/marks.json";
  write_file(json, R"({"frames": [{"image": "frame.ppm", "mask": "frame.mask.pgm"}]})");
  const std::string model_path = dir + "/colors.json";
  ASSERT_EQ(run({"train-colors", "--masks", json, "--out", model_path}), kExitOk);
  vision::ColorModel model;
  ASSERT_TRUE(load_color_model("test", model_path.c_str(), model));
  // The means are those of exactly the marked pixels, and on the main chroma
  // axis (b*) near the shipped model's (as for --sidecars in vision_cli_test).
  double sum_a[3] = {0.0, 0.0, 0.0};
  double sum_b[3] = {0.0, 0.0, 0.0};
  int marked[3] = {0, 0, 0};
  for (std::size_t i = 0U; i < mask.size(); ++i) {
    if (mask[i] == 1U || mask[i] == 2U) {
      const vision::Lab lab = vision::srgb_to_lab(pixels[3U * i], pixels[3U * i + 1U], pixels[3U * i + 2U]);
      sum_a[mask[i]] += lab.a;
      sum_b[mask[i]] += lab.b;
      ++marked[mask[i]];
    }
  }
  ASSERT_GT(marked[1], 200);
  ASSERT_GT(marked[2], 200);
  EXPECT_NEAR(model.blue.mean_a, sum_a[1] / marked[1], 0.01);
  EXPECT_NEAR(model.blue.mean_b, sum_b[1] / marked[1], 0.01);
  EXPECT_NEAR(model.yellow.mean_a, sum_a[2] / marked[2], 0.01);
  EXPECT_NEAR(model.yellow.mean_b, sum_b[2] / marked[2], 0.01);
  const vision::ColorModel shipped = vision::default_color_model();
  EXPECT_NEAR(model.blue.mean_b, shipped.blue.mean_b, 10.0);
  EXPECT_NEAR(model.yellow.mean_b, shipped.yellow.mean_b, 10.0);
  // The marked pixels get their class (the threshold keeps >= 95 % by rule).
  int counted[4] = {0, 0, 0, 0};
  int right[4] = {0, 0, 0, 0};
  for (std::size_t i = 0U; i < mask.size(); ++i) {
    const std::uint8_t code = mask[i];
    if (code == 0U) {
      continue;
    }
    const vision::PixelClass expected = code == 1U   ? vision::PixelClass::Blue
                                        : code == 2U ? vision::PixelClass::Yellow
                                                     : vision::PixelClass::Background;
    ++counted[code];
    if (model.classify(pixels[3U * i], pixels[3U * i + 1U], pixels[3U * i + 2U]) == expected) {
      ++right[code];
    }
  }
  for (int c = 1; c <= 3; ++c) {
    ASSERT_GT(counted[c], 200) << "class " << c;
    EXPECT_GE(right[c], counted[c] * 95 / 100) << "class " << c << ": " << right[c] << " of " << counted[c];
  }
}

TEST(TrainColorsMasks, BadMasksAreReportedAndTheirFramesSkipped) {
  const Fixture f = make_fixture("mask_bad");
  write_file(f.dir + "/good.ppm", pnm("P6", kWidth, kHeight, ppm_mask(true)));
  write_file(f.dir + "/small.ppm", pnm("P6", kWidth / 2, kHeight, std::vector<std::uint8_t>(kWidth / 2 * kHeight * 3U)));
  write_file(f.dir + "/corrupt.ppm", "\x89PNG\r\n\x1a\n not a netpbm file");
  std::string truncated = pnm("P6", kWidth, kHeight, ppm_mask(true));
  truncated.resize(truncated.size() / 2U);
  write_file(f.dir + "/truncated.ppm", truncated);
  write_file(f.dir + "/absurd.ppm", "P6\n123456789012 1\n255\nxxx");
  write_file(f.dir + "/huge.ppm", "P5\n100000 100000\n255\nxxx");
  write_file(f.dir + "/sixteen.pgm", "P5\n2 1\n65535\nxxxx");
  write_file(f.dir + "/empty.pgm", pnm("P5", kWidth, kHeight, std::vector<std::uint8_t>(kWidth * kHeight, 0U)));
  const char* bad[] = {"small.ppm", "corrupt.ppm", "truncated.ppm", "absurd.ppm", "huge.ppm",
                       "sixteen.pgm", "empty.pgm", "missing.ppm"};
  const char* expected_message[] = {"is 80x120 but image", "not a binary PGM (P5) or PPM (P6)",
                                    "truncated: ",
                                    "not a binary PGM (P5) or PPM (P6)", "100000x100000 larger than",
                                    "maxval 65535, expected 255", "marks no pixel", "cannot open"};
  for (std::size_t i = 0U; i < sizeof bad / sizeof bad[0]; ++i) {
    const std::string frame = std::string(R"({"image": "frame.ppm", "mask": ")") + bad[i] + "\"}";
    // Alone: nothing to train from, the run fails.
    ::testing::internal::CaptureStderr();
    EXPECT_EQ(run({"train-colors", "--masks", masks_json(f, frame), "--out", f.dir + "/m.json"}), kExitFailure)
        << bad[i];
    const std::string messages = ::testing::internal::GetCapturedStderr();
    EXPECT_NE(messages.find(expected_message[i]), std::string::npos) << bad[i] << ": " << messages;
    EXPECT_NE(messages.find("(frame skipped)"), std::string::npos) << bad[i] << ": " << messages;
    EXPECT_NE(messages.find("too few marked pixels"), std::string::npos) << bad[i] << ": " << messages;
    // With a good frame: the run goes on and succeeds.
    ::testing::internal::CaptureStderr();
    EXPECT_EQ(run({"train-colors", "--masks",
                   masks_json(f, frame + R"(, {"image": "frame.ppm", "mask": "good.ppm"})"), "--out",
                   f.dir + "/m.json"}),
              kExitOk)
        << bad[i];
    const std::string summary = ::testing::internal::GetCapturedStderr();
    EXPECT_NE(summary.find("1 frames (1 skipped)"), std::string::npos) << bad[i] << ": " << summary;
  }
  // A frame of a --masks file without a mask, or a mask that is not a name: configuration errors.
  EXPECT_EQ(run({"train-colors", "--masks", masks_json(f, R"({"image": "frame.ppm"})")}), kExitConfig);
  EXPECT_EQ(run({"train-colors", "--masks", masks_json(f, R"({"image": "frame.ppm", "mask": 3})")}), kExitConfig);
}

// A corrupt sidecar in a --sidecars dataset used to be skipped without a
// word: it is now named and counted, and the run goes on with the others.
TEST(TrainColorsSidecars, ACorruptSidecarIsNamedAndCounted) {
  std::string dir = std::string(::testing::TempDir()) + "tcpest_sidecars_XXXXXX";
  ASSERT_NE(::mkdtemp(&dir[0]), nullptr);
  ASSERT_EQ(run({"render", "--set", "lab", "--n", "1", "--start", "150", "--quiet", "--out", dir}), kExitOk);
  write_file(dir + "/broken.json", "{\"image\": ");
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run({"train-colors", "--sidecars", dir, "--out", dir + "/model.out"}), kExitOk);
  const std::string messages = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(messages.find("unreadable sidecar " + dir + "/broken.json"), std::string::npos) << messages;
  EXPECT_NE(messages.find("sidecars in " + dir + ": 1 used, 1 unreadable, 0 without a configuration"),
            std::string::npos)
      << messages;
}

TEST(TrainColorsMasks, ImageReaderReadsPgmAndPpmSamples) {
  const Fixture f = make_fixture("mask_reader");
  write_file(f.dir + "/a.pgm", pnm("P5", 3, 2, {1, 2, 3, 4, 5, 6}));
  ImageReader reader;
  ASSERT_TRUE(reader.init(64, 64));
  std::vector<std::uint8_t> samples;
  PnmInfo info;
  char error[256] = "";
  ASSERT_TRUE(reader.read_pnm((f.dir + "/a.pgm").c_str(), samples, info, error, sizeof error)) << error;
  EXPECT_EQ(info.width, 3);
  EXPECT_EQ(info.height, 2);
  EXPECT_EQ(info.channels, 1);
  EXPECT_EQ(samples, (std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6}));
  // The image path still reads P6 and refuses P5 (a mask is not a frame).
  ImageView view;
  std::vector<std::uint8_t> pixels;
  EXPECT_FALSE(reader.read((f.dir + "/a.pgm").c_str(), pixels, view, error, sizeof error));
  write_file(f.dir + "/b.ppm", pnm("P6", 1, 2, {1, 2, 3, 4, 5, 6}));
  ASSERT_TRUE(reader.read((f.dir + "/b.ppm").c_str(), pixels, view, error, sizeof error)) << error;
  EXPECT_EQ(view.width, 1);
  EXPECT_EQ(view.height, 2);
  ASSERT_TRUE(reader.read_pnm((f.dir + "/b.ppm").c_str(), samples, info, error, sizeof error)) << error;
  EXPECT_EQ(info.channels, 3);
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
