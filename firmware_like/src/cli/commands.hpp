// The tcpest subcommands. Each lives in its own cmd_*.cpp and returns the
// process exit code (see exit_codes below).
#pragma once

namespace tcpest {
namespace cli {

// Exit codes of every subcommand (documented in docs/cli.md).
enum ExitCode : int {
  kExitOk = 0,
  kExitFailure = 1,     // the job ran and failed (e.g. a target missed, a device lost for good)
  kExitUsage = 2,       // bad command line
  kExitConfig = 3,      // unreadable or invalid calibration/config/input file
  kExitInterrupted = 4, // stopped by SIGINT/SIGTERM before the end (clean stop, summary printed)
};

using CommandFn = int (*)(int argc, char** argv);  // argv[0] is the subcommand name

struct Command {
  const char* name;
  const char* summary;
  CommandFn run;
};

int cmd_project(int argc, char** argv);
int cmd_solve(int argc, char** argv);
int cmd_study(int argc, char** argv);
int cmd_render(int argc, char** argv);
int cmd_train_colors(int argc, char** argv);
int cmd_estimate(int argc, char** argv);
int cmd_evaluate(int argc, char** argv);
int cmd_run(int argc, char** argv);
int cmd_demo(int argc, char** argv);
int cmd_bench(int argc, char** argv);
int cmd_listen(int argc, char** argv);

// The table, in the order `tcpest --help` lists it.
const Command* commands(int& count) noexcept;

}  // namespace cli
}  // namespace tcpest
