// The status values of the frame sources and the JPEG decoder. errno and
// libjpeg's message codes are mapped to these once, at the system boundary.
#pragma once

#include <cstdint>

namespace tcpest {
namespace hal {

enum class CameraError : std::uint8_t {
  kNone = 0,
  kBadArgument,   // a null/invalid view, a zero capacity: our caller's bug
  kNotFound,      // no such file or device
  kIo,            // read()/ioctl() failed for another reason
  kCorrupt,       // the data is not a decodable image (bad marker, bad Huffman data, bad header)
  kTruncated,     // the data ends before the image does
  kWrongSize,     // a valid image whose size is not the configured one
  kUnsupported,   // a valid file in a format we do not take (CMYK JPEG, 4:1:1 Y4M, ...)
  kOutOfMemory,   // the decoder's fixed arena or a fixed buffer is too small
  kEndOfStream,   // no more frames (replay finished)
  kNotReady,      // no frame yet (non-blocking device): try again next cycle
  kDeviceLost,    // the device went away (unplugged, closed by the driver)
};

const char* to_string(CameraError error) noexcept;

}  // namespace hal
}  // namespace tcpest
