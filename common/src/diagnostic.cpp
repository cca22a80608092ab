#include "tcpest/common/diagnostic.hpp"

#include <cstdio>

namespace tcpest {

void copy_text(char* out, std::size_t capacity, const char* text) noexcept {
  if (out == nullptr || capacity == 0U) {
    return;
  }
  std::size_t i = 0U;
  if (text != nullptr) {
    for (; i + 1U < capacity && text[i] != '\0'; ++i) {
      out[i] = text[i];
    }
  }
  out[i] = '\0';
}

Diagnostic Diagnostic::make(const char* file_name, std::uint32_t line_number, const char* field_name,
                            const char* text) noexcept {
  Diagnostic d;
  copy_text(d.file, sizeof d.file, file_name);
  d.line = line_number;
  copy_text(d.field, sizeof d.field, field_name);
  copy_text(d.message, sizeof d.message, text);
  return d;
}

void Diagnostic::format(char* out, std::size_t capacity) const noexcept {
  if (out == nullptr || capacity == 0U) {
    return;
  }
  const char* shown_file = (file[0] != '\0') ? file : "<input>";
  int written = 0;
  if (line > 0U && field[0] != '\0') {
    written = std::snprintf(out, capacity, "%s:%u: field '%s': %s", shown_file, line, field, message);
  } else if (line > 0U) {
    written = std::snprintf(out, capacity, "%s:%u: %s", shown_file, line, message);
  } else if (field[0] != '\0') {
    written = std::snprintf(out, capacity, "%s: field '%s': %s", shown_file, field, message);
  } else {
    written = std::snprintf(out, capacity, "%s: %s", shown_file, message);
  }
  if (written < 0) {
    out[0] = '\0';
  }
}

}  // namespace tcpest
