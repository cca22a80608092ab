#include "tcpest/hal/camera/jpeg_decoder.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <vector>

#include "jpeg_test_images.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace hal {
namespace {

using testing::encode_jpeg;
using testing::EncodeOptions;
using testing::make_pattern;

constexpr int kW = 96;
constexpr int kH = 64;

struct Buffer {
  std::vector<std::uint8_t> bytes;
  MutableImageView view;
  Buffer(int w, int h, std::size_t pad = 0U)
      : bytes(static_cast<std::size_t>(h) * (static_cast<std::size_t>(w) * 3U + pad)) {
    view = MutableImageView{bytes.data(), w, h, static_cast<std::size_t>(w) * 3U + pad};
  }
};

double mean_abs_difference(const std::vector<std::uint8_t>& rgb, const MutableImageView& view) {
  double sum = 0.0;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width * 3; ++x) {
      sum += std::abs(static_cast<int>(view.row(y)[x]) - static_cast<int>(rgb[static_cast<std::size_t>(y * view.width * 3 + x)]));
    }
  }
  return sum / (view.width * view.height * 3.0);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, DecodesBaselineIntoAStridedBuffer) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  const auto rgb = make_pattern(kW, kH, 1);
  const auto jpeg = encode_jpeg(rgb, kW, kH);
  Buffer out(kW, kH, 13U);
  const auto status = decoder.decode(jpeg.data(), jpeg.size(), out.view);
  ASSERT_TRUE(status.ok()) << to_string(status.error()) << " " << decoder.last_message();
  EXPECT_LT(mean_abs_difference(rgb, out.view), 3.0);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, InspectReadsTheHeader) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  const auto jpeg = encode_jpeg(make_pattern(40, 30, 2), 40, 30);
  const auto info = decoder.inspect(jpeg.data(), jpeg.size());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info.value().width, 40);
  EXPECT_EQ(info.value().height, 30);
  EXPECT_EQ(info.value().components, 3);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, WrongSizeIsAnErrorAndTheDecoderCarriesOn) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  const auto small = encode_jpeg(make_pattern(48, 32, 3), 48, 32);
  Buffer out(kW, kH);
  const auto status = decoder.decode(small.data(), small.size(), out.view);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error(), CameraError::kWrongSize);
  const auto good = encode_jpeg(make_pattern(kW, kH, 3), kW, kH);
  EXPECT_TRUE(decoder.decode(good.data(), good.size(), out.view).ok());
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, TruncatedIsAnError) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  const auto jpeg = encode_jpeg(make_pattern(kW, kH, 4), kW, kH);
  Buffer out(kW, kH);
  const auto status = decoder.decode(jpeg.data(), jpeg.size() / 2U, out.view);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error(), CameraError::kTruncated);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, GarbageIsCorrupt) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  std::vector<std::uint8_t> garbage(4000U);
  for (std::size_t i = 0; i < garbage.size(); ++i) {
    garbage[i] = static_cast<std::uint8_t>((i * 2654435761U) >> 13U);
  }
  Buffer out(kW, kH);
  const auto status = decoder.decode(garbage.data(), garbage.size(), out.view);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error(), CameraError::kCorrupt);
  const auto empty = decoder.decode(garbage.data(), 0U, out.view);
  EXPECT_FALSE(empty.ok());
}

// Every prefix and many single-byte corruptions: each is ok or an error value,
// never a crash, and a good image still decodes afterwards.
// Verifies: REQ-HAL-001
TEST(JpegDecoder, SurvivesEveryTruncationAndByteFlips) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  const auto rgb = make_pattern(kW, kH, 5);
  const auto jpeg = encode_jpeg(rgb, kW, kH);
  Buffer out(kW, kH);
  std::size_t failures = 0U;
  for (std::size_t n = 0; n < jpeg.size(); n += 7U) {
    if (!decoder.decode(jpeg.data(), n, out.view).ok()) {
      ++failures;
    }
  }
  EXPECT_GT(failures, 0U);
  for (std::size_t i = 0; i < jpeg.size(); i += 3U) {
    auto corrupt = jpeg;
    corrupt[i] = static_cast<std::uint8_t>(corrupt[i] ^ 0xA5U);
    static_cast<void>(decoder.decode(corrupt.data(), corrupt.size(), out.view));  // any value is fine
  }
  ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok());
  EXPECT_LT(mean_abs_difference(rgb, out.view), 3.0);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, GreyscaleIsExpandedToRgb) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  EncodeOptions options;
  options.grayscale = true;
  const auto jpeg = encode_jpeg(make_pattern(kW, kH, 6), kW, kH, options);
  Buffer out(kW, kH);
  ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok());
  EXPECT_EQ(out.view.row(10)[30], out.view.row(10)[31]);
  EXPECT_EQ(out.view.row(10)[30], out.view.row(10)[32]);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, ProgressiveDecodesWithTheCountedFallback) {
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  EncodeOptions options;
  options.progressive = true;
  const auto rgb = make_pattern(kW, kH, 7);
  const auto jpeg = encode_jpeg(rgb, kW, kH, options);
  Buffer out(kW, kH);
  ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok());
  EXPECT_LT(mean_abs_difference(rgb, out.view), 3.0);
  EXPECT_EQ(decoder.arena_stats().fallback_allocations, 1U);
  // The deviation is bounded and the same on every progressive decode.
  std::size_t first = 0U;
  for (int i = 0; i < 3; ++i) {
    test::AllocationScope scope;
    ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok());
    if (i == 0) {
      first = scope.count();
    } else {
      EXPECT_EQ(scope.count(), first);
    }
  }
  if (test::malloc_hook_active()) {
    EXPECT_GT(first, 0U);
    EXPECT_LE(first, 8U);
  }
  std::printf("progressive decode: %zu heap allocations per frame (libjpeg's coefficient buffer)\n", first);
}

// Every sampling a baseline colour JPEG may have (luma 1x1 to 4x2, chroma
// 1x1; at most 10 blocks per MCU) decodes at 720x576 within the default
// arena, using less than 40 of its 64 RGB rows (hal/camera/README.md).
// Verifies: REQ-HAL-001
TEST(JpegDecoder, EverySamplingFitsTheDefaultArena) {
  constexpr int kPalW = 720;
  constexpr int kPalH = 576;
  const auto rgb = make_pattern(kPalW, kPalH, 7);
  Buffer out(kPalW, kPalH);
  const int samplings[][2] = {{1, 1}, {1, 2}, {1, 3}, {1, 4}, {2, 1}, {2, 2}, {2, 3}, {2, 4}, {3, 1}, {3, 2},
                              {4, 1}, {4, 2}};
  for (const auto& hv : samplings) {
    JpegDecoder decoder;
    ASSERT_TRUE(decoder.init(kPalW, kPalH).ok());
    EncodeOptions options;
    options.luma_h_samp = hv[0];
    options.luma_v_samp = hv[1];
    const auto jpeg = encode_jpeg(rgb, kPalW, kPalH, options);
    ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok()) << hv[0] << "x" << hv[1];
    EXPECT_LT(mean_abs_difference(rgb, out.view), 3.0) << hv[0] << "x" << hv[1];
    const JpegArenaStats stats = decoder.arena_stats();
    EXPECT_EQ(stats.fallback_allocations, 0U);
    EXPECT_LT(stats.permanent_bytes + stats.image_high_water_bytes, std::size_t{40U} * kPalW * 3U)
        << hv[0] << "x" << hv[1];
  }
}

// An arena too small for the image: kOutOfMemory at every decode, no
// crash, no heap allocation instead, and the decoder stays usable (the
// header reads); an arena of exactly the measured need decodes.
// Verifies: REQ-HAL-001
TEST(JpegDecoder, AnExhaustedArenaIsOutOfMemoryAndTheDecoderCarriesOn) {
  const auto rgb = make_pattern(kW, kH, 3);
  const auto jpeg = encode_jpeg(rgb, kW, kH);
  JpegDecoder roomy;
  ASSERT_TRUE(roomy.init(kW, kH).ok());
  Buffer out(kW, kH);
  ASSERT_TRUE(roomy.decode(jpeg.data(), jpeg.size(), out.view).ok());
  const JpegArenaStats need = roomy.arena_stats();
  const std::size_t enough = need.permanent_bytes + need.image_high_water_bytes;

  JpegDecoder tight;
  ASSERT_TRUE(tight.init(kW, kH, enough / 2U).ok());
  EXPECT_EQ(tight.arena_stats().capacity_bytes, (enough / 2U + 63U) / 64U * 64U);
  for (int i = 0; i < 3; ++i) {
    test::AllocationScope scope;
    const auto got = tight.decode(jpeg.data(), jpeg.size(), out.view);
    ASSERT_FALSE(got.ok());
    EXPECT_EQ(got.error(), CameraError::kOutOfMemory);
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_TRUE(tight.inspect(jpeg.data(), jpeg.size()).ok());  // the header needs no per-image memory

  JpegDecoder exact;
  ASSERT_TRUE(exact.init(kW, kH, enough).ok());
  EXPECT_TRUE(exact.decode(jpeg.data(), jpeg.size(), out.view).ok());

  JpegDecoder absurd;
  const auto refused = absurd.init(kW, kH, std::size_t{1U} << 40U);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error(), CameraError::kBadArgument);
}

// Verifies: REQ-LOOP-006, REQ-HAL-001
TEST(JpegDecoder, BaselineDecodeMakesNoHeapAllocation) {
  constexpr int kPalW = 720;
  constexpr int kPalH = 576;
  JpegDecoder decoder;
  ASSERT_TRUE(decoder.init(kPalW, kPalH).ok());
  const auto jpeg = encode_jpeg(make_pattern(kPalW, kPalH, 8), kPalW, kPalH);
  Buffer out(kPalW, kPalH);
  ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok());  // first decode: permanent tables
  test::AllocationScope scope;
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(decoder.decode(jpeg.data(), jpeg.size(), out.view).ok());
  }
  EXPECT_EQ(scope.count(), 0U);
  const auto stats = decoder.arena_stats();
  EXPECT_LT(stats.image_high_water_bytes + stats.permanent_bytes, stats.capacity_bytes);
  std::printf("arena: capacity %zu B, permanent %zu B, per-image high water %zu B (720x576)\n",
              stats.capacity_bytes, stats.permanent_bytes, stats.image_high_water_bytes);
}

// Memory running out at each allocation init() makes in turn (the context,
// the arena, libjpeg's memory manager, its first pools): init() reports
// kOutOfMemory, having freed what it took before, and the decoder stays
// uninitialised.
// Verifies: REQ-ERR-007
TEST(JpegDecoder, InitRecoversWhenMemoryRunsOutAtAnyOfItsAllocations) {
  if (!test::malloc_hook_active()) {
    GTEST_SKIP() << "malloc belongs to the sanitizer's runtime in this build";
  }
  Status<CameraError> status = ok_status<CameraError>();
  bool initialised = false;
  const auto init = [&]() {
    JpegDecoder decoder;
    status = decoder.init(kW, kH);
    initialised = decoder.initialised();
    return status.ok();  // the decoder is released here: only the count matters
  };
  const std::size_t allocations = test::run_out_of_memory_at_each_allocation(init, [&](const test::OutOfMemoryOutcome& o) {
    ASSERT_FALSE(o.succeeded) << "allocation " << o.nth;
    EXPECT_EQ(status.error(), CameraError::kOutOfMemory) << "allocation " << o.nth;
    EXPECT_EQ(o.leaked, 0U) << "out of memory at allocation " << o.nth;
    EXPECT_FALSE(initialised);
  });
  EXPECT_GE(allocations, 3U);
}

// Verifies: REQ-HAL-001
TEST(JpegDecoder, UninitialisedOrBadViewIsAnError) {
  JpegDecoder decoder;
  std::uint8_t byte = 0U;
  Buffer out(kW, kH);
  EXPECT_FALSE(decoder.decode(&byte, 1U, out.view).ok());
  ASSERT_TRUE(decoder.init(kW, kH).ok());
  EXPECT_FALSE(decoder.init(kW, kH).ok());
  EXPECT_FALSE(decoder.decode(&byte, 1U, MutableImageView{}).ok());
  Buffer big(kW * 2, kH);
  EXPECT_EQ(decoder.decode(&byte, 1U, big.view).error(), CameraError::kBadArgument);
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
