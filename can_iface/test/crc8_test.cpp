#include "tcpest/can_iface/crc8.hpp"

#include <gtest/gtest.h>

#include <cstring>

#include "tcpest/can_iface/messages.hpp"

namespace tcpest {
namespace can {
namespace {

// Verifies: REQ-CAN-004
TEST(Crc8, CatalogueCheckValue) {
  const char* text = "123456789";
  EXPECT_EQ(crc8_sae_j1850(reinterpret_cast<const std::uint8_t*>(text), std::strlen(text)), 0x4BU);
}

// Verifies: REQ-CAN-004
TEST(Crc8, EmptyInputIsInitXorFinal) { EXPECT_EQ(crc8_sae_j1850(nullptr, 0U), 0x00U); }

// Bit-by-bit reference, independent of the table.
std::uint8_t reference_crc(const std::uint8_t* bytes, std::size_t length) {
  std::uint8_t crc = 0xFF;
  for (std::size_t i = 0; i < length; ++i) {
    crc ^= bytes[i];
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x80) ? static_cast<std::uint8_t>((crc << 1) ^ 0x1D) : static_cast<std::uint8_t>(crc << 1);
    }
  }
  return static_cast<std::uint8_t>(crc ^ 0xFF);
}

// Verifies: REQ-CAN-004
TEST(Crc8, MatchesBitwiseReferenceOnAllSingleBytes) {
  for (int value = 0; value < 256; ++value) {
    const auto byte = static_cast<std::uint8_t>(value);
    EXPECT_EQ(crc8_sae_j1850(&byte, 1U), reference_crc(&byte, 1U)) << value;
  }
}

// Verifies: REQ-CAN-004
TEST(Crc8, E2eCoversCobIdLowByteFirstThenBytes0To6) {
  Frame frame;
  frame.id = 0x190;
  frame.length = 8;
  for (std::uint8_t i = 0; i < 8; ++i) {
    frame.data[i] = static_cast<std::uint8_t>(0x11 * (i + 1));
  }
  const std::uint8_t expected_input[9] = {0x90, 0x01, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77};
  EXPECT_EQ(e2e_crc(frame.id, frame), reference_crc(expected_input, sizeof expected_input));
}

}  // namespace
}  // namespace can
}  // namespace tcpest
