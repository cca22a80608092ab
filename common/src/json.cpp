#include "tcpest/common/json.hpp"

#include <charconv>
#include <cmath>
#include <cstring>

namespace tcpest {
namespace json {

const char* to_string(JsonError e) noexcept {
  switch (e) {
    case JsonError::Syntax: return "syntax error";
    case JsonError::Truncated: return "text ends inside a value";
    case JsonError::TooManyTokens: return "too many values for the reader's capacity";
    case JsonError::TooDeep: return "nesting too deep";
    case JsonError::TrailingText: return "text after the value";
    case JsonError::TooLong: return "text too long";
  }
  return "unknown error";
}

const char* to_string(LookupError e) noexcept {
  switch (e) {
    case LookupError::NotFound: return "missing";
    case LookupError::WrongType: return "wrong type";
    case LookupError::OutOfRange: return "index out of range";
    case LookupError::BadNumber: return "not a finite number";
    case LookupError::TooLong: return "string too long";
  }
  return "unknown error";
}

namespace {

bool is_space(char c) noexcept { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

std::uint32_t line_of(const char* text, std::size_t offset) noexcept {
  std::uint32_t line = 1U;
  for (std::size_t i = 0U; i < offset; ++i) {
    if (text[i] == '\n') {
      ++line;
    }
  }
  return line;
}

// Grammar state: what the next significant character may be.
enum class Expect : std::uint8_t { Value, KeyOrClose, Key, Colon, CommaOrClose, ValueOrClose, End };

// The state of one parse: the text, the caller's token array and the open
// containers (an explicit stack instead of recursion).
struct Tokeniser {
  const char* text = nullptr;
  std::size_t length = 0U;
  Token* tokens = nullptr;
  std::size_t capacity = 0U;
  std::size_t& count;
  // Open containers: token index, and whether the next thing is a key (objects).
  std::size_t stack[kMaxDepth] = {};
  std::size_t depth = 0U;
  Expect expect = Expect::Value;
};

// The error `code` at offset `at`, with its line.
Status<ParseError> fail(const Tokeniser& t, JsonError code, std::size_t at) noexcept {
  ParseError e;
  e.code = code;
  e.offset = static_cast<std::uint32_t>(at);
  e.line = line_of(t.text, at < t.length ? at : t.length);
  return Status<ParseError>::failure(e);
}

// Appends a token; kNone when the token array is full.
std::size_t add_token(Tokeniser& t, TokenType type, std::size_t start, std::size_t end) noexcept {
  if (t.count == t.capacity) {
    return kNone;
  }
  Token& token = t.tokens[t.count];
  token.type = type;
  token.start = static_cast<std::uint32_t>(start);
  token.end = static_cast<std::uint32_t>(end);
  token.children = 0U;
  token.subtree_end = static_cast<std::uint32_t>(t.count + 1U);
  ++t.count;
  return t.count - 1U;
}

// Marks the end of a finished value: the next token index closes the subtree.
void value_done(Tokeniser& t) noexcept {
  if (t.depth == 0U) {
    t.expect = Expect::End;
  } else {
    t.expect = Expect::CommaOrClose;
  }
}

// Closes the innermost container at its bracket, offset `at`.
void close_container(Tokeniser& t, std::size_t at) noexcept {
  const std::size_t open = t.stack[t.depth - 1U];
  t.tokens[open].end = static_cast<std::uint32_t>(at + 1U);
  t.tokens[open].subtree_end = static_cast<std::uint32_t>(t.count);
  --t.depth;
  value_done(t);
}

// What the grammar state makes of the character at `i` before a key or value
// can start (':' and ',', closing brackets, text after the end). `consumed`
// is false when a key or value starts there.
Status<ParseError> take_punctuation(Tokeniser& t, std::size_t i, bool in_object, bool& consumed) noexcept {
  const char c = t.text[i];
  consumed = true;
  switch (t.expect) {
    case Expect::End:
      return fail(t, JsonError::TrailingText, i);
    case Expect::Colon:
      if (c != ':') {
        return fail(t, JsonError::Syntax, i);
      }
      t.expect = Expect::Value;
      return ok_status<ParseError>();
    case Expect::CommaOrClose:
      if (c == ',') {
        t.expect = in_object ? Expect::Key : Expect::Value;
        return ok_status<ParseError>();
      }
      if ((c == '}' && in_object) || (c == ']' && !in_object)) {
        close_container(t, i);
        return ok_status<ParseError>();
      }
      return fail(t, JsonError::Syntax, i);
    case Expect::KeyOrClose:
    case Expect::ValueOrClose:
      if ((c == '}' && t.expect == Expect::KeyOrClose) || (c == ']' && t.expect == Expect::ValueOrClose)) {
        close_container(t, i);
        return ok_status<ParseError>();
      }
      break;
    case Expect::Key:
    case Expect::Value:
      break;
  }
  consumed = false;
  return ok_status<ParseError>();
}

// A string (key or value) whose opening quote is at `i`; `i` moves to its
// closing quote.
Status<ParseError> scan_string(Tokeniser& t, std::size_t& i, bool want_key) noexcept {
  const std::size_t start = i + 1U;
  std::size_t j = start;
  bool closed = false;
  for (; j < t.length; ++j) {
    const char s = t.text[j];
    if (s == '\\') {
      ++j;  // skip the escaped character
      continue;
    }
    if (static_cast<unsigned char>(s) < 0x20U) {
      return fail(t, JsonError::Syntax, j);
    }
    if (s == '"') {
      closed = true;
      break;
    }
  }
  if (!closed) {
    return fail(t, JsonError::Truncated, t.length);
  }
  if (add_token(t, TokenType::String, start, j) == kNone) {
    return fail(t, JsonError::TooManyTokens, i);
  }
  i = j;
  if (want_key) {
    t.expect = Expect::Colon;
  } else {
    value_done(t);
  }
  return ok_status<ParseError>();
}

// An object or array opening at `i`.
Status<ParseError> open_container(Tokeniser& t, std::size_t i) noexcept {
  const char c = t.text[i];
  if (t.depth == kMaxDepth) {
    return fail(t, JsonError::TooDeep, i);
  }
  const std::size_t index = add_token(t, c == '{' ? TokenType::Object : TokenType::Array, i, i + 1U);
  if (index == kNone) {
    return fail(t, JsonError::TooManyTokens, i);
  }
  t.stack[t.depth] = index;
  ++t.depth;
  t.expect = (c == '{') ? Expect::KeyOrClose : Expect::ValueOrClose;
  return ok_status<ParseError>();
}

// Whether text[begin, end) is a JSON number: -?digits[.digits][e[+-]digits]
bool is_number(const char* text, std::size_t begin, std::size_t end) noexcept {
  std::size_t k = begin;
  if (k < end && text[k] == '-') {
    ++k;
  }
  bool digits = false;
  while (k < end && text[k] >= '0' && text[k] <= '9') {
    ++k;
    digits = true;
  }
  if (k < end && text[k] == '.') {
    ++k;
    while (k < end && text[k] >= '0' && text[k] <= '9') {
      ++k;
    }
  }
  if (k < end && (text[k] == 'e' || text[k] == 'E')) {
    ++k;
    if (k < end && (text[k] == '+' || text[k] == '-')) {
      ++k;
    }
    while (k < end && text[k] >= '0' && text[k] <= '9') {
      ++k;
    }
  }
  return digits && k == end;
}

// A literal or number starting at `i`; `i` moves to its last character.
Status<ParseError> scan_literal(Tokeniser& t, std::size_t& i) noexcept {
  const char* text = t.text;
  // Literals and numbers: a run of characters up to a delimiter.
  std::size_t j = i;
  while (j < t.length && !is_space(text[j]) && text[j] != ',' && text[j] != ']' && text[j] != '}' && text[j] != ':') {
    ++j;
  }
  const std::size_t run = j - i;
  TokenType type = TokenType::Number;
  if (run == 4U && std::strncmp(text + i, "true", 4U) == 0) {
    type = TokenType::True;
  } else if (run == 5U && std::strncmp(text + i, "false", 5U) == 0) {
    type = TokenType::False;
  } else if (run == 4U && std::strncmp(text + i, "null", 4U) == 0) {
    type = TokenType::Null;
  } else if (!is_number(text, i, j)) {
    return fail(t, JsonError::Syntax, i);
  }
  if (add_token(t, type, i, j) == kNone) {
    return fail(t, JsonError::TooManyTokens, i);
  }
  i = j - 1U;
  value_done(t);
  return ok_status<ParseError>();
}

// Takes the significant character at `i` and what follows it in the same
// token; `i` moves to the token's last character.
Status<ParseError> next_token(Tokeniser& t, std::size_t& i) noexcept {
  const char c = t.text[i];
  const bool in_object = t.depth > 0U && t.tokens[t.stack[t.depth - 1U]].type == TokenType::Object;
  bool consumed = false;
  const auto punctuation = take_punctuation(t, i, in_object, consumed);
  if (!punctuation.ok() || consumed) {
    return punctuation;
  }
  const bool want_key = (t.expect == Expect::Key || t.expect == Expect::KeyOrClose);
  if (want_key && c != '"') {
    return fail(t, JsonError::Syntax, i);
  }
  // A new key or value starts here; count it in its container.
  if (t.depth > 0U && !(in_object && !want_key)) {
    ++t.tokens[t.stack[t.depth - 1U]].children;
  }
  if (c == '"') {
    return scan_string(t, i, want_key);
  }
  if (c == '{' || c == '[') {
    return open_container(t, i);
  }
  return scan_literal(t, i);
}

}  // namespace

Status<ParseError> Document::parse(const char* text, std::size_t length) noexcept {
  text_ = text;
  length_ = length;
  count_ = 0U;
  Tokeniser t{text, length, tokens_, capacity_, count_};
  if (length > 0xFFFFFFF0U) {
    return fail(t, JsonError::TooLong, 0U);
  }
  for (std::size_t i = 0U; i < length; ++i) {
    if (is_space(text[i])) {
      continue;
    }
    const auto step = next_token(t, i);
    if (!step.ok()) {
      return step;
    }
  }
  if (t.depth > 0U || t.expect != Expect::End) {
    return fail(t, JsonError::Truncated, length);
  }
  return ok_status<ParseError>();
}

Result<std::size_t, LookupError> Document::member(std::size_t object, const char* key) const noexcept {
  using R = Result<std::size_t, LookupError>;
  if (object >= count_ || tokens_[object].type != TokenType::Object) {
    return R::failure(LookupError::WrongType);
  }
  std::size_t index = object + 1U;
  for (std::uint32_t m = 0U; m < tokens_[object].children; ++m) {
    const std::size_t value = index + 1U;
    if (string_equals(index, key)) {
      return R::success(value);
    }
    index = tokens_[value].subtree_end;
  }
  return R::failure(LookupError::NotFound);
}

Result<std::size_t, LookupError> Document::element(std::size_t array, std::size_t i) const noexcept {
  using R = Result<std::size_t, LookupError>;
  if (array >= count_ || tokens_[array].type != TokenType::Array) {
    return R::failure(LookupError::WrongType);
  }
  if (i >= tokens_[array].children) {
    return R::failure(LookupError::OutOfRange);
  }
  std::size_t index = array + 1U;
  for (std::size_t e = 0U; e < i; ++e) {
    index = tokens_[index].subtree_end;
  }
  return R::success(index);
}

std::size_t Document::array_size(std::size_t array) const noexcept {
  if (array >= count_ || tokens_[array].type != TokenType::Array) {
    return 0U;
  }
  return tokens_[array].children;
}

Result<double, LookupError> Document::number(std::size_t index) const noexcept {
  using R = Result<double, LookupError>;
  if (index >= count_ || tokens_[index].type != TokenType::Number) {
    return R::failure(LookupError::WrongType);
  }
  const Token& t = tokens_[index];
  double value = 0.0;
  const auto parsed = std::from_chars(text_ + t.start, text_ + t.end, value);
  if (parsed.ec != std::errc() || parsed.ptr != text_ + t.end || !std::isfinite(value)) {
    return R::failure(LookupError::BadNumber);
  }
  return R::success(value);
}

Status<LookupError> Document::string(std::size_t index, char* out, std::size_t capacity) const noexcept {
  if (index >= count_ || tokens_[index].type != TokenType::String) {
    return Status<LookupError>::failure(LookupError::WrongType);
  }
  if (capacity == 0U) {
    return Status<LookupError>::failure(LookupError::TooLong);
  }
  const Token& t = tokens_[index];
  std::size_t n = 0U;
  for (std::size_t i = t.start; i < t.end; ++i) {
    char c = text_[i];
    if (c == '\\' && i + 1U < t.end) {
      ++i;
      switch (text_[i]) {
        case 'n': c = '\n'; break;
        case 't': c = '\t'; break;
        case 'r': c = '\r'; break;
        case 'b': c = '\b'; break;
        case 'f': c = '\f'; break;
        case 'u': c = '?'; i = (i + 4U < t.end) ? i + 4U : t.end - 1U; break;
        default: c = text_[i]; break;
      }
    }
    if (n + 1U >= capacity) {
      out[0] = '\0';
      return Status<LookupError>::failure(LookupError::TooLong);
    }
    out[n] = c;
    ++n;
  }
  out[n] = '\0';
  return ok_status<LookupError>();
}

bool Document::string_equals(std::size_t index, const char* text) const noexcept {
  if (index >= count_ || tokens_[index].type != TokenType::String) {
    return false;
  }
  const Token& t = tokens_[index];
  const std::size_t n = t.end - t.start;
  return std::strlen(text) == n && std::strncmp(text_ + t.start, text, n) == 0;
}

Status<LookupError> Document::numbers(std::size_t array, double* out, std::size_t count) const noexcept {
  if (array >= count_ || tokens_[array].type != TokenType::Array) {
    return Status<LookupError>::failure(LookupError::WrongType);
  }
  if (tokens_[array].children != count) {
    return Status<LookupError>::failure(LookupError::OutOfRange);
  }
  std::size_t index = array + 1U;
  for (std::size_t e = 0U; e < count; ++e) {
    const auto value = number(index);
    if (!value.ok()) {
      return Status<LookupError>::failure(value.error());
    }
    out[e] = value.value();
    index = tokens_[index].subtree_end;
  }
  return ok_status<LookupError>();
}

}  // namespace json
}  // namespace tcpest
