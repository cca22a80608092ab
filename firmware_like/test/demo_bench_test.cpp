// tcpest demo (the README's main job) and tcpest bench end to end, short:
// the outputs a person opens, the accuracy counted over frames, the
// timing tables, and bad arguments refused with the documented exit codes.
#include <gtest/gtest.h>

#include <dirent.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.hpp"
#include "cli/heap_probe.hpp"
#include "command_test_support.hpp"
#include "tcpest/can_iface/receiver.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/test/alloc_counter.hpp"

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

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, separator)) {
    parts.push_back(part);
  }
  return parts;
}

// The number after `"key": ` in a JSON line (the listener's flat objects).
double json_number(const std::string& line, const std::string& key) {
  const std::size_t at = line.find("\"" + key + "\": ");
  EXPECT_NE(at, std::string::npos) << key << " in " << line;
  return at == std::string::npos ? std::nan("") : std::stod(line.substr(at + key.size() + 4U));
}

std::string json_text(const std::string& line, const std::string& key) {
  const std::size_t at = line.find("\"" + key + "\": \"");
  EXPECT_NE(at, std::string::npos) << key << " in " << line;
  if (at == std::string::npos) {
    return "";
  }
  const std::size_t from = at + key.size() + 5U;
  return line.substr(from, line.find('"', from) - from);
}

// The controllers' side on the demo's own traffic: `tcpest listen --log`
// and can::Receiver read the demo's can.log with no E2E failure, no counter
// jump, and the TCP values and statuses the loop wrote in cycles.csv.
// Verifies: REQ-CAN-016, REQ-LOOP-017
TEST(ListenCommand, DecodesTheDemosLogAsTheLoopPublishedIt) {
  const std::string dir = temp_dir() + "/out";
  testing::internal::CaptureStdout();
  const int demo = run(cmd_demo, {"demo", "--out", dir, "--frames", "8", "--bus", "sim", "--overlay-every", "0"});
  static_cast<void>(testing::internal::GetCapturedStdout());
  ASSERT_EQ(demo, kExitOk);
  const std::string log = dir + "/can.log";

  // The loop's record of what it published, one row per cycle.
  const std::vector<std::string> rows = split(slurp(dir + "/cycles.csv"), '\n');
  ASSERT_GT(rows.size(), 8U);
  const std::vector<std::string> header = split(rows[0], ',');
  auto column = [&header](const char* name) {
    const auto at = std::find(header.begin(), header.end(), name);
    EXPECT_NE(at, header.end()) << name;
    return static_cast<std::size_t>(at - header.begin());
  };
  const std::size_t status_col = column("status");
  const std::size_t x_col = column("tcp_x_mm");
  const std::size_t used_col = column("corners_used");
  const std::size_t detected_col = column("corners_detected");

  testing::internal::CaptureStdout();
  const int code = run(cmd_listen, {"listen", "--log", log, "--json"});
  const std::string printed = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, kExitOk) << printed;
  std::vector<std::string> tcp_lines;
  std::vector<std::string> quality_lines;
  std::string summary;
  for (const std::string& line : split(printed, '\n')) {
    if (line.find("\"msg\": \"tcp\"") != std::string::npos) {
      tcp_lines.push_back(line);
    } else if (line.find("\"msg\": \"quality\"") != std::string::npos) {
      quality_lines.push_back(line);
    } else if (line.find("\"msg\": \"summary\"") != std::string::npos) {
      summary = line;
    }
    EXPECT_EQ(line.find("\"error\""), std::string::npos) << line;
  }
  EXPECT_EQ(json_number(summary, "e2e_failures"), 0.0) << summary;
  EXPECT_EQ(json_number(summary, "counter_jumps"), 0.0) << summary;
  EXPECT_EQ(json_text(summary, "nmt_state"), "operational") << summary;
  ASSERT_EQ(tcp_lines.size(), 8U) << printed;  // one per frame
  ASSERT_EQ(quality_lines.size(), 8U) << printed;
  int compared = 0;
  for (std::size_t i = 0U; i < tcp_lines.size(); ++i) {
    const std::vector<std::string> row = split(rows[i + 1U], ',');
    ASSERT_GT(row.size(), x_col + 2U);
    const std::string status = json_text(tcp_lines[i], "status");
    EXPECT_EQ(status, row[status_col]) << "cycle " << i;
    // QUALITY: what the row says, used never above detected.
    EXPECT_EQ(json_number(quality_lines[i], "corners_detected"), std::stod(row[detected_col])) << i;
    EXPECT_EQ(json_number(quality_lines[i], "corners_used"), std::stod(row[used_col])) << i;
    EXPECT_LE(std::stod(row[used_col]), std::stod(row[detected_col])) << i;
    if (status == "valid" || status == "degraded") {
      const char* keys[3] = {"x_mm", "y_mm", "z_mm"};
      for (std::size_t a = 0U; a < 3U; ++a) {
        // CSV: 0.001 mm; wire: 0.01 mm, rounded.
        EXPECT_NEAR(json_number(tcp_lines[i], keys[a]), std::stod(row[x_col + a]), 0.0051) << i << " " << keys[a];
      }
      ++compared;
    }
  }
  EXPECT_GT(compared, 4);

  // can::Receiver on the same lines: the same verdict.
  can::Receiver rx;
  std::int64_t last_us = 0;
  for (const std::string& line : split(slurp(log), '\n')) {
    can::Frame frame;
    std::int64_t t_us = 0;
    ASSERT_TRUE(hal::parse_candump_line(line.c_str(), frame, t_us)) << line;
    static_cast<void>(rx.receive(frame, t_us));  // refusals are counted, checked below
    last_us = t_us;
  }
  EXPECT_EQ(rx.counters().e2e_failures, 0U);
  EXPECT_EQ(rx.counters().counter_jumps, 0U);
  EXPECT_EQ(rx.tcp_e2e().accepted, 8U);
  EXPECT_EQ(rx.joints_e2e().accepted, 8U);
  EXPECT_EQ(rx.counters().boot_ups, 1U);
  ASSERT_TRUE(rx.tcp().ok());
  const std::vector<std::string> last = split(rows[8], ',');
  if (last[status_col] == "valid" || last[status_col] == "degraded") {
    EXPECT_NEAR(rx.tcp().value().value.x_mm, std::stod(last[x_col]), 0.0051);
  }
  EXPECT_EQ(std::string(can::to_string(rx.tcp().value().value.status)), last[status_col]);
  static_cast<void>(last_us);
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

// The soak's allocation probe in a test program: the tests' counter (the
// tcpest executable's own replaces the same functions and is not linked here).
std::optional<test::AllocationScope>& soak_scope() {
  static std::optional<test::AllocationScope> scope;
  return scope;
}
void arm_soak_scope() noexcept { soak_scope().emplace(); }
std::uint64_t disarm_soak_scope() noexcept {
  const std::uint64_t count = soak_scope()->count();
  soak_scope().reset();
  return count;
}

// A short soak: a warm-up pass over 4 frames, then 300 cycles (75 passes);
// the four checks pass and say so, one line each.
// Verifies: REQ-LOOP-018, REQ-LOOP-006
TEST(BenchCommand, AShortSoakPassesItsFourChecks) {
  const HeapProbe probe{test::malloc_hook_active() ? "operator new and malloc" : "operator new only", arm_soak_scope,
                        disarm_soak_scope};
  set_heap_probe(&probe);
  testing::internal::CaptureStdout();
  const int code = run(cmd_bench, {"bench", "--soak", "300", "--dataset", "4"});
  const std::string printed = testing::internal::GetCapturedStdout();
  set_heap_probe(nullptr);
  ASSERT_EQ(code, kExitOk) << printed;
  EXPECT_NE(printed.find("== soak, 720x576: a warm-up pass over the 4 frames, then 300 cycles"), std::string::npos)
      << printed;
  EXPECT_NE(printed.find("\nheap allocations after start-up: 0 in 300 cycles ("), std::string::npos) << printed;
  EXPECT_NE(printed.find("\nheap in use: "), std::string::npos) << printed;
  EXPECT_NE(printed.find("\ncycle time drift, first vs last tenth (30 cycles each): CPU "), std::string::npos) << printed;
  EXPECT_NE(printed.find("\npayload determinism: passes 3..76 (74) equal to pass 2 frame by frame"), std::string::npos)
      << printed;
  EXPECT_EQ(count_of(printed, " ok\n"), 4U) << printed;  // every check's verdict
  EXPECT_EQ(count_of(printed, "FAIL"), 0U) << printed;
  EXPECT_NE(printed.find("\nsoak: passed\n"), std::string::npos) << printed;
}

// Verifies: REQ-LOOP-018, REQ-ERR-004
TEST(BenchCommand, BadSoakValuesAreRefusedWithAUsageError) {
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "0"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "1000000001"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "-5"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "abc"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "18446744073709551616"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "10", "--dataset", "0"}), kExitUsage);
  // The options of the throughput and jitter parts do not apply to the soak: refused, not ignored.
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "10", "--frames", "5"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "10", "--hd"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "10", "--jitter-seconds", "0"}), kExitUsage);
  EXPECT_EQ(run(cmd_bench, {"bench", "--soak", "10", "--period-us", "20000"}), kExitUsage);
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
