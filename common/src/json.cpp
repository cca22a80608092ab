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

}  // namespace

Status<ParseError> Document::parse(const char* text, std::size_t length) noexcept {
  text_ = text;
  length_ = length;
  count_ = 0U;
  auto fail = [&](JsonError code, std::size_t at) noexcept {
    ParseError e;
    e.code = code;
    e.offset = static_cast<std::uint32_t>(at);
    e.line = line_of(text, at < length ? at : length);
    return Status<ParseError>::failure(e);
  };
  if (length > 0xFFFFFFF0U) {
    return fail(JsonError::TooLong, 0U);
  }

  // Open containers: token index, and whether the next thing is a key (objects).
  std::size_t stack[kMaxDepth];
  std::size_t depth = 0U;
  // Grammar state: what the next significant character may be.
  enum class Expect : std::uint8_t { Value, KeyOrClose, Key, Colon, CommaOrClose, ValueOrClose, End };
  Expect expect = Expect::Value;

  auto add_token = [&](TokenType type, std::size_t start, std::size_t end) noexcept -> std::size_t {
    if (count_ == capacity_) {
      return kNone;
    }
    Token& t = tokens_[count_];
    t.type = type;
    t.start = static_cast<std::uint32_t>(start);
    t.end = static_cast<std::uint32_t>(end);
    t.children = 0U;
    t.subtree_end = static_cast<std::uint32_t>(count_ + 1U);
    ++count_;
    return count_ - 1U;
  };
  // Marks the end of a finished value: the next token index closes the subtree.
  auto value_done = [&]() noexcept {
    if (depth == 0U) {
      expect = Expect::End;
    } else {
      expect = Expect::CommaOrClose;
    }
  };

  std::size_t i = 0U;
  for (; i < length; ++i) {
    const char c = text[i];
    if (is_space(c)) {
      continue;
    }
    const bool in_object = depth > 0U && tokens_[stack[depth - 1U]].type == TokenType::Object;
    switch (expect) {
      case Expect::End:
        return fail(JsonError::TrailingText, i);
      case Expect::Colon:
        if (c != ':') {
          return fail(JsonError::Syntax, i);
        }
        expect = Expect::Value;
        continue;
      case Expect::CommaOrClose:
        if (c == ',') {
          expect = in_object ? Expect::Key : Expect::Value;
          continue;
        }
        if ((c == '}' && in_object) || (c == ']' && !in_object)) {
          const std::size_t open = stack[depth - 1U];
          tokens_[open].end = static_cast<std::uint32_t>(i + 1U);
          tokens_[open].subtree_end = static_cast<std::uint32_t>(count_);
          --depth;
          value_done();
          continue;
        }
        return fail(JsonError::Syntax, i);
      case Expect::KeyOrClose:
      case Expect::ValueOrClose:
        if ((c == '}' && expect == Expect::KeyOrClose) || (c == ']' && expect == Expect::ValueOrClose)) {
          const std::size_t open = stack[depth - 1U];
          tokens_[open].end = static_cast<std::uint32_t>(i + 1U);
          tokens_[open].subtree_end = static_cast<std::uint32_t>(count_);
          --depth;
          value_done();
          continue;
        }
        break;
      case Expect::Key:
      case Expect::Value:
        break;
    }
    const bool want_key = (expect == Expect::Key || expect == Expect::KeyOrClose);
    if (want_key && c != '"') {
      return fail(JsonError::Syntax, i);
    }
    // A new key or value starts here; count it in its container.
    if (depth > 0U && !(in_object && !want_key)) {
      ++tokens_[stack[depth - 1U]].children;
    }
    if (c == '"') {
      const std::size_t start = i + 1U;
      std::size_t j = start;
      bool closed = false;
      for (; j < length; ++j) {
        const char s = text[j];
        if (s == '\\') {
          ++j;  // skip the escaped character
          continue;
        }
        if (static_cast<unsigned char>(s) < 0x20U) {
          return fail(JsonError::Syntax, j);
        }
        if (s == '"') {
          closed = true;
          break;
        }
      }
      if (!closed) {
        return fail(JsonError::Truncated, length);
      }
      if (add_token(TokenType::String, start, j) == kNone) {
        return fail(JsonError::TooManyTokens, i);
      }
      i = j;
      if (want_key) {
        expect = Expect::Colon;
      } else {
        value_done();
      }
      continue;
    }
    if (c == '{' || c == '[') {
      if (depth == kMaxDepth) {
        return fail(JsonError::TooDeep, i);
      }
      const std::size_t index = add_token(c == '{' ? TokenType::Object : TokenType::Array, i, i + 1U);
      if (index == kNone) {
        return fail(JsonError::TooManyTokens, i);
      }
      stack[depth] = index;
      ++depth;
      expect = (c == '{') ? Expect::KeyOrClose : Expect::ValueOrClose;
      continue;
    }
    // Literals and numbers: a run of characters up to a delimiter.
    std::size_t j = i;
    while (j < length && !is_space(text[j]) && text[j] != ',' && text[j] != ']' && text[j] != '}' && text[j] != ':') {
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
    } else {
      // JSON numbers: -?digits[.digits][e[+-]digits]
      std::size_t k = i;
      if (k < j && text[k] == '-') {
        ++k;
      }
      bool digits = false;
      while (k < j && text[k] >= '0' && text[k] <= '9') {
        ++k;
        digits = true;
      }
      if (k < j && text[k] == '.') {
        ++k;
        while (k < j && text[k] >= '0' && text[k] <= '9') {
          ++k;
        }
      }
      if (k < j && (text[k] == 'e' || text[k] == 'E')) {
        ++k;
        if (k < j && (text[k] == '+' || text[k] == '-')) {
          ++k;
        }
        while (k < j && text[k] >= '0' && text[k] <= '9') {
          ++k;
        }
      }
      if (!digits || k != j) {
        return fail(JsonError::Syntax, i);
      }
    }
    if (add_token(type, i, j) == kNone) {
      return fail(JsonError::TooManyTokens, i);
    }
    i = j - 1U;
    value_done();
  }
  if (depth > 0U || expect != Expect::End) {
    return fail(JsonError::Truncated, length);
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
