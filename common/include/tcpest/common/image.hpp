// Image views shared by the renderer, the frame sources and the vision
// pipeline. A view never owns its pixels: the buffers are allocated once at
// start-up by whoever owns them. Pixels are 8-bit RGB, rows top to bottom,
// pixel (0, 0) centred at the top-left (OpenCV's convention, as model.md).
#pragma once

#include <cstddef>
#include <cstdint>

namespace tcpest {

struct ImageView {
  const std::uint8_t* data = nullptr;  // RGB24
  int width = 0;
  int height = 0;
  std::size_t stride_bytes = 0U;  // bytes from one row to the next (>= 3 * width)

  bool valid() const noexcept {
    return data != nullptr && width > 0 && height > 0 && stride_bytes >= static_cast<std::size_t>(width) * 3U;
  }
  const std::uint8_t* row(int y) const noexcept { return data + static_cast<std::size_t>(y) * stride_bytes; }
};

struct MutableImageView {
  std::uint8_t* data = nullptr;  // RGB24
  int width = 0;
  int height = 0;
  std::size_t stride_bytes = 0U;

  bool valid() const noexcept {
    return data != nullptr && width > 0 && height > 0 && stride_bytes >= static_cast<std::size_t>(width) * 3U;
  }
  std::uint8_t* row(int y) const noexcept { return data + static_cast<std::size_t>(y) * stride_bytes; }
  ImageView view() const noexcept { return ImageView{data, width, height, stride_bytes}; }
};

}  // namespace tcpest
