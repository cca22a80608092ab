// Diagnostic: the one error value of every text loader (calibration, config,
// corner files). It names the file, the line and the field, so that an operator
// can fix the file without reading code.
#pragma once

#include <cstddef>
#include <cstdint>

namespace tcpest {

struct Diagnostic {
  char file[256] = {};
  std::uint32_t line = 0U;  // 1-based; 0 = not tied to a line (missing field, I/O error)
  char field[96] = {};
  char message[192] = {};

  // Builds a diagnostic; every string is truncated to its buffer.
  static Diagnostic make(const char* file_name, std::uint32_t line_number, const char* field_name,
                         const char* text) noexcept;
  // Writes "file:line: field 'f': message" (parts omitted when empty) into out.
  void format(char* out, std::size_t capacity) const noexcept;
};

// Copies a NUL-terminated string into a fixed buffer, always terminating it.
void copy_text(char* out, std::size_t capacity, const char* text) noexcept;

}  // namespace tcpest
