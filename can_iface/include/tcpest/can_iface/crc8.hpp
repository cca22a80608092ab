// CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, final XOR 0xFF, not reflected),
// the CRC of the protocol's end-to-end protection (AUTOSAR E2E profile 11
// style). Check value: 0x4B for the ASCII bytes "123456789".
#pragma once

#include <cstddef>
#include <cstdint>

namespace tcpest {
namespace can {

// Continues a CRC over `length` bytes from a raw (not yet final-XORed)
// register value; start with kCrc8Init and finish with crc8_finish.
constexpr std::uint8_t kCrc8Init = 0xFFU;
std::uint8_t crc8_update(std::uint8_t crc, const std::uint8_t* bytes, std::size_t length) noexcept;
inline std::uint8_t crc8_finish(std::uint8_t crc) noexcept { return static_cast<std::uint8_t>(crc ^ 0xFFU); }

// The whole CRC over one buffer.
std::uint8_t crc8_sae_j1850(const std::uint8_t* bytes, std::size_t length) noexcept;

}  // namespace can
}  // namespace tcpest
