#include "tcpest/can_iface/crc8.hpp"

#include <array>

namespace tcpest {
namespace can {
namespace {

constexpr std::uint8_t kPolynomial = 0x1DU;

// Table built at compile time: one lookup per byte, no start-up work.
constexpr std::array<std::uint8_t, 256> make_table() noexcept {
  std::array<std::uint8_t, 256> table{};
  for (std::size_t value = 0U; value < table.size(); ++value) {
    auto crc = static_cast<std::uint8_t>(value);
    for (int bit = 0; bit < 8; ++bit) {
      const bool top = (crc & 0x80U) != 0U;
      crc = static_cast<std::uint8_t>(crc << 1U);
      if (top) {
        crc = static_cast<std::uint8_t>(crc ^ kPolynomial);
      }
    }
    table[value] = crc;
  }
  return table;
}

constexpr std::array<std::uint8_t, 256> kTable = make_table();

}  // namespace

std::uint8_t crc8_update(std::uint8_t crc, const std::uint8_t* bytes, std::size_t length) noexcept {
  for (std::size_t i = 0U; i < length; ++i) {
    crc = kTable[static_cast<std::uint8_t>(crc ^ bytes[i])];
  }
  return crc;
}

std::uint8_t crc8_sae_j1850(const std::uint8_t* bytes, std::size_t length) noexcept {
  return crc8_finish(crc8_update(kCrc8Init, bytes, length));
}

}  // namespace can
}  // namespace tcpest
