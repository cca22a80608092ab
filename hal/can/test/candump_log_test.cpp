#include "tcpest/hal/can/candump_log.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace tcpest {
namespace hal {
namespace {

TEST(CandumpLine, MatchesCandumpLogFormat) {
  can::Frame f;
  f.id = 0x190;
  f.length = 8;
  const std::uint8_t bytes[8] = {0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF};
  for (int i = 0; i < 8; ++i) {
    f.data[i] = bytes[i];
  }
  char line[kCandumpMaxLine];
  const std::size_t n = format_candump_line(f, 1700000000123456, "vcan0", line, sizeof line);
  EXPECT_EQ(std::string(line, n), "(1700000000.123456) vcan0 190#0123456789ABCDEF\n");
  f.id = 0x080;
  f.length = 0;
  EXPECT_GT(format_candump_line(f, 5, "can0", line, sizeof line), 0U);
  EXPECT_STREQ(line, "(0.000005) can0 080#\n");
}

TEST(CandumpLine, RejectsInvalidInput) {
  can::Frame f;
  char line[kCandumpMaxLine];
  f.id = 0x800;
  EXPECT_EQ(format_candump_line(f, 0, "can0", line, sizeof line), 0U);
  f.id = 1;
  f.length = 9;
  EXPECT_EQ(format_candump_line(f, 0, "can0", line, sizeof line), 0U);
  f.length = 1;
  EXPECT_EQ(format_candump_line(f, 0, "", line, sizeof line), 0U);
  EXPECT_EQ(format_candump_line(f, -1, "can0", line, sizeof line), 0U);
  EXPECT_EQ(format_candump_line(f, 0, "can0", line, 10), 0U);
}

TEST(CandumpLogWriter, WritesManyLinesThroughItsBuffer) {
  char path[] = "/tmp/tcpest_candump_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  close(fd);
  CandumpLogWriter writer;
  EXPECT_EQ(writer.write(can::Frame{}, 0).error(), CanBusError::kNotOpen);
  ASSERT_TRUE(writer.open(path, "vcan0").ok());
  for (int i = 0; i < 500; ++i) {
    can::Frame f;
    f.id = 0x710;
    f.length = 1;
    f.data[0] = static_cast<std::uint8_t>(i);
    ASSERT_TRUE(writer.write(f, 1000000LL * i).ok());
  }
  ASSERT_TRUE(writer.close().ok());
  ASSERT_TRUE(writer.close().ok());
  std::ifstream in(path);
  std::string line;
  int count = 0;
  while (std::getline(in, line)) {
    std::ostringstream want;
    char hex[3];
    std::snprintf(hex, sizeof hex, "%02X", count & 0xFF);
    want << "(" << count << ".000000) vcan0 710#" << hex;
    EXPECT_EQ(line, want.str());
    ++count;
  }
  EXPECT_EQ(count, 500);
  std::remove(path);
}

TEST(CandumpLogWriter, OpenFailureIsAnErrorValue) {
  CandumpLogWriter writer;
  EXPECT_FALSE(writer.open("/nonexistent-dir/x.log", "vcan0").ok());
  EXPECT_EQ(writer.open("/tmp/x.log", "a-name-that-is-too-long").error(), CanBusError::kInvalidArgument);
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
