// tcpest demo (the README's main job) and tcpest bench end to end, short:
// the outputs a person opens, the accuracy counted over frames, the
// timing tables, and bad arguments refused with the documented exit codes.
#include <gtest/gtest.h>

#include <dirent.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.hpp"
#include "command_test_support.hpp"

namespace tcpest {
namespace cli {
namespace {

using command_test::count_of;
using command_test::slurp;

int run(int (*command)(int, char**), std::vector<std::string> words) {
  return command_test::run_command(command, std::move(words));
}

std::string temp_dir() { return command_test::fresh_dir("demo"); }

std::vector<std::string> files_in(const std::string& dir) {
  std::vector<std::string> names;
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) {
    return names;
  }
  for (const dirent* e = ::readdir(d); e != nullptr; e = ::readdir(d)) {
    const std::string name = e->d_name;
    if (name != "." && name != "..") {
      names.push_back(name);
    }
  }
  static_cast<void>(::closedir(d));  // read-only listing
  return names;
}

// 12 frames on the simulated bus (the machine's vcan0, if any, is not
// used): every output is written, one cycles.csv row per cycle, the TCP
// sent once per frame, and the accuracy counts the 12 frames, not the
// 13th cycle that finds the sequence ended.
TEST(DemoCommand, RunsTheLoopOnTheSimulatedBusAndWritesItsOutputs) {
  const std::string dir = temp_dir() + "/out";
  testing::internal::CaptureStdout();
  const int code =
      run(cmd_demo, {"demo", "--out", dir, "--frames", "12", "--bus", "sim", "--overlay-every", "5"});
  const std::string printed = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, kExitOk) << printed;
  EXPECT_NE(printed.find("frames 12, with an estimate (valid or degraded) "), std::string::npos) << printed;
  EXPECT_NE(printed.find("cycles 13, frames 12, dropped frames 0"), std::string::npos) << printed;
  EXPECT_NE(printed.find("3-D error (mm): median "), std::string::npos) << printed;
  EXPECT_NE(printed.find("overruns "), std::string::npos) << printed;
  EXPECT_NE(printed.find("latency frame -> CAN send (ms): p50 "), std::string::npos) << printed;

  const std::string log = slurp(dir + "/can.log");
  EXPECT_NE(log.find(" sim0 710#00\n"), std::string::npos) << log;  // the node's boot-up
  EXPECT_EQ(count_of(log, " sim0 190#"), 12U) << log;              // one TCP message per frame
  const std::string csv = slurp(dir + "/cycles.csv");
  EXPECT_EQ(csv.rfind("cycle,frame,t_ms,status,", 0U), 0U) << csv.substr(0U, 200U);
  EXPECT_EQ(count_of(csv, "\n"), 1U + 13U);  // the header and one row per cycle
  for (const char* svg : {"/tcp.svg", "/latency.svg"}) {
    const std::string text = slurp(dir + svg);
    EXPECT_EQ(text.rfind("<svg ", 0U), 0U) << svg;
    EXPECT_NE(text.find("</svg>\n"), std::string::npos) << svg;
  }
  std::vector<std::string> overlays = files_in(dir + "/overlays");
  std::sort(overlays.begin(), overlays.end());
  EXPECT_EQ(overlays, (std::vector<std::string>{"frame_0000.png", "frame_0005.png", "frame_0010.png"}));
}

// Verifies: REQ-ERR-004
TEST(DemoCommand, BadArgumentsAreRefusedWithTheirExitCodes) {
  const std::string dir = temp_dir();
  EXPECT_EQ(run(cmd_demo, {"demo", "--help"}), kExitOk);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--frames", "abc"}), kExitUsage);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--frames", "0"}), kExitUsage);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--seed", "-3"}), kExitUsage);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--overlay-every", "4294967296"}), kExitUsage);  // wrapped to 0
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--overlay-every", "100001"}), kExitUsage);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--frames", "100001"}), kExitUsage);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "stray"}), kExitUsage);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/a", "--no-such-option"}), kExitUsage);
  // An output directory that cannot be made, a calibration that cannot be read.
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/missing/parent/out", "--frames", "2", "--bus", "sim"}),
            kExitConfig);
  EXPECT_EQ(run(cmd_demo, {"demo", "--out", dir + "/b", "--frames", "2", "--bus", "sim", "--calib",
                           dir + "/none.yaml"}),
            kExitConfig);
}

// The throughput run's table and the jitter comparison side by side, both
// short.
TEST(BenchCommand, PrintsTheStepsPercentilesAndTheJitterComparison) {
  testing::internal::CaptureStdout();
  const int code = run(cmd_bench, {"bench", "--frames", "6", "--dataset", "2", "--jitter-seconds", "0.2",
                                   "--period-us", "20000"});
  const std::string printed = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, kExitOk) << printed;
  EXPECT_NE(printed.find("== throughput, PAL 720x576: 6 cycles"), std::string::npos) << printed;
  for (const char* step : {"\nacquire ", "\nclassify ", "\ninterpret ", "\nborders ", "\ncorners ", "\nsolve ",
                           "\nrefine ", "\npublish ", "\nhousekeeping ", "\ntotal "}) {
    EXPECT_NE(printed.find(step), std::string::npos) << step << "\n" << printed;
  }
  EXPECT_NE(printed.find("bare clock_nanosleep wake-up"), std::string::npos) << printed;
  EXPECT_NE(printed.find("tcpest loop CAN send (TCP frame)"), std::string::npos) << printed;
  EXPECT_NE(printed.find("ratio p99.9 loop / bare: "), std::string::npos) << printed;
}

// Verifies: REQ-ERR-004
TEST(BenchCommand, BadArgumentsAreRefusedWithTheirExitCodes) {
  EXPECT_EQ(run(cmd_bench, {"bench", "--help"}), kExitOk);
  EXPECT_EQ(run(cmd_bench, {"bench", "--frames", "0"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--dataset", "0"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--dataset", "10001"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--period-us", "999"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--jitter-seconds", "-1"}), kExitUsage);
  // Past what the conversions after the check can hold: refused, not wrapped or undefined.
  EXPECT_EQ(run(cmd_bench, {"bench", "--frames", "1", "--dataset", "1", "--jitter-seconds", "1e308"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--jitter-seconds", "86401"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--period-us", "18446744073709551615"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--frames", "18446744073709551616"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "stray"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--frames", "2", "--dataset", "1", "--jitter-seconds", "0", "--calib",
                            "/nonexistent/camera.yaml"}),
            kExitConfig);
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
