// Writing JSON strings: any text (a file name, an error message) as the
// contents of a JSON string literal, so that a line of JSON stays valid
// whatever the text holds: quotes, backslashes, control characters, bytes
// that are not UTF-8. Fixed buffers, no allocation.
#pragma once

#include <cstddef>

namespace tcpest {
namespace json {

// Writes `text` escaped, without the surrounding quotes, into `out` (always
// NUL-terminated when capacity > 0): '"' and '\\' as \" and \\, \b \f \n \r
// \t by name, other control characters (< 0x20, and 0x7F) as \u00XX, valid
// UTF-8 sequences as they are, and every byte that is not part of one as
// \ufffd (the replacement character). An escape or a character is never cut:
// when the text does not fit, the output stops before the first one that
// does not. Returns the length written (without the NUL); `complete` (when
// given) says whether all of `text` fitted. A null text is written as "".
std::size_t escape_string(const char* text, char* out, std::size_t capacity, bool* complete = nullptr) noexcept;

// Bytes escape_string() needs for `text`, its NUL included.
std::size_t escaped_size(const char* text) noexcept;

}  // namespace json
}  // namespace tcpest
