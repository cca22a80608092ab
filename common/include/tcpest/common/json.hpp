// A JSON reader that never allocates: the text is tokenised in place into a
// token array owned by the caller (in the spirit of jsmn), with an explicit
// depth-bounded stack instead of recursion. Tokens refer to the text; it must
// outlive the Document.
#pragma once

#include <cstddef>
#include <cstdint>

#include "tcpest/common/result.hpp"

namespace tcpest {
namespace json {

enum class TokenType : std::uint8_t { Object, Array, String, Number, True, False, Null };

struct Token {
  TokenType type = TokenType::Null;
  std::uint32_t start = 0U;     // offset of the first character (inside the quotes for strings)
  std::uint32_t end = 0U;       // offset one past the last character
  std::uint32_t children = 0U;  // members of an object (key+value pairs) or elements of an array
  std::uint32_t subtree_end = 0U;  // index of the first token after this one's subtree
};

enum class JsonError : std::uint8_t {
  Syntax,         // unexpected character
  Truncated,      // text ended inside a value
  TooManyTokens,  // the caller's token array is too small
  TooDeep,        // nesting deeper than kMaxDepth
  TrailingText,   // something after the top-level value
  TooLong,        // text longer than 4 GiB
};

struct ParseError {
  JsonError code = JsonError::Syntax;
  std::uint32_t offset = 0U;  // where in the text
  std::uint32_t line = 0U;    // 1-based line of offset
};

const char* to_string(JsonError e) noexcept;

enum class LookupError : std::uint8_t { NotFound, WrongType, OutOfRange, BadNumber, TooLong };
const char* to_string(LookupError e) noexcept;

constexpr std::size_t kMaxDepth = 32U;
constexpr std::size_t kNone = static_cast<std::size_t>(-1);

class Document {
 public:
  Document(Token* storage, std::size_t capacity) noexcept : tokens_(storage), capacity_(capacity) {}

  // Tokenises one JSON value (surrounding white space allowed).
  Status<ParseError> parse(const char* text, std::size_t length) noexcept;

  std::size_t token_count() const noexcept { return count_; }
  std::size_t root() const noexcept { return 0U; }
  const Token& token(std::size_t index) const noexcept { return tokens_[index]; }
  TokenType type(std::size_t index) const noexcept { return tokens_[index].type; }
  bool is_null(std::size_t index) const noexcept { return tokens_[index].type == TokenType::Null; }

  // The value of member `key` of an object.
  Result<std::size_t, LookupError> member(std::size_t object, const char* key) const noexcept;
  // Element `i` of an array.
  Result<std::size_t, LookupError> element(std::size_t array, std::size_t i) const noexcept;
  std::size_t array_size(std::size_t array) const noexcept;
  Result<double, LookupError> number(std::size_t index) const noexcept;
  // Copies a string token (escapes resolved, non-ASCII \u escapes as '?').
  Status<LookupError> string(std::size_t index, char* out, std::size_t capacity) const noexcept;
  bool string_equals(std::size_t index, const char* text) const noexcept;
  // Reads an array of exactly `count` numbers.
  Status<LookupError> numbers(std::size_t array, double* out, std::size_t count) const noexcept;

 private:
  Token* tokens_;
  std::size_t capacity_;
  std::size_t count_ = 0U;
  const char* text_ = nullptr;
  std::size_t length_ = 0U;
};

}  // namespace json
}  // namespace tcpest
