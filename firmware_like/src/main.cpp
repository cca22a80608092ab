// tcpest: git-style front end. `tcpest --help` lists the subcommands,
// `tcpest SUB --help` describes one.
#include <cstdio>
#include <cstring>

#include "cli/commands.hpp"
#include "cli/heap_probe.hpp"

namespace {

void print_help() {
  int count = 0;
  const tcpest::cli::Command* table = tcpest::cli::commands(count);
  std::printf(
      "usage: tcpest <command> [options]\n\n"
      "Estimates the 3D position of the tip (TCP) of a bendable instrument from the\n"
      "endoscope's images and sends it to the STRAS robot's controllers over CAN.\n\ncommands:\n");
  for (int i = 0; i < count; ++i) {
    std::printf("  %-14s %s\n", table[i].name, table[i].summary);
  }
  std::printf("\n'tcpest <command> --help' describes a command. Angles on the command line are in\n"
              "radians and lengths in millimetres unless an option says otherwise.\n");
}

}  // namespace

int main(int argc, char** argv) {
  tcpest::cli::set_heap_probe(tcpest::cli::executable_heap_counter());  // tcpest bench --soak
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0 ||
      std::strcmp(argv[1], "help") == 0) {
    print_help();
    return argc < 2 ? tcpest::cli::kExitUsage : tcpest::cli::kExitOk;
  }
  if (std::strcmp(argv[1], "--version") == 0) {
    std::printf("tcpest %s\n", TCPEST_VERSION);
    return tcpest::cli::kExitOk;
  }
  int count = 0;
  const tcpest::cli::Command* table = tcpest::cli::commands(count);
  for (int i = 0; i < count; ++i) {
    if (std::strcmp(argv[1], table[i].name) == 0) {
      return table[i].run(argc - 1, argv + 1);
    }
  }
  std::fprintf(stderr, "tcpest: unknown command '%s' (see 'tcpest --help')\n", argv[1]);
  return tcpest::cli::kExitUsage;
}
