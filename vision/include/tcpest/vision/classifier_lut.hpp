// Stage 1's per-pixel classifier: the exact L*a*b* Mahalanobis decision of
// ColorModel precomputed at start-up over quantised RGB (kBitsPerChannel bits
// per channel, 256 KiB). A cell whose eight corner colours all get the same
// class stores that class; a cell that a decision boundary crosses is marked
// kAmbiguous and gets a second-level block holding the exact class of each of
// its 4 x 4 x 4 colours. A pixel costs one table read (two in ambiguous
// cells). The agreement with the exact classifier over all 2^24 colours is
// measured by a test (docs/vision.md gives the number).
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
    const std::uint32_t cell = index(red, green, blue);
    const std::uint8_t c = table_[cell];
    return c == kAmbiguous ? static_cast<PixelClass>(fine(cell, red, green, blue)) : static_cast<PixelClass>(c);
  }
  // The class of a colour of an ambiguous cell, from its block.
  std::uint8_t fine(std::uint32_t cell, std::uint8_t red, std::uint8_t green, std::uint8_t blue) const noexcept {
    constexpr std::uint32_t kMask = (1U << kShift) - 1U;
    const std::uint32_t offset = ((red & kMask) << (2 * kShift)) | ((green & kMask) << kShift) | (blue & kMask);
    return blocks_[static_cast<std::size_t>(block_of_cell_[cell]) * kBlockSize + offset];
  }
  std::uint32_t ambiguous_cells() const noexcept { return block_count_; }
  static constexpr std::size_t kBlockSize = 1U << (3 * kShift);
  const ColorModel& model() const noexcept { return model_; }
  const std::uint8_t* table() const noexcept { return table_.get(); }

 private:
  std::unique_ptr<std::uint8_t[]> table_;
  std::unique_ptr<std::uint32_t[]> block_of_cell_;  // for ambiguous cells
  std::unique_ptr<std::uint8_t[]> blocks_;
  std::uint32_t block_count_ = 0U;
  ColorModel model_{};
};

}  // namespace vision
}  // namespace tcpest
