// tcpest run --record DIR and --status-json, on frames rendered here: one
// cycles.csv row per cycle with empty fields for "none", the candump log the
// same as --bus log:'s, an overlay every N frames; a failed write exits 1;
// the status lines are JSON objects with the documented fields.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.hpp"
#include "command_test_support.hpp"
#include "tcpest/common/json.hpp"

namespace tcpest {
namespace cli {
namespace {

// The decimal number just before `tail` in `text` ("12 overlays"), or -1.
long number_before(const std::string& text, const std::string& tail) {
  const std::size_t at = text.find(tail);
  if (at == std::string::npos) {
    return -1;
  }
  std::size_t start = at;
  while (start > 0U && text[start - 1U] >= '0' && text[start - 1U] <= '9') {
    --start;
  }
  return start == at ? -1 : std::stol(text.substr(start, at - start));
}

// The decimal number just after `head` in `text`, or -1.
long number_after(const std::string& text, const std::string& head) {
  const std::size_t at = text.find(head);
  if (at == std::string::npos) {
    return -1;
  }
  std::size_t end = at + head.size();
  while (end < text.size() && text[end] >= '0' && text[end] <= '9') {
    ++end;
  }
  return end == at + head.size() ? -1 : std::stol(text.substr(at + head.size(), end - at - head.size()));
}

using command_test::count_of;
using command_test::fresh_dir;
using command_test::run_command;
using command_test::slurp;

bool exists(const std::string& path) { return ::access(path.c_str(), F_OK) == 0; }

class RunRecordTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    frames_dir_ = new std::string(fresh_dir("run_record") + "/seq");
    // The occluder makes some frames fail: rows with nothing estimated.
    ASSERT_EQ(run_command(cmd_render, {"render", "--set", "seq", "--n", "12", "--seed", "79", "--hard", "occluder",
                                       "--out", *frames_dir_, "--quiet"}),
              kExitOk);
  }
  static void TearDownTestSuite() {
    delete frames_dir_;
    frames_dir_ = nullptr;
  }
  // Runs `tcpest run` over the frames with `extra` words; stdout in `out`.
  static int run(std::vector<std::string> extra, std::string& out) {
    // No NMT master on the simulated bus: the node starts itself.
    std::vector<std::string> words = {"run", "--source", *frames_dir_, "--start-operational"};
    words.insert(words.end(), extra.begin(), extra.end());
    testing::internal::CaptureStdout();
    const int code = run_command(cmd_run, words);
    out = testing::internal::GetCapturedStdout();
    return code;
  }
  static std::string* frames_dir_;
};

std::string* RunRecordTest::frames_dir_ = nullptr;

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    lines.push_back(line);
  }
  return lines;
}

TEST_F(RunRecordTest, WritesOneRowPerCycleTheCandumpLogAndEveryNthOverlay) {
  const std::string dir = fresh_dir("run_record_out");
  const std::string record = dir + "/rec";
  const std::string bus_log = dir + "/bus.log";
  std::string out;
  ASSERT_EQ(run({"--no-pacing", "--quiet", "--bus", "log:" + bus_log, "--record", record, "--overlay-every", "5"}, out),
            kExitOk)
      << out;
  const long cycles = number_before(out, ", frames");
  ASSERT_GT(cycles, 0L) << out;
  const std::vector<std::string> rows = lines_of(slurp(record + "/cycles.csv"));
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(cycles) + 1U);  // the header, then one row per cycle
  EXPECT_EQ(rows[0].find("truth"), std::string::npos);  // replayed files: no truth
  bool some_empty = false;
  const std::size_t columns = count_of(rows[0], ",");
  for (std::size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(count_of(rows[i], ","), columns) << rows[i];
    EXPECT_EQ(rows[i].find(",-1"), std::string::npos) << rows[i];
    some_empty = some_empty || rows[i].find(",,") != std::string::npos;
  }
  EXPECT_TRUE(some_empty);  // the end-of-stream cycle sent nothing
  // What was sent and received: the same lines as --bus log: writes in the cycle.
  const std::string recorded_log = slurp(record + "/can.log");
  EXPECT_GT(count_of(recorded_log, " sim0 190#"), 10U);
  EXPECT_EQ(recorded_log, slurp(bus_log));
  // Frames 0, 5 and 10: each written, or skipped when both slots were still
  // busy (a loaded machine); the first always finds a slot.
  const long written = number_before(out, " overlays (removed 0, skipped ");
  const long skipped = number_after(out, " overlays (removed 0, skipped ");
  ASSERT_GE(written, 0L) << out;
  ASSERT_GE(skipped, 0L) << out;
  EXPECT_EQ(written + skipped, 3L) << out;
  EXPECT_TRUE(exists(record + "/overlays/frame_000000.png"));
  std::size_t on_disk = 0U;
  for (int frame = 0; frame < 12; ++frame) {
    char name[32];
    std::snprintf(name, sizeof name, "/overlays/frame_%06d.png", frame);
    if (exists(record + name)) {
      EXPECT_EQ(frame % 5, 0) << name;
      ++on_disk;
    }
  }
  EXPECT_EQ(on_disk, static_cast<std::size_t>(written));
  EXPECT_NE(out.find("record " + record + ": " + std::to_string(rows.size() - 1U) + " rows"), std::string::npos) << out;
  EXPECT_NE(out.find("dropped 0 entries"), std::string::npos) << out;
}

TEST_F(RunRecordTest, AWriteThatFailsIsReportedAndExitsOne) {
  const std::string record = fresh_dir("run_record_full");
  ASSERT_EQ(::symlink("/dev/full", (record + "/cycles.csv").c_str()), 0);
  std::string out;
  testing::internal::CaptureStderr();
  const int code = run({"--no-pacing", "--quiet", "--bus", "sim", "--record", record, "--overlay-every", "0"}, out);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(code, kExitFailure);
  EXPECT_NE(err.find(record + "/cycles.csv: No space left on device"), std::string::npos) << err;
  EXPECT_EQ(out.find("write errors 0\n"), std::string::npos) << out;
}

TEST_F(RunRecordTest, ATargetThatCannotBeCreatedExitsOne) {
  std::string out;
  testing::internal::CaptureStderr();
  const int code = run({"--no-pacing", "--quiet", "--bus", "sim", "--record", "/dev/full"}, out);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(code, kExitFailure);
  EXPECT_NE(err.find("--record /dev/full"), std::string::npos) << err;
}

TEST_F(RunRecordTest, ACapTooSmallForTheStreamsIsAUsageError) {
  const std::string record = fresh_dir("run_record_small");
  std::string out;
  testing::internal::CaptureStderr();
  const int code = run({"--no-pacing", "--quiet", "--bus", "sim", "--record", record, "--record-max-mb", "0.001"}, out);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(code, kExitUsage);
  EXPECT_NE(err.find("--record-max-mb too small"), std::string::npos) << err;
}

TEST_F(RunRecordTest, StatusJsonLinesAreObjectsWithTheFields) {
  const std::string dir = fresh_dir("run_status_json");
  const std::string config = dir + "/status.yaml";
  std::ofstream(config) << "loop:\n  status_period_ms: 100\n";
  std::string out;
  // Paced at 25 Hz: about half a second, several status periods.
  ASSERT_EQ(run({"--config", config, "--bus", "sim", "--status-json", "--record", dir + "/rec"}, out), kExitOk) << out;
  int objects = 0;
  for (const std::string& line : lines_of(out)) {
    if (line.empty() || line[0] != '{') {
      continue;
    }
    ++objects;
    json::Token tokens[64];
    json::Document doc(tokens, 64U);
    ASSERT_TRUE(doc.parse(line.c_str(), line.size()).ok()) << line;
    for (const char* key : {"t_s", "cycles", "frames", "valid_share", "latency_p50_ms", "latency_p99_ms", "overruns",
                            "slips", "drops", "write_errors"}) {
      const auto member = doc.member(doc.root(), key);
      ASSERT_TRUE(member.ok()) << key << " in " << line;
      EXPECT_TRUE(doc.number(member.value()).ok()) << key << " in " << line;
    }
    const auto mode = doc.member(doc.root(), "mode");
    ASSERT_TRUE(mode.ok()) << line;
    EXPECT_TRUE(doc.string_equals(mode.value(), "operational")) << line;
    for (const char* key : {"camera_lost", "bus_lost"}) {
      const auto member = doc.member(doc.root(), key);
      ASSERT_TRUE(member.ok()) << key << " in " << line;
      EXPECT_EQ(doc.type(member.value()), json::TokenType::False) << key << " in " << line;
    }
  }
  EXPECT_GE(objects, 2) << out;
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
