// A classic CAN 2.0A data frame as the protocol sees it: an 11-bit identifier
// and 0..8 data bytes. Extended, remote and error frames never reach the
// protocol layer (the bus backends filter and count them).
#pragma once

#include <array>
#include <cstdint>

namespace tcpest {
namespace can {

constexpr std::uint32_t kMaxStandardId = 0x7FFU;
constexpr std::uint8_t kMaxDataLength = 8U;

struct Frame {
  std::uint32_t id = 0U;    // 11-bit COB-ID
  std::uint8_t length = 0U;  // data length code, 0..8
  std::array<std::uint8_t, kMaxDataLength> data{};
};

inline bool operator==(const Frame& a, const Frame& b) noexcept {
  if (a.id != b.id || a.length != b.length) {
    return false;
  }
  for (std::uint8_t i = 0U; i < a.length && i < kMaxDataLength; ++i) {
    if (a.data[i] != b.data[i]) {
      return false;
    }
  }
  return true;
}
inline bool operator!=(const Frame& a, const Frame& b) noexcept { return !(a == b); }

}  // namespace can
}  // namespace tcpest
