#include "tcpest/hal/can/candump_log.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace tcpest {
namespace hal {
namespace {

// Verifies: REQ-HAL-005
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

// Verifies: REQ-HAL-005
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

// What the writer formats, the reader reads back; anything else is refused.
// Verifies: REQ-HAL-005
TEST(CandumpLine, ReadsBackWhatItWrites) {
  can::Frame f;
  f.id = 0x710;
  f.length = 1;
  f.data[0] = 0x7F;
  char line[kCandumpMaxLine];
  ASSERT_GT(format_candump_line(f, 1700000000123456, "vcan0", line, sizeof line), 0U);
  can::Frame got;
  std::int64_t t_us = 0;
  ASSERT_TRUE(parse_candump_line(line, got, t_us));
  EXPECT_EQ(got, f);
  EXPECT_EQ(t_us, 1700000000123456);
  ASSERT_TRUE(parse_candump_line("(0.000005) can0 080#", got, t_us));
  EXPECT_EQ(got.length, 0U);
  EXPECT_EQ(t_us, 5);
  ASSERT_TRUE(parse_candump_line("(12.500000) sim0 190#cefa6d02d81117fa\r\n", got, t_us));
  EXPECT_EQ(got.length, 8U);
  EXPECT_EQ(got.data[7], 0xFAU);
  for (const char* bad : {"", "190#00", "(1.5) vcan0 190#00", "(1.000000) vcan0 12345678#00",
                          "(1.000000) vcan0 190#R", "(1.000000) vcan0 190##0011", "(1.000000) vcan0 190#001",
                          "(1.000000) vcan0 190#000102030405060708", "(1.000000)  190#00",
                          "(1.000000) vcan0 800#00"}) {
    EXPECT_FALSE(parse_candump_line(bad, got, t_us)) << bad;
  }
  EXPECT_FALSE(parse_candump_line(nullptr, got, t_us));
}

// Verifies: REQ-HAL-005
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

// Verifies: REQ-HAL-005
TEST(CandumpLogWriter, OpenFailureIsAnErrorValue) {
  CandumpLogWriter writer;
  EXPECT_FALSE(writer.open("/nonexistent-dir/x.log", "vcan0").ok());
  EXPECT_EQ(writer.open("/tmp/x.log", "a-name-that-is-too-long").error(), CanBusError::kInvalidArgument);
}

// Every failed write(2) is counted with its errno, also the one close()'s
// flush makes (a short run's lines are all still buffered then): a full
// disk used to lose the whole log with nothing counted.
// Verifies: REQ-HAL-005
TEST(CandumpLogWriter, WriteErrorsAreCountedAlsoAtClose) {
  if (::access("/dev/full", W_OK) != 0) {
    GTEST_SKIP() << "no /dev/full here";
  }
  CandumpLogWriter writer;
  ASSERT_TRUE(writer.open("/dev/full", "sim0").ok());
  can::Frame f;
  f.id = 0x190;
  f.length = 8;
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(writer.write(f, 1000000LL * i).ok());  // buffered: no write(2) yet
  }
  EXPECT_EQ(writer.write_errors(), 0U);
  const auto closed = writer.close();
  ASSERT_FALSE(closed.ok());
  EXPECT_EQ(writer.write_errors(), 1U);
  EXPECT_EQ(writer.first_errno(), ENOSPC);
  EXPECT_EQ(writer.lines_written(), 20U);
  EXPECT_EQ(writer.lines_lost(), 20U);
  // A long run: every failed flush of the buffer counts; write() says so to its caller.
  ASSERT_TRUE(writer.open("/dev/full", "sim0").ok());
  EXPECT_EQ(writer.write_errors(), 0U);  // a new file, a new count
  int failed_writes = 0;
  for (int i = 0; i < 500; ++i) {
    failed_writes += writer.write(f, 1000000LL * i).ok() ? 0 : 1;
  }
  EXPECT_GT(failed_writes, 0);
  EXPECT_EQ(writer.write_errors(), static_cast<std::uint64_t>(failed_writes));
  EXPECT_FALSE(writer.close().ok());
  EXPECT_EQ(writer.write_errors(), static_cast<std::uint64_t>(failed_writes) + 1U);
  EXPECT_EQ(writer.first_errno(), ENOSPC);
  EXPECT_EQ(writer.lines_lost(), writer.lines_written());  // nothing reached the file
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
