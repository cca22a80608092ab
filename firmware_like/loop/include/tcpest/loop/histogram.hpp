// A fixed-memory histogram of durations for percentiles (p50, p99, p99.9)
// over any number of cycles: log-linear bins (512 per octave above 512 ns,
// relative error below 0.2 %), 32 KiB, no allocation after construction.
#pragma once

#include <array>
#include <cstdint>

namespace tcpest {
namespace loop {

class DurationHistogram {
 public:
  static constexpr int kSubBits = 9;  // 512 bins per octave
  static constexpr int kOctaves = 32;  // up to 2^41 ns (~36 min)
  static constexpr int kBins = (kOctaves + 1) << kSubBits;

  void clear() noexcept;
  void add(std::int64_t ns) noexcept;
  std::uint64_t count() const noexcept { return count_; }
  std::int64_t min_ns() const noexcept { return count_ == 0U ? 0 : min_; }
  std::int64_t max_ns() const noexcept { return max_; }
  double mean_ns() const noexcept { return count_ == 0U ? 0.0 : static_cast<double>(sum_) / static_cast<double>(count_); }
  // The value at quantile q in [0, 1] (the bin's lower edge; exact below 512 ns).
  std::int64_t quantile_ns(double q) const noexcept;
  // Merges another histogram (bench: several runs).
  void merge(const DurationHistogram& other) noexcept;

 private:
  static int bin_of(std::int64_t ns) noexcept;
  static std::int64_t lower_edge(int bin) noexcept;
  std::array<std::uint32_t, kBins> bins_{};
  std::uint64_t count_ = 0U;
  std::int64_t sum_ = 0;
  std::int64_t min_ = 0;
  std::int64_t max_ = 0;
};

}  // namespace loop
}  // namespace tcpest
