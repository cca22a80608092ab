// Command-line options of the tcpest subcommands: `--name value` and
// `--name=value` both work, and a value may start with a minus sign
// (`--r -13.3,6.2,...`): an option declared to take a value always takes the
// next word.
#pragma once

#include <cstddef>

namespace tcpest {
namespace cli {

struct OptionSpec {
  const char* name;       // without the leading "--"
  const char* value_name; // nullptr for a flag
  const char* help;
};

constexpr std::size_t kMaxOptions = 48U;
constexpr std::size_t kMaxPositionals = 4096U;

class Args {
 public:
  // Parses argv[first..argc). On failure writes a message to `error`.
  bool parse(int argc, char** argv, int first, const OptionSpec* specs, std::size_t spec_count, char* error,
             std::size_t error_capacity) noexcept;
  // The option's value (last one wins), or nullptr if absent.
  const char* value(const char* name) const noexcept;
  bool flag(const char* name) const noexcept;
  bool help_requested() const noexcept { return help_; }
  std::size_t positional_count() const noexcept { return positional_count_; }
  const char* positional(std::size_t i) const noexcept { return positionals_[i]; }

 private:
  const OptionSpec* specs_ = nullptr;
  std::size_t spec_count_ = 0U;
  const char* values_[kMaxOptions] = {};
  bool present_[kMaxOptions] = {};
  const char* positionals_[kMaxPositionals] = {};
  std::size_t positional_count_ = 0U;
  bool help_ = false;
};

// Prints "usage" then the options table.
void print_usage(const char* usage, const char* description, const OptionSpec* specs, std::size_t spec_count) noexcept;

// Parses exactly `count` comma-separated finite numbers.
bool parse_number_list(const char* text, double* out, std::size_t count) noexcept;
// Parses one finite number / a non-negative integer.
bool parse_number(const char* text, double& out) noexcept;
bool parse_unsigned(const char* text, unsigned long long& out) noexcept;

// Range-checked numbers: a whole text that is a non-negative integer (no
// sign, no spaces) / a finite number, accepted only in [lo, hi]. `out` is
// written only on success. Every option value is converted through these,
// with the range its use can take, so that no later conversion to a
// narrower type can wrap, overflow or be undefined.
bool parse_unsigned_in(const char* text, unsigned long long lo, unsigned long long hi,
                       unsigned long long& out) noexcept;
bool parse_number_in(const char* text, double lo, double hi, double& out) noexcept;

// The option `--name` of `args`, when given, range-checked as above into
// `out` (which keeps its default when the option is absent). On a bad value
// prints "tcpest COMMAND: --NAME: expected an integer in LO..HI, got 'TEXT'"
// to stderr and returns false (the command then exits with kExitUsage).
bool unsigned_option(const Args& args, const char* command, const char* name, unsigned long long lo,
                     unsigned long long hi, unsigned long long& out) noexcept;
bool number_option(const Args& args, const char* command, const char* name, double lo, double hi,
                   double& out) noexcept;

}  // namespace cli
}  // namespace tcpest
