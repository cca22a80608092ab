#include "tcpest/render/sidecar.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "render_test_support.hpp"
#include "tcpest/render/dataset.hpp"
#include "tcpest/test/mutate.hpp"

namespace tcpest {
namespace render {
namespace {

Sidecar rendered_sidecar(bool two, std::uint32_t hard_cases = kHardHaze | kHardDecoy) {
  static const auto camera = test::pal_camera();
  static auto renderer = test::make_renderer(camera);
  test::Frame f(720, 576);
  SceneSpec scene;
  scene.r = solver::InstrumentGeometry{}.nominal_pose(22.5, 0.3, 1.1);
  scene.seed = 0xFFFFFFFFFFFFFFF1ULL;  // beyond 2^53: must survive the round trip
  scene.world_seed = 0xFFFFFFFFFFFFFF07ULL;
  scene.hard_cases = hard_cases;
  scene.second_instrument = two;
  scene.r2 = renderer->mirrored_nominal_pose(20.0, -0.2, 0.9);
  GroundTruth truth;
  EXPECT_TRUE(renderer->render(scene, f.view, truth).ok());
  Sidecar s = make_sidecar(truth, scene, RenderSettings{}, 720, 576);
  std::snprintf(s.image, sizeof s.image, "0007.jpg");
  std::snprintf(s.set, sizeof s.set, "hard");
  s.index = 7;
  s.has_dataset_seed = true;
  s.dataset_seed = 99U;
  s.has_prior = true;
  s.prior = {23.1, 0.25, 1.2};
  s.jpeg_quality = 90;
  return s;
}

void expect_same_instrument(const SidecarInstrument& a, const SidecarInstrument& b) {
  EXPECT_EQ(a.has_r, b.has_r);
  EXPECT_LT((a.r - b.r).norm(), 1e-9);
  EXPECT_LT((a.tcp - b.tcp).norm(), 1e-9);
  EXPECT_EQ(a.corner_present, b.corner_present);
  EXPECT_EQ(a.corner_in_image, b.corner_in_image);
  EXPECT_EQ(a.corner_visible, b.corner_visible);
  EXPECT_EQ(a.view, b.view);
  for (std::size_t k = 0; k < 12U; ++k) {
    if (a.corner_present[k]) {
      EXPECT_LT((a.corners[k] - b.corners[k]).norm(), 1e-8);
    }
  }
}

TEST(Sidecar, RoundTripKeepsEveryField) {
  for (bool two : {false, true}) {
    const Sidecar s = rendered_sidecar(two);
    char text[kSidecarMaxBytes];
    const std::size_t n = format_sidecar(s, text, sizeof text);
    ASSERT_GT(n, 0U);
    const auto parsed = parse_sidecar(text, n, "mem.json");
    ASSERT_TRUE(parsed.ok()) << parsed.error().message << " " << parsed.error().field;
    const Sidecar& p = parsed.value();
    EXPECT_STREQ(p.image, "0007.jpg");
    EXPECT_STREQ(p.set, "hard");
    EXPECT_EQ(p.index, 7);
    EXPECT_EQ(p.width, 720);
    EXPECT_EQ(p.height, 576);
    EXPECT_EQ(p.seed, s.seed);
    EXPECT_EQ(p.scene.world_seed, s.scene.world_seed);
    EXPECT_TRUE(p.has_dataset_seed);
    EXPECT_EQ(p.dataset_seed, 99U);
    EXPECT_EQ(p.hard_cases, s.hard_cases);
    EXPECT_TRUE(p.has_prior);
    EXPECT_DOUBLE_EQ(p.prior[0], 23.1);
    EXPECT_EQ(p.jpeg_quality, 90);
    EXPECT_NEAR(p.tissue_depth_mm, s.tissue_depth_mm, 1e-3);
    expect_same_instrument(s.instrument, p.instrument);
    EXPECT_EQ(p.has_second, two);
    if (two) {
      expect_same_instrument(s.second, p.second);
    }
  }
}

// A randomised look's appearance and chroma subsampling are written and
// read back; a sidecar without them is the default look.
// Verifies: REQ-HAL-009
TEST(Sidecar, ARandomisedLookRoundTrips) {
  Sidecar s = rendered_sidecar(false);
  char text[kSidecarMaxBytes];
  std::size_t n = format_sidecar(s, text, sizeof text);
  auto parsed = parse_sidecar(text, n, "mem.json");
  ASSERT_TRUE(parsed.ok());
  EXPECT_FALSE(parsed.value().has_appearance);
  EXPECT_EQ(parsed.value().chroma, ChromaSubsampling::k420);
  s.has_appearance = true;
  s.scene.appearance = random_look(3U).appearance;
  s.chroma = ChromaSubsampling::k444;
  n = format_sidecar(s, text, sizeof text);
  ASSERT_GT(n, 0U);
  parsed = parse_sidecar(text, n, "mem.json");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message << " " << parsed.error().field;
  const Appearance& a = parsed.value().scene.appearance;
  EXPECT_TRUE(parsed.value().has_appearance);
  EXPECT_EQ(parsed.value().chroma, ChromaSubsampling::k444);
  for (std::size_t c = 0U; c < 3U; ++c) {
    EXPECT_NEAR(a.blue_albedo[c], s.scene.appearance.blue_albedo[c], 1e-9);
    EXPECT_NEAR(a.white_balance[c], s.scene.appearance.white_balance[c], 1e-9);
    EXPECT_NEAR(a.tissue_tint[c], s.scene.appearance.tissue_tint[c], 1e-9);
  }
  EXPECT_NEAR(a.grasper_gloss, s.scene.appearance.grasper_gloss, 1e-5);
  EXPECT_NEAR(a.shaft_radius_scale, s.scene.appearance.shaft_radius_scale, 1e-5);
  EXPECT_NEAR(a.grasper_radius_scale, s.scene.appearance.grasper_radius_scale, 1e-5);
  EXPECT_NEAR(a.lamp_offset_mm[0], s.scene.appearance.lamp_offset_mm[0], 1e-9);
  EXPECT_NEAR(a.lamp_offset_mm[1], s.scene.appearance.lamp_offset_mm[1], 1e-9);
  // A look no render can show is named.
  const char bad[] = R"({"corners": [null, null, null, null, null, null, null, null, null, null, null, null],
    "render": {"appearance": {"white_balance": [9, 1, 1]}}})";
  const auto refused = parse_sidecar(bad, sizeof bad - 1U, "bad.json");
  ASSERT_FALSE(refused.ok());
  EXPECT_STREQ(refused.error().field, "render.appearance");
}

TEST(Sidecar, MotionBlurStreakIsWrittenOnlyWithTheBlur) {
  const Sidecar blurred = rendered_sidecar(false, kHardMotionBlur);
  ASSERT_TRUE(blurred.has_motion_blur);
  const double length_px = std::hypot(blurred.motion_blur_px[0], blurred.motion_blur_px[1]);
  EXPECT_GE(length_px, 5.0);  // the renderer's streak: 5..14 px
  EXPECT_LE(length_px, 14.0);
  char text[kSidecarMaxBytes];
  std::size_t n = format_sidecar(blurred, text, sizeof text);
  ASSERT_GT(n, 0U);
  auto parsed = parse_sidecar(text, n, "mem.json");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_TRUE(parsed.value().has_motion_blur);
  EXPECT_NEAR(parsed.value().motion_blur_px[0], blurred.motion_blur_px[0], 1e-9);
  EXPECT_NEAR(parsed.value().motion_blur_px[1], blurred.motion_blur_px[1], 1e-9);
  EXPECT_EQ(parsed.value().jpeg_quality, 90);  // the render object still closes after the streak

  const Sidecar sharp = rendered_sidecar(false);
  EXPECT_FALSE(sharp.has_motion_blur);
  n = format_sidecar(sharp, text, sizeof text);
  ASSERT_GT(n, 0U);
  EXPECT_EQ(std::strstr(text, "motion_blur_px"), nullptr);
  parsed = parse_sidecar(text, n, "mem.json");
  ASSERT_TRUE(parsed.ok());
  EXPECT_FALSE(parsed.value().has_motion_blur);
}

TEST(Sidecar, FileRoundTrip) {
  const Sidecar s = rendered_sidecar(false);
  const std::string path = ::testing::TempDir() + "sidecar_round_trip.json";
  ASSERT_TRUE(write_sidecar_file(path.c_str(), s));
  const auto read = read_sidecar_file(path.c_str());
  ASSERT_TRUE(read.ok()) << read.error().message;
  expect_same_instrument(s.instrument, read.value().instrument);
  std::remove(path.c_str());
  EXPECT_FALSE(read_sidecar_file(path.c_str()).ok());
}

TEST(Sidecar, MinimalForeignAnnotationIsAccepted) {
  // Someone's own annotated image: corners only, some null.
  const char* text =
      "{\"corners\": [[10,20],[30,40],null,null,[1,2],[3,4],[5,6],[7,8],[9,10],[11,12],null,[13,14]]}";
  const auto parsed = parse_sidecar(text, std::strlen(text), "own.json");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const Sidecar& s = parsed.value();
  EXPECT_FALSE(s.instrument.has_r);
  EXPECT_FALSE(s.has_prior);
  EXPECT_FALSE(s.instrument.corner_present[2]);
  EXPECT_TRUE(s.instrument.corner_visible[0]);
  EXPECT_FALSE(s.instrument.corner_visible[10]);
  EXPECT_DOUBLE_EQ(s.instrument.corners[11].x(), 13.0);
}

// Verifies: REQ-ERR-003
TEST(Sidecar, ErrorsNameTheField) {
  struct Case {
    const char* text;
    const char* field;
  };
  const Case cases[] = {
      {"{}", "corners"},
      {"{\"corners\": [1,2]}", "corners"},
      {"{\"corners\": [[1,2],[3,4],null,null,null,null,null,null,null,null,null,[1]]}", "corners"},
      {"{\"corners\": [null,null,null,null,null,null,null,null,null,null,null,null], \"r\": [1,2,3]}", "r"},
      {"{\"corners\": [null,null,null,null,null,null,null,null,null,null,null,null], "
       "\"corner_visible\": [true,false,false,false,false,false,false,false,false,false,false,false]}",
       "corner_visible"},
      {"{\"corners\": [null,null,null,null,null,null,null,null,null,null,null,null], \"hard_cases\": [\"rain\"]}",
       "hard_cases"},
      {"{\"corners\": [null,null,null,null,null,null,null,null,null,null,null,null], \"instrument2\": {}}",
       "instrument2.corners"},
      {"{\"corners\": [null,null,null,null,null,null,null,null,null,null,null,null], "
       "\"render\": {\"motion_blur_px\": [3]}}",
       "render.motion_blur_px"},
  };
  for (const Case& c : cases) {
    const auto parsed = parse_sidecar(c.text, std::strlen(c.text), "bad.json");
    ASSERT_FALSE(parsed.ok()) << c.text;
    EXPECT_STREQ(parsed.error().field, c.field) << c.text;
  }
  const char* broken = "{\"corners\": [";
  EXPECT_FALSE(parse_sidecar(broken, std::strlen(broken), "broken.json").ok());
  EXPECT_FALSE(parse_sidecar("[1]", 3U, "array.json").ok());
}

// Seeded damage to a rendered sidecar: refused with the field named, or
// read with every value it reports finite and within its array. Never a
// crash or an overrun (the sanitizer build runs this).
// Verifies: REQ-ERR-003
TEST(Sidecar, DamagedFilesAreRefusedOrSound) {
  char valid[kSidecarMaxBytes];
  const std::size_t length = format_sidecar(rendered_sidecar(true), valid, sizeof valid);
  ASSERT_GT(length, 0U);
  const std::string text_valid(valid, length);
  tcpest::test::Mutator mutator(11U);
  int refused = 0;
  for (int i = 0; i < 5000; ++i) {
    const std::string text = mutator.damage(text_valid);
    const auto parsed = parse_sidecar(text.data(), text.size(), "damaged.json");
    if (!parsed.ok()) {
      EXPECT_NE(parsed.error().message[0], '\0') << text;
      ++refused;
      continue;
    }
    const Sidecar& s = parsed.value();
    EXPECT_GE(s.width, 0) << text;
    EXPECT_GE(s.height, 0) << text;
    EXPECT_NE(std::memchr(s.image, '\0', sizeof s.image), nullptr) << text;
    EXPECT_TRUE(!s.instrument.has_r || s.instrument.r.allFinite()) << text;
    EXPECT_TRUE(!s.instrument.has_tcp || s.instrument.tcp.allFinite()) << text;
    for (std::size_t k = 0; k < 12U; ++k) {
      EXPECT_TRUE(!s.instrument.corner_present[k] || s.instrument.corners[k].allFinite()) << text;
    }
  }
  EXPECT_GT(refused, 500);
  EXPECT_GT(5000 - refused, 100);  // and some damage is harmless (a comment, a digit)
}

}  // namespace
}  // namespace render
}  // namespace tcpest
