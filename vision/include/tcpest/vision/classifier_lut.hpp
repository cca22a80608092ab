// Stage 1's per-pixel classifier: the exact L*a*b* Mahalanobis decision of
// ColorModel precomputed at start-up over quantised RGB (kBitsPerChannel bits
// per channel, the cell's centre colour decides). 256 KiB, built once; a pixel
// then costs one table read. The agreement with the exact classifier over all
// 2^24 colours is measured by a test (docs/vision.md gives the number).
#pragma once

#include <cstdint>
#include <memory>

#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {

class ClassifierLut {
 public:
  static constexpr int kBitsPerChannel = 6;
  static constexpr int kShift = 8 - kBitsPerChannel;
  static constexpr std::uint32_t kEntries = 1U << (3 * kBitsPerChannel);

  // Allocates (start-up only) and fills the table. False if out of memory.
  bool build(const ColorModel& model) noexcept;
  bool ready() const noexcept { return table_ != nullptr; }

  static std::uint32_t index(std::uint8_t red, std::uint8_t green, std::uint8_t blue) noexcept {
    return (static_cast<std::uint32_t>(red >> kShift) << (2 * kBitsPerChannel)) |
           (static_cast<std::uint32_t>(green >> kShift) << kBitsPerChannel) |
           static_cast<std::uint32_t>(blue >> kShift);
  }
  PixelClass classify(std::uint8_t red, std::uint8_t green, std::uint8_t blue) const noexcept {
    return static_cast<PixelClass>(table_[index(red, green, blue)]);
  }
  const std::uint8_t* table() const noexcept { return table_.get(); }

 private:
  std::unique_ptr<std::uint8_t[]> table_;
};

}  // namespace vision
}  // namespace tcpest
