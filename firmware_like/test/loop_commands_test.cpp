// tcpest run end to end on a small raw clip: exit codes and the candump log.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.hpp"
#include "command_test_support.hpp"
#include "tcpest/hal/camera/file_sources.hpp"

namespace tcpest {
namespace cli {
namespace {

using command_test::count_of;
using command_test::slurp;

int run(std::vector<std::string> words) { return command_test::run_command(cmd_run, std::move(words)); }

std::string temp_dir() { return command_test::fresh_dir("run"); }

void write_clip(const std::string& path, int w, int h, int frames) {
  hal::Y4mWriter writer;
  ASSERT_TRUE(writer.open(path.c_str(), w, h, 25, 1).ok());
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(w * h * 3), 90U);
  for (int i = 0; i < frames; ++i) {
    ASSERT_TRUE(writer.write(ImageView{rgb.data(), w, h, static_cast<std::size_t>(w) * 3U}).ok());
  }
  ASSERT_TRUE(writer.close().ok());
}

// Verifies: REQ-HAL-005
TEST(RunCommand, ReplaysAClipOntoTheSimulatedBusAndLogsInCandumpFormat) {
  const std::string dir = temp_dir();
  write_clip(dir + "/clip.y4m", 720, 576, 5);
  const std::string log = dir + "/can.log";
  EXPECT_EQ(run({"run", "--source", dir + "/clip.y4m", "--bus", "log:" + log, "--no-pacing", "--quiet",
                 "--start-operational"}),
            kExitOk);
  const std::string s = slurp(log);
  EXPECT_NE(s.find(" sim0 710#00\n"), std::string::npos) << s;  // boot-up
  EXPECT_EQ(count_of(s, " sim0 190#"), 5U);                      // one TCP message per frame
}

// Without --start-operational (or can.start_operational) the node waits in
// pre-operational for an NMT start that no one sends on this bus: boot-up
// and heartbeats, no PDO (CiA 301's default, docs/can-protocol.md).
// Verifies: REQ-LOOP-016
TEST(RunCommand, WaitsForTheNmtStartByDefault) {
  const std::string dir = temp_dir();
  write_clip(dir + "/clip.y4m", 720, 576, 5);
  const std::string log = dir + "/can.log";
  EXPECT_EQ(run({"run", "--source", dir + "/clip.y4m", "--bus", "log:" + log, "--no-pacing", "--quiet"}), kExitOk);
  const std::string s = slurp(log);
  EXPECT_NE(s.find(" sim0 710#00\n"), std::string::npos) << s;  // boot-up
  EXPECT_EQ(count_of(s, " sim0 190#"), 0U) << s;
  // The old key is refused with its new name.
  const std::string cfg = dir + "/old.yaml";
  {
    std::ofstream out(cfg);
    out << "can:\n  autostart: true\n";
  }
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"run", "--config", cfg, "--source", dir + "/clip.y4m", "--bus", "sim", "--quiet"}), kExitConfig);
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("can.start_operational"), std::string::npos) << said;
}

// `tcpest listen` on what `tcpest run` logged: every frame decoded, no E2E
// failure; one flipped bit in a TCP frame is refused (bad CRC) and fails the
// listen (exit 1); a line that is not candump's is named and exits 3.
// Verifies: REQ-CAN-016
TEST(ListenCommand, ChecksARunsLogAndRefusesACorruptedFrame) {
  const std::string dir = temp_dir();
  write_clip(dir + "/clip.y4m", 720, 576, 6);
  const std::string log = dir + "/can.log";
  ASSERT_EQ(run({"run", "--source", dir + "/clip.y4m", "--bus", "log:" + log, "--no-pacing", "--quiet",
                 "--start-operational"}),
            kExitOk);
  testing::internal::CaptureStdout();
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--bus", "log:" + log}), kExitOk);
  std::string printed = testing::internal::GetCapturedStdout();
  EXPECT_EQ(count_of(printed, ") tcp "), 6U) << printed;
  EXPECT_EQ(count_of(printed, ") quality "), 6U) << printed;
  EXPECT_NE(printed.find(") heartbeat  boot-up\n"), std::string::npos) << printed;
  EXPECT_NE(printed.find("E2E failures 0 "), std::string::npos) << printed;
  EXPECT_NE(printed.find("counter jumps 0, "), std::string::npos) << printed;
  EXPECT_NE(printed.find("boot-ups 1, "), std::string::npos) << printed;  // too short a run for a heartbeat

  std::string text = slurp(log);
  const std::size_t tcp = text.find(" sim0 190#");
  ASSERT_NE(tcp, std::string::npos);
  char& digit = text[tcp + 11U];  // the low nibble of byte 0
  digit = digit == '0' ? '1' : '0';
  const std::string bad_log = dir + "/bad.log";
  {
    std::ofstream out(bad_log);
    out << text;
  }
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--log", bad_log, "--json"}), kExitFailure);
  printed = testing::internal::GetCapturedStdout();
  std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(printed.find("\"id\": \"190\", \"error\": \"bad CRC\""), std::string::npos) << printed;
  EXPECT_NE(printed.find("\"e2e_failures\": 1,"), std::string::npos) << printed;
  EXPECT_NE(said.find("1 E2E failure(s)"), std::string::npos) << said;

  {
    std::ofstream out(bad_log, std::ios::app);
    out << "this is not candump\n";
  }
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--log", bad_log, "--quiet"}), kExitConfig);
  static_cast<void>(testing::internal::GetCapturedStdout());
  said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("bad.log, line "), std::string::npos) << said;

  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--help"}), kExitOk);
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen"}), kExitUsage);
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--log", log, "--bus", "vcan0"}), kExitUsage);
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--log", log, "--node-id", "0"}), kExitUsage);
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--bus", "sim"}), kExitUsage);
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--log", log, "stray"}), kExitUsage);
  testing::internal::CaptureStderr();
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--log", dir + "/missing.log"}), kExitConfig);
  static_cast<void>(testing::internal::GetCapturedStderr());
  // An interface that is not there (or no CAN in this kernel): said, exit 1.
  testing::internal::CaptureStderr();
  EXPECT_EQ(command_test::run_command(cmd_listen, {"listen", "--bus", "no-such-can0", "--seconds", "0.1"}),
            kExitFailure);
  said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("CAN interface no-such-can0: "), std::string::npos) << said;
}

// The loop as deployed, paced at the source's 25 Hz (no --no-pacing) and
// not quiet: a status line once a second, then the summary, one TCP
// message per frame. (The simulated camera, the default source, renders
// its sequence first; the demo's test runs it.)
TEST(RunCommand, PacedRunPrintsAStatusLineEverySecond) {
  const std::string dir = temp_dir();
  write_clip(dir + "/clip.y4m", 720, 576, 30);
  const std::string log = dir + "/can.log";
  testing::internal::CaptureStdout();
  const int code = run({"run", "--source", dir + "/clip.y4m", "--bus", "log:" + log, "--start-operational"});
  const std::string printed = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, kExitOk) << printed;
  EXPECT_NE(printed.find("(720x576, y4m)"), std::string::npos) << printed;
  EXPECT_NE(printed.find("trigger frame\n"), std::string::npos) << printed;  // paced: no "(no pacing)"
  EXPECT_NE(printed.find("[operational] frames "), std::string::npos) << printed;  // 30 frames at 25 Hz: 1.2 s
  // The 31st cycle only finds the clip ended.
  EXPECT_NE(printed.find("cycles 31, frames 30, dropped frames 0"), std::string::npos) << printed;
  EXPECT_EQ(count_of(slurp(log), " sim0 190#"), 30U);
}

std::vector<std::uint8_t> bytes_of(const std::string& path) {
  const std::string text = slurp(path);
  return std::vector<std::uint8_t>(text.begin(), text.end());
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// A damaged recording: one bad frame tag costs one frame; a header followed
// by junk stops the run with the reason and exit 3 (it used to be millions of
// dropped cycles, exit 0 and nothing said); so does a colour space the loop
// cannot read, or a file with no frame.
// Verifies: REQ-ERR-006
TEST(RunCommand, ADamagedRecordingDropsAFrameOrStopsWithTheReason) {
  const std::string dir = temp_dir();
  write_clip(dir + "/clip.y4m", 720, 576, 4);
  std::vector<std::uint8_t> clip = bytes_of(dir + "/clip.y4m");
  const std::size_t header = std::string(clip.begin(), clip.end()).find('\n') + 1U;
  clip[header + 4U] = 'X';  // the first FRAME tag -> FRAMX
  write_bytes(dir + "/framx.y4m", clip);
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"run", "--source", dir + "/framx.y4m", "--bus", "sim", "--no-pacing", "--quiet"}), kExitOk);
  std::string printed = testing::internal::GetCapturedStdout();
  EXPECT_NE(printed.find("frames 3, dropped frames 1"), std::string::npos) << printed;

  std::vector<std::uint8_t> junk(clip.begin(), clip.begin() + static_cast<std::ptrdiff_t>(header));
  junk.resize(header + 4U * 1024U * 1024U, 0x5AU);
  write_bytes(dir + "/junk.y4m", junk);
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"run", "--source", dir + "/junk.y4m", "--bus", "sim", "--no-pacing", "--quiet"}), kExitConfig);
  printed = testing::internal::GetCapturedStdout();
  std::string errors = testing::internal::GetCapturedStderr();
  EXPECT_NE(printed.find("frames 0, dropped frames 1"), std::string::npos) << printed;
  EXPECT_NE(errors.find("damaged stream"), std::string::npos) << errors;

  junk.resize(header);
  write_bytes(dir + "/empty.y4m", junk);
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"run", "--source", dir + "/empty.y4m", "--bus", "sim", "--quiet"}), kExitConfig);
  errors = testing::internal::GetCapturedStderr();
  EXPECT_NE(errors.find("no frame after the header"), std::string::npos) << errors;

  const std::string p10 = "YUV4MPEG2 W720 H576 F25:1 Ip C420p10\n";
  write_bytes(dir + "/p10.y4m", std::vector<std::uint8_t>(p10.begin(), p10.end()));
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"run", "--source", dir + "/p10.y4m", "--bus", "sim", "--quiet"}), kExitConfig);
  errors = testing::internal::GetCapturedStderr();
  EXPECT_NE(errors.find("'C420p10'"), std::string::npos) << errors;
}

// Every log write failing (a full disk) used to end in exit 0 and
// "published 20 (errors 0)": now the summary counts the write errors and the
// run exits 1 (docs/cli.md: a write failed).
// Verifies: REQ-HAL-005
TEST(RunCommand, ALogThatCannotBeWrittenIsReportedAndFailsTheRun) {
  if (::access("/dev/full", W_OK) != 0) {
    GTEST_SKIP() << "no /dev/full here";
  }
  const std::string dir = temp_dir();
  write_clip(dir + "/clip.y4m", 720, 576, 3);
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  const int code = run({"run", "--source", dir + "/clip.y4m", "--bus", "log:/dev/full", "--no-pacing", "--quiet"});
  const std::string printed = testing::internal::GetCapturedStdout();
  const std::string errors = testing::internal::GetCapturedStderr();
  EXPECT_EQ(code, kExitFailure) << printed << errors;
  EXPECT_NE(printed.find("candump log /dev/full: "), std::string::npos) << printed;
  EXPECT_EQ(printed.find("write errors 0"), std::string::npos) << printed;
  EXPECT_NE(errors.find("No space left on device"), std::string::npos) << errors;
  // A log that is written: said so, exit 0.
  testing::internal::CaptureStdout();
  EXPECT_EQ(run({"run", "--source", dir + "/clip.y4m", "--bus", "log:" + dir + "/can.log", "--no-pacing", "--quiet"}),
            kExitOk);
  const std::string good = testing::internal::GetCapturedStdout();
  EXPECT_NE(good.find("lost 0, write errors 0"), std::string::npos) << good;
}

// Verifies: REQ-ERR-004
TEST(RunCommand, ExitCodes) {
  const std::string dir = temp_dir();
  EXPECT_EQ(run({"run", "--bogus"}), kExitUsage);
  EXPECT_EQ(run({"run", "--frames", "-3"}), kExitUsage);
  EXPECT_EQ(run({"run", "--frames", "18446744073709551615"}), kExitUsage);  // was -1 after the conversion: no limit
  EXPECT_EQ(run({"run", "--frames", "1e3"}), kExitUsage);
  EXPECT_EQ(run({"run", "--source", dir + "/missing", "--quiet"}), kExitConfig);
  write_clip(dir + "/small.y4m", 64, 48, 1);
  EXPECT_EQ(run({"run", "--source", dir + "/small.y4m", "--quiet"}), kExitConfig);  // not the camera's size
  {
    std::ofstream cfg(dir + "/bad.yaml");
    cfg << "loop:\n  trigger: frame\n  peroid_us: 100\n";
  }
  EXPECT_EQ(run({"run", "--config", dir + "/bad.yaml", "--quiet"}), kExitConfig);
  EXPECT_EQ(run({"run", "--source", dir + "/missing.y4m", "--bus", "no-such-can0", "--quiet"}), kExitConfig);
  write_clip(dir + "/ok.y4m", 720, 576, 1);
  EXPECT_EQ(run({"run", "--source", dir + "/ok.y4m", "--bus", "no-such-can0", "--quiet"}), kExitFailure);
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
