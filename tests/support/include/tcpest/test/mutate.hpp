// Seeded damage to a valid input, for the tests that a malformed file or
// message gives an error value and never a crash, an overrun (the sanitizer
// build runs them) or a half-read result. Deterministic on every machine:
// splitmix64 (common) and our own arithmetic, no std:: distribution. Each
// damaged text differs from the valid one by 1 to 4 edits: a bit flipped,
// a byte replaced, a run deleted, the text cut short, a run copied
// elsewhere, or a token that parsers find hard (non-finite or huge
// numbers, brackets, quotes, deep nesting, control bytes) inserted or put
// in place of a number.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include "tcpest/common/splitmix64.hpp"

namespace tcpest {
namespace test {

// The whole of a (small) file, "" if it cannot be read: the valid input to damage.
inline std::string read_text_file(const char* path) {
  std::string text;
  std::FILE* file = std::fopen(path, "rb");
  if (file == nullptr) {
    return text;
  }
  char chunk[4096];
  std::size_t got = 0U;
  while ((got = std::fread(chunk, 1U, sizeof chunk, file)) > 0U) {
    text.append(chunk, got);
  }
  static_cast<void>(std::fclose(file));  // read-only
  return text;
}

class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) noexcept : state_(seed) {}

  std::uint64_t next() noexcept {
    const std::uint64_t z = splitmix64(state_);
    state_ += kSplitMix64Step;
    return z;
  }
  // 0..n-1 (n > 0); the slight modulo bias does not matter here.
  std::size_t below(std::size_t n) noexcept { return static_cast<std::size_t>(next() % n); }

  std::string damage(const std::string& valid) noexcept {
    static const char* const kTokens[] = {
        "nan", "inf", "-inf", "1e309", "-1e309", "1e-320", "0", "-0", "99999999999999999999", "-1",
        "[", "]", "{", "}", ":", ",", "\"", "\\", "\\u0000", "\n", "\t", "- ", "#", "null", "true",
        "4294967296", "-2147483649", "0x10", "1e5", "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
        "{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":{\"a\":"};
    constexpr std::size_t kTokenCount = sizeof kTokens / sizeof kTokens[0];
    std::string text = valid;
    const std::size_t edits = 1U + below(4U);
    for (std::size_t e = 0U; e < edits; ++e) {
      if (text.empty()) {
        text = "x";
      }
      const std::size_t at = below(text.size());
      switch (below(7U)) {
        case 0U:
          text[at] = static_cast<char>(static_cast<unsigned char>(text[at]) ^ (1U << below(8U)));
          break;
        case 1U:
          text[at] = static_cast<char>(below(256U));
          break;
        case 2U:
          text.erase(at, 1U + below(16U));
          break;
        case 3U:
          text.insert(at, kTokens[below(kTokenCount)]);
          break;
        case 4U: {
          std::size_t end = at;
          while (end < text.size() && is_number_char(text[end])) {
            ++end;
          }
          text.replace(at, end - at, kTokens[below(kTokenCount)]);
          break;
        }
        case 5U:
          text.resize(at);
          break;
        default: {
          const std::size_t from = below(text.size());
          const std::string run = text.substr(from, 1U + below(64U));
          text.insert(at, run);
          break;
        }
      }
    }
    return text;
  }

 private:
  static bool is_number_char(char c) noexcept {
    return (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '+' || c == 'e' || c == 'E';
  }
  std::uint64_t state_;
};

}  // namespace test
}  // namespace tcpest
