// What `tcpest evaluate` and `estimate` score is what `tcpest run` sends:
// over the same image sequence (the same priors: none, the track's), the
// TCP and JOINTS frames of the loop's candump log and those `estimate
// --can-log` writes for the same images are byte for byte the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.hpp"
#include "command_test_support.hpp"

namespace tcpest {
namespace cli {
namespace {

struct LoggedFrame {
  std::string id;
  std::string data;  // hex, as candump writes it
};

// The frames of one CAN id in a candump log, in order.
std::vector<LoggedFrame> frames_of(const std::string& log, const std::string& id) {
  std::vector<LoggedFrame> out;
  std::istringstream lines(log);
  std::string line;
  while (std::getline(lines, line)) {
    const std::size_t hash = line.find('#');
    const std::size_t space = line.rfind(' ', hash);
    if (hash == std::string::npos || space == std::string::npos) {
      continue;
    }
    const std::string frame_id = line.substr(space + 1U, hash - space - 1U);
    if (frame_id == id) {
      out.push_back(LoggedFrame{frame_id, line.substr(hash + 1U)});
    }
  }
  return out;
}

// The status nibble of a TCP/JOINTS frame (byte 6, bits 4-7).
int status_of(const LoggedFrame& f) { return std::stoi(f.data.substr(12U, 1U), nullptr, 16); }

// Verifies: REQ-LOOP-005
TEST(RunAndEstimate, SendTheSameTcpAndJointsPayloadsForTheSameSequence) {
  const std::string dir = command_test::fresh_dir("identity");
  const std::string frames = dir + "/seq";
  // A rendered motion with hard cases, so that some frames fail and the
  // track, the temporal priors and the held frames all take part.
  ASSERT_EQ(command_test::run_command(cmd_render, {"render", "--set", "seq", "--n", "40", "--seed", "79",
                                                   "--hard", "occluder,motion_blur", "--out", frames, "--quiet"}),
            kExitOk);
  std::vector<std::string> images;
  for (int i = 0; i < 40; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "/%04d.jpg", i);
    images.push_back(frames + name);
  }
  const std::string run_log = dir + "/run.log";
  testing::internal::CaptureStdout();
  const int run_code = command_test::run_command(
      cmd_run, {"run", "--source", frames, "--bus", "log:" + run_log, "--no-pacing", "--quiet", "--start-operational"});
  static_cast<void>(testing::internal::GetCapturedStdout());
  ASSERT_EQ(run_code, kExitOk);
  const std::string estimate_log = dir + "/estimate.log";
  std::vector<std::string> words = {"estimate", "--can-log", estimate_log};
  words.insert(words.end(), images.begin(), images.end());
  testing::internal::CaptureStdout();
  const int code = command_test::run_command(cmd_estimate, std::move(words));
  static_cast<void>(testing::internal::GetCapturedStdout());
  ASSERT_EQ(code, kExitOk);

  const std::string run_text = command_test::slurp(run_log);
  const std::string estimate_text = command_test::slurp(estimate_log);
  int solved = 0;
  int held = 0;
  for (const char* id : {"190", "290"}) {  // TCP, JOINTS of node 0x10
    const std::vector<LoggedFrame> sent = frames_of(run_text, id);
    const std::vector<LoggedFrame> scored = frames_of(estimate_text, id);
    ASSERT_EQ(sent.size(), images.size()) << id;
    ASSERT_EQ(scored.size(), images.size()) << id;
    for (std::size_t i = 0U; i < images.size(); ++i) {
      const int status = status_of(sent[i]);
      if (status <= 1) {  // valid, degraded: this frame's estimate
        EXPECT_EQ(sent[i].data, scored[i].data) << "frame " << i << ", id " << id;
        ++solved;
      } else {  // held or invalid: the frame gave no estimate
        EXPECT_EQ(status_of(scored[i]), 3) << "frame " << i << ", id " << id;
        ++held;
      }
    }
  }
  EXPECT_GT(solved, 40);  // most frames of both ids are estimated
  std::printf("solved %d, held or invalid %d (TCP and JOINTS frames)\n", solved, held);
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
