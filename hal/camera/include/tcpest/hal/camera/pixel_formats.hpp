// Conversions from the cameras' pixel formats to RGB24 (BT.601). Integer
// arithmetic only, so that every machine gives the same bits. Fixed loops
// over the image; no allocation.
#pragma once

#include <cstddef>
#include <cstdint>

#include "tcpest/common/image.hpp"

namespace tcpest {
namespace hal {

enum class ChromaLayout : std::uint8_t {
  k420,   // one Cb/Cr sample per 2x2 luma block (C420jpeg, C420mpeg2, C420paldv, C420)
  k422,   // one per 2x1
  k444,   // one per pixel
  kMono,  // no chroma
};

enum class YuvRange : std::uint8_t {
  kLimited,  // Y 16..235, C 16..240 (video, ffmpeg's default for YUV output)
  kFull,     // 0..255 (JPEG)
};

// Bytes of one planar frame of that layout.
std::size_t planar_frame_bytes(int width, int height, ChromaLayout layout) noexcept;

// Planar Y, Cb, Cr (Y4M order) to RGB. Chroma is taken from the nearest sample.
void planar_yuv_to_rgb(const std::uint8_t* frame, int width, int height, ChromaLayout layout, YuvRange range,
                       const MutableImageView& out) noexcept;

// Packed YUYV 4:2:2 (V4L2_PIX_FMT_YUYV), `stride_bytes` per source row.
void yuyv_to_rgb(const std::uint8_t* frame, std::size_t stride_bytes, int width, int height, YuvRange range,
                 const MutableImageView& out) noexcept;

// Packed RGB24 with a stride to our view (a row copy).
void copy_rgb(const std::uint8_t* frame, std::size_t stride_bytes, int width, int height,
              const MutableImageView& out) noexcept;

// RGB to planar YUV (for writing test videos and the demo's recordings).
void rgb_to_planar_yuv420(const ImageView& in, YuvRange range, std::uint8_t* frame) noexcept;

}  // namespace hal
}  // namespace tcpest
