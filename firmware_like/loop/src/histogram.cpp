#include "tcpest/loop/histogram.hpp"

namespace tcpest {
namespace loop {

namespace {
constexpr std::int64_t kSub = std::int64_t{1} << DurationHistogram::kSubBits;

int highest_bit(std::uint64_t v) noexcept { return 63 - __builtin_clzll(v); }
}  // namespace

void DurationHistogram::clear() noexcept {
  bins_.fill(0U);
  count_ = 0U;
  sum_ = 0;
  min_ = 0;
  max_ = 0;
}

int DurationHistogram::bin_of(std::int64_t ns) noexcept {
  if (ns < kSub) {
    return ns < 0 ? 0 : static_cast<int>(ns);
  }
  const int octave = highest_bit(static_cast<std::uint64_t>(ns)) - kSubBits + 1;  // >= 1
  if (octave > kOctaves) {
    return kBins - 1;
  }
  const auto sub = static_cast<int>((ns >> (octave - 1)) - kSub);  // 0..kSub-1
  return (octave << kSubBits) + sub;
}

std::int64_t DurationHistogram::lower_edge(int bin) noexcept {
  const int octave = bin >> kSubBits;
  const std::int64_t sub = bin & (kSub - 1);
  if (octave == 0) {
    return sub;
  }
  return (kSub + sub) << (octave - 1);
}

void DurationHistogram::add(std::int64_t ns) noexcept {
  if (ns < 0) {
    ns = 0;
  }
  const int bin = bin_of(ns);
  if (bins_[static_cast<std::size_t>(bin)] < 0xFFFFFFFFU) {
    ++bins_[static_cast<std::size_t>(bin)];
  }
  if (count_ == 0U || ns < min_) {
    min_ = ns;
  }
  if (ns > max_) {
    max_ = ns;
  }
  ++count_;
  sum_ += ns;
}

std::int64_t DurationHistogram::quantile_ns(double q) const noexcept {
  if (count_ == 0U) {
    return 0;
  }
  if (q <= 0.0) {
    return min_;
  }
  if (q >= 1.0) {
    return max_;
  }
  // The smallest value with at least ceil(q * n) samples at or below it.
  auto rank = static_cast<std::uint64_t>(q * static_cast<double>(count_));
  if (static_cast<double>(rank) < q * static_cast<double>(count_)) {
    ++rank;
  }
  if (rank == 0U) {
    rank = 1U;
  }
  std::uint64_t seen = 0U;
  for (int b = 0; b < kBins; ++b) {
    seen += bins_[static_cast<std::size_t>(b)];
    if (seen >= rank) {
      const std::int64_t edge = lower_edge(b);
      return edge < min_ ? min_ : (edge > max_ ? max_ : edge);
    }
  }
  return max_;
}

void DurationHistogram::merge(const DurationHistogram& other) noexcept {
  for (std::size_t b = 0; b < bins_.size(); ++b) {
    bins_[b] += other.bins_[b];
  }
  if (other.count_ > 0U && (count_ == 0U || other.min_ < min_)) {
    min_ = other.min_;
  }
  if (other.max_ > max_) {
    max_ = other.max_;
  }
  count_ += other.count_;
  sum_ += other.sum_;
}

}  // namespace loop
}  // namespace tcpest
