#include "tcpest/common/json_escape.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>

#include "tcpest/common/json.hpp"
#include "tcpest/common/splitmix64.hpp"

namespace tcpest {
namespace json {
namespace {

std::string escaped(const std::string& text) {
  std::string out(escaped_size(text.c_str()), '#');
  bool complete = false;
  const std::size_t n = escape_string(text.c_str(), &out[0], out.size(), &complete);
  EXPECT_TRUE(complete) << text;
  EXPECT_EQ(n + 1U, out.size()) << text;  // escaped_size() is exact
  out.resize(n);
  return out;
}

// The contents of a JSON string literal by RFC 8259: no raw '"', '\\' or
// control character, escapes from the list, the rest valid UTF-8.
bool valid_string_contents(const std::string& s) {
  for (std::size_t i = 0U; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c == '"' || c < 0x20U) {
      return false;
    }
    if (c == '\\') {
      if (i + 1U >= s.size() || std::strchr("\"\\/bfnrtu", s[i + 1U]) == nullptr) {
        return false;
      }
      if (s[i + 1U] == 'u') {
        if (i + 5U >= s.size() || std::strspn(s.substr(i + 2U, 4U).c_str(), "0123456789abcdefABCDEF") != 4U) {
          return false;
        }
        i += 5U;
      } else {
        ++i;
      }
      continue;
    }
    if (c >= 0x80U) {
      std::size_t length = c >= 0xF0U ? 4U : c >= 0xE0U ? 3U : 2U;
      if (c < 0xC2U || c > 0xF4U || i + length > s.size()) {
        return false;
      }
      for (std::size_t k = 1U; k < length; ++k) {
        if ((static_cast<unsigned char>(s[i + k]) & 0xC0U) != 0x80U) {
          return false;
        }
      }
      i += length - 1U;
    }
  }
  return true;
}

// The error line of `tcpest estimate --json` for an unreadable image whose
// name holds a quote printed the name raw: the line was not JSON.
// Verifies: REQ-ERR-009
TEST(JsonEscape, QuotesBackslashesAndControlsAreEscaped) {
  EXPECT_EQ(escaped("e\"vil.jpg"), "e\\\"vil.jpg");
  EXPECT_EQ(escaped("C:\\images\\a.jpg"), "C:\\\\images\\\\a.jpg");
  EXPECT_EQ(escaped("a\nb\tc\rd\be\ff"), "a\\nb\\tc\\rd\\be\\ff");
  EXPECT_EQ(escaped(std::string("\x01\x1f\x7f", 3)), "\\u0001\\u001f\\u007f");
  EXPECT_EQ(escaped("plain/path-0001.jpg"), "plain/path-0001.jpg");
  EXPECT_EQ(escaped(""), "");
  char out[4] = {'x', 'x', 'x', 'x'};
  EXPECT_EQ(escape_string(nullptr, out, sizeof out), 0U);
  EXPECT_STREQ(out, "");
  EXPECT_EQ(escaped_size(nullptr), 1U);
}

// Verifies: REQ-ERR-009
TEST(JsonEscape, Utf8PassesAndEveryOtherByteIsTheReplacementCharacter) {
  EXPECT_EQ(escaped("caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x98\x80"), "caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x98\x80");
  EXPECT_EQ(escaped("\xFF"), "\\ufffd");
  EXPECT_EQ(escaped("a\xC3"), "a\\ufffd");                      // cut sequence
  EXPECT_EQ(escaped("\xC0\xAF"), "\\ufffd\\ufffd");              // overlong '/'
  EXPECT_EQ(escaped("\xED\xA0\x80"), "\\ufffd\\ufffd\\ufffd");   // a surrogate
  EXPECT_EQ(escaped("\xF4\x90\x80\x80"), "\\ufffd\\ufffd\\ufffd\\ufffd");  // past U+10FFFF
  EXPECT_EQ(escaped("\xE2\x82x"), "\\ufffd\\ufffdx");
}

// Verifies: REQ-ERR-009
TEST(JsonEscape, TruncationNeverCutsAnEscapeOrACharacter) {
  const std::string text = "ab\"\xE2\x82\xAC\x01z";
  const std::string whole = escaped(text);
  for (std::size_t capacity = 1U; capacity <= whole.size() + 1U; ++capacity) {
    std::string out(capacity, '#');
    bool complete = true;
    const std::size_t n = escape_string(text.c_str(), &out[0], capacity, &complete);
    ASSERT_LT(n, capacity);
    EXPECT_EQ(out[n], '\0');
    EXPECT_EQ(complete, capacity == whole.size() + 1U) << capacity;
    EXPECT_EQ(whole.compare(0U, n, out, 0U, n), 0) << capacity;       // a prefix of the whole
    EXPECT_TRUE(valid_string_contents(out.substr(0U, n))) << capacity;  // and still valid
  }
  bool complete = true;
  EXPECT_EQ(escape_string("a", nullptr, 0U, &complete), 0U);
  EXPECT_FALSE(complete);
}

// Any bytes at all (a file name is any bytes but '/' and NUL): the escaped
// text is valid JSON string contents, which the project's reader takes.
// Verifies: REQ-ERR-009
TEST(JsonEscape, AnyBytesGiveAValidJsonString) {
  std::uint64_t state = 73U;
  const auto next = [&state]() {
    state += kSplitMix64Step;
    return splitmix64(state);
  };
  for (int trial = 0; trial < 2000; ++trial) {
    std::string text;
    const std::size_t length = 1U + next() % 40U;
    for (std::size_t i = 0U; i < length; ++i) {
      auto byte = static_cast<char>(next() & 0xFFU);
      text.push_back(byte == '\0' ? '"' : byte);
    }
    const std::string e = escaped(text);
    ASSERT_TRUE(valid_string_contents(e)) << trial;
    const std::string line = "{\"image\": \"" + e + "\", \"status\": \"none\"}";
    Token tokens[8];
    Document doc(tokens, 8U);
    ASSERT_TRUE(doc.parse(line.c_str(), line.size()).ok()) << line;
    const auto image = doc.member(doc.root(), "image");
    ASSERT_TRUE(image.ok());
    EXPECT_TRUE(doc.string_equals(doc.member(doc.root(), "status").value(), "none"));
  }
  // Printable ASCII and the named escapes round-trip exactly through the
  // reader (which reads \u escapes as '?').
  const std::string ascii = "e\"vil\\ name\t\n.jpg";
  const std::string line = "{\"image\": \"" + escaped(ascii) + "\"}";
  Token tokens[4];
  Document doc(tokens, 4U);
  ASSERT_TRUE(doc.parse(line.c_str(), line.size()).ok()) << line;
  char back[64];
  ASSERT_TRUE(doc.string(doc.member(doc.root(), "image").value(), back, sizeof back).ok());
  EXPECT_EQ(std::string(back), ascii);
}

}  // namespace
}  // namespace json
}  // namespace tcpest
