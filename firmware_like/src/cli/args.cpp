#include "cli/args.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "tcpest/common/yaml_lite.hpp"

namespace tcpest {
namespace cli {

bool Args::parse(int argc, char** argv, int first, const OptionSpec* specs, std::size_t spec_count, char* error,
                 std::size_t error_capacity) noexcept {
  specs_ = specs;
  spec_count_ = spec_count < kMaxOptions ? spec_count : kMaxOptions;
  for (int i = first; i < argc; ++i) {
    const char* word = argv[i];
    if (std::strcmp(word, "--help") == 0 || std::strcmp(word, "-h") == 0) {
      help_ = true;
      continue;
    }
    if (std::strncmp(word, "--", 2U) != 0 || word[2] == '\0') {
      // A positional (a lone "-" is standard input; "--" alone is positional too).
      if (positional_count_ == kMaxPositionals) {
        static_cast<void>(std::snprintf(error, error_capacity, "too many arguments (at most %zu)", kMaxPositionals));
        return false;
      }
      positionals_[positional_count_] = word;
      ++positional_count_;
      continue;
    }
    const char* name = word + 2;
    const char* equals = std::strchr(name, '=');
    const std::size_t name_length = equals != nullptr ? static_cast<std::size_t>(equals - name) : std::strlen(name);
    std::size_t index = spec_count_;
    for (std::size_t s = 0U; s < spec_count_; ++s) {
      if (std::strlen(specs_[s].name) == name_length && std::strncmp(specs_[s].name, name, name_length) == 0) {
        index = s;
        break;
      }
    }
    if (index == spec_count_) {
      static_cast<void>(std::snprintf(error, error_capacity, "unknown option --%.*s", static_cast<int>(name_length), name));
      return false;
    }
    present_[index] = true;
    if (specs_[index].value_name == nullptr) {
      if (equals != nullptr) {
        static_cast<void>(std::snprintf(error, error_capacity, "option --%s takes no value", specs_[index].name));
        return false;
      }
      continue;
    }
    if (equals != nullptr) {
      values_[index] = equals + 1;
    } else if (i + 1 < argc) {
      ++i;
      values_[index] = argv[i];  // may start with '-': a negative number
    } else {
      static_cast<void>(std::snprintf(error, error_capacity, "option --%s needs a value (%s)", specs_[index].name,
                                      specs_[index].value_name));
      return false;
    }
  }
  return true;
}

const char* Args::value(const char* name) const noexcept {
  for (std::size_t s = 0U; s < spec_count_; ++s) {
    if (std::strcmp(specs_[s].name, name) == 0) {
      return values_[s];
    }
  }
  return nullptr;
}

bool Args::flag(const char* name) const noexcept {
  for (std::size_t s = 0U; s < spec_count_; ++s) {
    if (std::strcmp(specs_[s].name, name) == 0) {
      return present_[s];
    }
  }
  return false;
}

void print_usage(const char* usage, const char* description, const OptionSpec* specs, std::size_t spec_count) noexcept {
  std::printf("usage: %s\n\n%s\n", usage, description);
  if (spec_count > 0U) {
    std::printf("\noptions:\n");
  }
  for (std::size_t s = 0U; s < spec_count; ++s) {
    char left[64];
    if (specs[s].value_name != nullptr) {
      static_cast<void>(std::snprintf(left, sizeof left, "--%s %s", specs[s].name, specs[s].value_name));
    } else {
      static_cast<void>(std::snprintf(left, sizeof left, "--%s", specs[s].name));
    }
    std::printf("  %-28s %s\n", left, specs[s].help);
  }
  std::printf("  %-28s %s\n", "--help", "show this help");
}

bool parse_number(const char* text, double& out) noexcept {
  if (text == nullptr) {
    return false;
  }
  return yaml::parse_double(text, out);
}

bool parse_unsigned(const char* text, unsigned long long& out) noexcept {
  return parse_unsigned_in(text, 0U, ~0ULL, out);
}

bool parse_unsigned_in(const char* text, unsigned long long lo, unsigned long long hi,
                       unsigned long long& out) noexcept {
  if (text == nullptr || *text == '\0') {
    return false;
  }
  const char* end = text + std::strlen(text);
  unsigned long long value = 0U;
  const auto parsed = std::from_chars(text, end, value);  // no sign, no spaces; out of range is an error
  if (parsed.ec != std::errc() || parsed.ptr != end || value < lo || value > hi) {
    return false;
  }
  out = value;
  return true;
}

bool parse_number_in(const char* text, double lo, double hi, double& out) noexcept {
  double value = 0.0;
  if (!parse_number(text, value) || !(value >= lo && value <= hi)) {  // parse_number: finite only
    return false;
  }
  out = value;
  return true;
}

bool unsigned_option(const Args& args, const char* command, const char* name, unsigned long long lo,
                     unsigned long long hi, unsigned long long& out) noexcept {
  const char* text = args.value(name);
  if (text == nullptr || parse_unsigned_in(text, lo, hi, out)) {
    return true;
  }
  std::fprintf(stderr, "tcpest %s: --%s: expected an integer in %llu..%llu, got '%s'\n", command, name, lo, hi, text);
  return false;
}

bool number_option(const Args& args, const char* command, const char* name, double lo, double hi,
                   double& out) noexcept {
  const char* text = args.value(name);
  if (text == nullptr || parse_number_in(text, lo, hi, out)) {
    return true;
  }
  std::fprintf(stderr, "tcpest %s: --%s: expected a number in %g..%g, got '%s'\n", command, name, lo, hi, text);
  return false;
}

bool parse_number_list(const char* text, double* out, std::size_t count) noexcept {
  if (text == nullptr) {
    return false;
  }
  std::size_t n = 0U;
  const char* p = text;
  char item[64];
  while (true) {
    const char* comma = std::strchr(p, ',');
    const std::size_t length = comma != nullptr ? static_cast<std::size_t>(comma - p) : std::strlen(p);
    if (length == 0U || length >= sizeof item || n == count) {
      return false;
    }
    std::memcpy(item, p, length);
    item[length] = '\0';
    if (!yaml::parse_double(item, out[n])) {
      return false;
    }
    ++n;
    if (comma == nullptr) {
      break;
    }
    p = comma + 1;
  }
  return n == count;
}

}  // namespace cli
}  // namespace tcpest
