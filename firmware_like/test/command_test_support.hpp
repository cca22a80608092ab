// What the command tests share: running a command's entry point with its
// words, a fresh temporary directory, a file's bytes, and counting a text's
// occurrences (CAN messages in a candump log, rows in a CSV).
#pragma once

#include <gtest/gtest.h>

#include <stdlib.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace tcpest {
namespace cli {
namespace command_test {

// `words` as argv (the command's name first).
inline int run_command(int (*command)(int, char**), std::vector<std::string> words) {
  std::vector<char*> argv;
  for (std::string& w : words) {
    argv.push_back(&w[0]);
  }
  return command(static_cast<int>(argv.size()), argv.data());
}

// A new directory under the test's temporary directory, named from `tag`.
inline std::string fresh_dir(const char* tag) {
  std::string dir = std::string(::testing::TempDir()) + "tcpest_" + tag + "_XXXXXX";
  EXPECT_NE(::mkdtemp(&dir[0]), nullptr);
  return dir;
}

inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

inline std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0U;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1U)) {
    ++n;
  }
  return n;
}

}  // namespace command_test
}  // namespace cli
}  // namespace tcpest
