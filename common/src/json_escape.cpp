#include "tcpest/common/json_escape.hpp"

#include <cstdint>
#include <cstring>

namespace tcpest {
namespace json {

namespace {

// The length of the valid UTF-8 sequence at `p` (1 to 4), 0 if the bytes
// there are not one (overlong forms, surrogates and code points past
// U+10FFFF included). `p` is NUL-terminated: a cut sequence is invalid.
std::size_t utf8_length(const char* p) noexcept {
  const auto byte = [p](std::size_t i) noexcept { return static_cast<unsigned char>(p[i]); };
  const unsigned char c = byte(0U);
  if (c < 0x80U) {
    return 1U;
  }
  std::size_t length = 0U;
  unsigned char low = 0x80U;   // the second byte's range, which excludes the overlong,
  unsigned char high = 0xBFU;  // surrogate and too-large forms
  if (c >= 0xC2U && c <= 0xDFU) {
    length = 2U;
  } else if (c >= 0xE0U && c <= 0xEFU) {
    length = 3U;
    low = c == 0xE0U ? 0xA0U : 0x80U;
    high = c == 0xEDU ? 0x9FU : 0xBFU;
  } else if (c >= 0xF0U && c <= 0xF4U) {
    length = 4U;
    low = c == 0xF0U ? 0x90U : 0x80U;
    high = c == 0xF4U ? 0x8FU : 0xBFU;
  } else {
    return 0U;
  }
  if (byte(1U) < low || byte(1U) > high) {
    return 0U;
  }
  for (std::size_t i = 2U; i < length; ++i) {
    if (byte(i) < 0x80U || byte(i) > 0xBFU) {
      return 0U;
    }
  }
  return length;
}

// The escape of a byte that cannot be written as it is, or nullptr.
const char* named_escape(unsigned char c) noexcept {
  switch (c) {
    case '"':
      return "\\\"";
    case '\\':
      return "\\\\";
    case '\b':
      return "\\b";
    case '\f':
      return "\\f";
    case '\n':
      return "\\n";
    case '\r':
      return "\\r";
    case '\t':
      return "\\t";
    default:
      return nullptr;
  }
}

// The next piece of output for the text at `p`: either `escape` (an escape
// sequence, NUL-terminated in `scratch` or static) or `length` bytes of the
// text as they are. Returns how many text bytes the piece stands for.
std::size_t next_piece(const char* p, char (&scratch)[8], const char*& escape, std::size_t& length) noexcept {
  constexpr char kHex[] = "0123456789abcdef";
  const auto c = static_cast<unsigned char>(p[0]);
  escape = named_escape(c);
  if (escape != nullptr) {
    return 1U;
  }
  if (c < 0x20U || c == 0x7FU) {
    scratch[0] = '\\';
    scratch[1] = 'u';
    scratch[2] = '0';
    scratch[3] = '0';
    scratch[4] = kHex[c >> 4U];
    scratch[5] = kHex[c & 0x0FU];
    scratch[6] = '\0';
    escape = scratch;
    return 1U;
  }
  length = utf8_length(p);
  if (length == 0U) {
    escape = "\\ufffd";
    return 1U;
  }
  return length;
}

}  // namespace

std::size_t escape_string(const char* text, char* out, std::size_t capacity, bool* complete) noexcept {
  if (complete != nullptr) {
    *complete = true;
  }
  if (out == nullptr || capacity == 0U) {
    if (complete != nullptr) {
      *complete = text == nullptr || text[0] == '\0';
    }
    return 0U;
  }
  std::size_t used = 0U;
  out[0] = '\0';
  if (text == nullptr) {
    return 0U;
  }
  const char* p = text;
  // Each pass consumes at least one byte of the NUL-terminated text.
  while (*p != '\0') {
    char scratch[8] = {};
    const char* escape = nullptr;
    std::size_t length = 0U;
    const std::size_t consumed = next_piece(p, scratch, escape, length);
    const char* piece = escape != nullptr ? escape : p;
    const std::size_t piece_length = escape != nullptr ? std::strlen(escape) : length;
    if (used + piece_length + 1U > capacity) {
      if (complete != nullptr) {
        *complete = false;
      }
      break;
    }
    std::memcpy(out + used, piece, piece_length);
    used += piece_length;
    p += consumed;
  }
  out[used] = '\0';
  return used;
}

std::size_t escaped_size(const char* text) noexcept {
  std::size_t size = 1U;
  if (text == nullptr) {
    return size;
  }
  const char* p = text;
  while (*p != '\0') {
    char scratch[8] = {};
    const char* escape = nullptr;
    std::size_t length = 0U;
    p += next_piece(p, scratch, escape, length);
    size += escape != nullptr ? std::strlen(escape) : length;
  }
  return size;
}

}  // namespace json
}  // namespace tcpest
