// Placeholder until this command's issue lands.
#include <cstdio>

#include "cli/commands.hpp"

namespace tcpest {
namespace cli {

int cmd_evaluate(int /*argc*/, char** argv) {
  std::fprintf(stderr, "tcpest %s: not available in this build yet\n", argv[0]);
  return kExitFailure;
}

}  // namespace cli
}  // namespace tcpest
