// Stage 1's per-pixel classifier: the exact L*a*b* Mahalanobis decision of
// ColorModel precomputed at start-up over quantised RGB (kBitsPerChannel bits
// per channel). A cell whose eight corner colours all get the same class
// stores that class; a cell that a decision boundary crosses is marked
// kAmbiguous and its pixels are classified exactly (they are rare: colours
// between classes). 256 KiB, built once; a pixel costs one table read. The
// agreement with the exact classifier over all 2^24 colours is measured by a
// test (docs/vision.md gives the number).
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
  static constexpr std::uint8_t kAmbiguous = 3U;
  // The class, the exact one for colours of ambiguous cells.
  PixelClass classify(std::uint8_t red, std::uint8_t green, std::uint8_t blue) const noexcept {
    const std::uint8_t c = table_[index(red, green, blue)];
    return c == kAmbiguous ? model_.classify(red, green, blue) : static_cast<PixelClass>(c);
  }
  const ColorModel& model() const noexcept { return model_; }
  const std::uint8_t* table() const noexcept { return table_.get(); }

 private:
  std::unique_ptr<std::uint8_t[]> table_;
  ColorModel model_{};
};

}  // namespace vision
}  // namespace tcpest
