// Formatted text appended to a caller's fixed buffer, without allocation:
// the project's formatter for lines and small documents (the dataset
// sidecars, cycles.csv rows). Text that does not fit is not cut: the whole
// buffer is then reported empty (length() 0), so a caller never writes a
// truncated line.
#pragma once

#include <cstdarg>
#include <cstddef>
#include <cstdio>

namespace tcpest {

class TextBuffer {
 public:
  TextBuffer(char* out, std::size_t capacity) noexcept : out_(out), capacity_(capacity) {
    if (capacity_ > 0U) {
      out_[0] = '\0';
    } else {
      overflow_ = true;
    }
  }

  // NOLINTNEXTLINE(cert-dcl50-cpp): printf-style formatting into a fixed buffer is the project's allocation-free formatter; the format attribute lets the compiler check every call
  __attribute__((format(printf, 2, 3))) void add(const char* format, ...) noexcept {
    if (overflow_) {
      return;
    }
    va_list args;
    va_start(args, format);
    const int n = std::vsnprintf(out_ + used_, capacity_ - used_, format, args);
    va_end(args);
    if (n < 0 || static_cast<std::size_t>(n) >= capacity_ - used_) {
      overflow_ = true;
      return;
    }
    used_ += static_cast<std::size_t>(n);
  }

  // The text's length; 0 once something did not fit.
  std::size_t length() const noexcept { return overflow_ ? 0U : used_; }
  bool overflowed() const noexcept { return overflow_; }

 private:
  char* out_;
  std::size_t capacity_;
  std::size_t used_ = 0U;
  bool overflow_ = false;
};

}  // namespace tcpest
