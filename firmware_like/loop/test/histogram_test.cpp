#include "tcpest/loop/histogram.hpp"

#include <gtest/gtest.h>

#include <memory>

namespace tcpest {
namespace loop {
namespace {

TEST(DurationHistogram, QuantilesWithinTheBinResolution) {
  auto h = std::make_unique<DurationHistogram>();
  for (std::int64_t v = 1; v <= 100000; ++v) {
    h->add(v * 1000);  // 1 us .. 100 ms, uniform
  }
  EXPECT_EQ(h->count(), 100000U);
  EXPECT_NEAR(static_cast<double>(h->quantile_ns(0.5)), 50.0e6, 50.0e6 * 0.003);
  EXPECT_NEAR(static_cast<double>(h->quantile_ns(0.99)), 99.0e6, 99.0e6 * 0.003);
  EXPECT_NEAR(static_cast<double>(h->quantile_ns(0.999)), 99.9e6, 99.9e6 * 0.003);
  EXPECT_EQ(h->min_ns(), 1000);
  EXPECT_EQ(h->max_ns(), 100000000);
  EXPECT_EQ(h->quantile_ns(1.0), 100000000);
  EXPECT_NEAR(h->mean_ns(), 50.0005e6, 1.0);
}

TEST(DurationHistogram, SmallValuesAreExactAndMergeAdds) {
  auto a = std::make_unique<DurationHistogram>();
  auto b = std::make_unique<DurationHistogram>();
  a->add(3);
  a->add(5);
  b->add(7);
  b->add(-4);  // clamped to 0
  a->merge(*b);
  EXPECT_EQ(a->count(), 4U);
  EXPECT_EQ(a->quantile_ns(0.5), 3);
  EXPECT_EQ(a->min_ns(), 0);
  EXPECT_EQ(a->max_ns(), 7);
  a->clear();
  EXPECT_EQ(a->count(), 0U);
  EXPECT_EQ(a->quantile_ns(0.5), 0);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest
