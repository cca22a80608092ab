#include "tcpest/hal/camera/pixel_formats.hpp"

#include <cstring>

namespace tcpest {
namespace hal {

namespace {

std::uint8_t clamp_u8(int value) noexcept {
  if (value < 0) {
    return 0U;
  }
  if (value > 255) {
    return 255U;
  }
  return static_cast<std::uint8_t>(value);
}

// BT.601 in 16.16 fixed point. Limited range scales Y by 255/219 and C by 255/224.
struct YuvCoefficients {
  int y_offset;
  int y_scale;
  int cr_to_r;
  int cb_to_g;
  int cr_to_g;
  int cb_to_b;
};

constexpr YuvCoefficients kLimited{16, 76309, 104597, 25675, 53279, 132201};
constexpr YuvCoefficients kFull{0, 65536, 91881, 22554, 46802, 116130};

inline void yuv_pixel(const YuvCoefficients& k, int y, int cb, int cr, std::uint8_t* rgb) noexcept {
  const int luma = (y - k.y_offset) * k.y_scale + 32768;
  const int u = cb - 128;
  const int v = cr - 128;
  rgb[0] = clamp_u8((luma + k.cr_to_r * v) >> 16);
  rgb[1] = clamp_u8((luma - k.cb_to_g * u - k.cr_to_g * v) >> 16);
  rgb[2] = clamp_u8((luma + k.cb_to_b * u) >> 16);
}

const YuvCoefficients& coefficients(YuvRange range) noexcept { return range == YuvRange::kFull ? kFull : kLimited; }

}  // namespace

std::size_t planar_frame_bytes(int width, int height, ChromaLayout layout) noexcept {
  const auto w = static_cast<std::size_t>(width);
  const auto h = static_cast<std::size_t>(height);
  const std::size_t luma = w * h;
  switch (layout) {
    case ChromaLayout::k420:
      return luma + 2U * ((w + 1U) / 2U) * ((h + 1U) / 2U);
    case ChromaLayout::k422:
      return luma + 2U * ((w + 1U) / 2U) * h;
    case ChromaLayout::k444:
      return 3U * luma;
    case ChromaLayout::kMono:
      return luma;
  }
  return luma;
}

void planar_yuv_to_rgb(const std::uint8_t* frame, int width, int height, ChromaLayout layout, YuvRange range,
                       const MutableImageView& out) noexcept {
  const YuvCoefficients& k = coefficients(range);
  const auto w = static_cast<std::size_t>(width);
  const auto h = static_cast<std::size_t>(height);
  std::size_t chroma_w = w;
  std::size_t chroma_h = h;
  int shift_x = 0;
  int shift_y = 0;
  if (layout == ChromaLayout::k420) {
    chroma_w = (w + 1U) / 2U;
    chroma_h = (h + 1U) / 2U;
    shift_x = 1;
    shift_y = 1;
  } else if (layout == ChromaLayout::k422) {
    chroma_w = (w + 1U) / 2U;
    shift_x = 1;
  }
  const std::uint8_t* plane_y = frame;
  const std::uint8_t* plane_cb = frame + w * h;
  const std::uint8_t* plane_cr = plane_cb + chroma_w * chroma_h;
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row_y = plane_y + static_cast<std::size_t>(y) * w;
    const std::size_t chroma_row = static_cast<std::size_t>(y >> shift_y) * chroma_w;
    std::uint8_t* dst = out.row(y);
    for (int x = 0; x < width; ++x) {
      int cb = 128;
      int cr = 128;
      if (layout != ChromaLayout::kMono) {
        const std::size_t c = chroma_row + static_cast<std::size_t>(x >> shift_x);
        cb = plane_cb[c];
        cr = plane_cr[c];
      }
      yuv_pixel(k, row_y[x], cb, cr, dst + 3 * x);
    }
  }
}

void yuyv_to_rgb(const std::uint8_t* frame, std::size_t stride_bytes, int width, int height, YuvRange range,
                 const MutableImageView& out) noexcept {
  const YuvCoefficients& k = coefficients(range);
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* src = frame + static_cast<std::size_t>(y) * stride_bytes;
    std::uint8_t* dst = out.row(y);
    for (int x = 0; x + 1 < width; x += 2) {
      const int cb = src[2 * x + 1];
      const int cr = src[2 * x + 3];
      yuv_pixel(k, src[2 * x], cb, cr, dst + 3 * x);
      yuv_pixel(k, src[2 * x + 2], cb, cr, dst + 3 * (x + 1));
    }
    if ((width & 1) != 0) {
      const int x = width - 1;
      yuv_pixel(k, src[2 * x], src[2 * x + 1], 128, dst + 3 * x);
    }
  }
}

void copy_rgb(const std::uint8_t* frame, std::size_t stride_bytes, int width, int height,
              const MutableImageView& out) noexcept {
  const std::size_t row_bytes = static_cast<std::size_t>(width) * 3U;
  for (int y = 0; y < height; ++y) {
    std::memcpy(out.row(y), frame + static_cast<std::size_t>(y) * stride_bytes, row_bytes);
  }
}

void rgb_to_planar_yuv420(const ImageView& in, YuvRange range, std::uint8_t* frame) noexcept {
  const auto w = static_cast<std::size_t>(in.width);
  const auto h = static_cast<std::size_t>(in.height);
  const std::size_t cw = (w + 1U) / 2U;
  const std::size_t ch = (h + 1U) / 2U;
  std::uint8_t* plane_y = frame;
  std::uint8_t* plane_cb = frame + w * h;
  std::uint8_t* plane_cr = plane_cb + cw * ch;
  const bool full = range == YuvRange::kFull;
  // BT.601, 16.16 fixed point.
  const int ky_r = full ? 19595 : 16829;
  const int ky_g = full ? 38470 : 33039;
  const int ky_b = full ? 7471 : 6416;
  const int y_off = full ? 0 : 16;
  const int kc_scale_num = full ? 256 : 224;  // chroma excursion per 256
  for (int y = 0; y < in.height; ++y) {
    const std::uint8_t* src = in.row(y);
    for (int x = 0; x < in.width; ++x) {
      const int r = src[3 * x];
      const int g = src[3 * x + 1];
      const int b = src[3 * x + 2];
      plane_y[static_cast<std::size_t>(y) * w + static_cast<std::size_t>(x)] =
          clamp_u8(((ky_r * r + ky_g * g + ky_b * b + 32768) >> 16) + y_off);
    }
  }
  for (std::size_t cy = 0; cy < ch; ++cy) {
    for (std::size_t cx = 0; cx < cw; ++cx) {
      int sum_r = 0;
      int sum_g = 0;
      int sum_b = 0;
      int n = 0;
      for (std::size_t dy = 0; dy < 2U; ++dy) {
        for (std::size_t dx = 0; dx < 2U; ++dx) {
          const std::size_t px = 2U * cx + dx;
          const std::size_t py = 2U * cy + dy;
          if (px < w && py < h) {
            const std::uint8_t* p = in.row(static_cast<int>(py)) + 3U * px;
            sum_r += p[0];
            sum_g += p[1];
            sum_b += p[2];
            ++n;
          }
        }
      }
      const int r = sum_r / n;
      const int g = sum_g / n;
      const int b = sum_b / n;
      // Cb = 128 + s (-0.168736 R - 0.331264 G + 0.5 B), Cr = 128 + s (0.5 R - 0.418688 G - 0.081312 B)
      const int cb = (-11059 * r - 21709 * g + 32768 * b) * kc_scale_num / 256;
      const int cr = (32768 * r - 27439 * g - 5329 * b) * kc_scale_num / 256;
      plane_cb[cy * cw + cx] = clamp_u8(128 + ((cb + 32768) >> 16));
      plane_cr[cy * cw + cx] = clamp_u8(128 + ((cr + 32768) >> 16));
    }
  }
}

}  // namespace hal
}  // namespace tcpest
