#include "tcpest/common/json.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>

#include "tcpest/test/mutate.hpp"

namespace tcpest {
namespace json {
namespace {

struct Parsed {
  Token tokens[256];
  Document doc{tokens, 256U};
  bool parse(const char* text) { return doc.parse(text, std::strlen(text)).ok(); }
};

// Verifies: REQ-ERR-001
TEST(Json, ReadsNestedValues) {
  Parsed p;
  ASSERT_TRUE(p.parse(R"({"corners": [[1.5, -2e3], null, [3, 4]], "prior": [0.1, 0.2, 0.3], "s": "a\"b"})"));
  const auto corners = p.doc.member(p.doc.root(), "corners");
  ASSERT_TRUE(corners.ok());
  EXPECT_EQ(p.doc.array_size(corners.value()), 3U);
  const auto first = p.doc.element(corners.value(), 0U);
  ASSERT_TRUE(first.ok());
  double uv[2];
  ASSERT_TRUE(p.doc.numbers(first.value(), uv, 2U).ok());
  EXPECT_DOUBLE_EQ(uv[0], 1.5);
  EXPECT_DOUBLE_EQ(uv[1], -2000.0);
  EXPECT_TRUE(p.doc.is_null(p.doc.element(corners.value(), 1U).value()));
  const auto third = p.doc.element(corners.value(), 2U);
  ASSERT_TRUE(p.doc.numbers(third.value(), uv, 2U).ok());
  EXPECT_DOUBLE_EQ(uv[1], 4.0);
  const auto prior = p.doc.member(p.doc.root(), "prior");
  double pr[3];
  ASSERT_TRUE(p.doc.numbers(prior.value(), pr, 3U).ok());
  EXPECT_DOUBLE_EQ(pr[2], 0.3);
  char text[8];
  ASSERT_TRUE(p.doc.string(p.doc.member(p.doc.root(), "s").value(), text, sizeof text).ok());
  EXPECT_STREQ(text, "a\"b");
  EXPECT_FALSE(p.doc.member(p.doc.root(), "missing").ok());
}

// Verifies: REQ-ERR-001
TEST(Json, RefusesMalformedText) {
  const char* bad[] = {"",         "{",          "[1, 2",       "{\"a\" 1}",  "[1,]x",  "[01x]",
                       "{\"a\":}", "[1 2]",      "\"open",      "[nul]",      "{1: 2}", "[1] [2]",
                       "[-]",      "{\"a\":1,}", "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]"};
  for (const char* text : bad) {
    Parsed p;
    EXPECT_FALSE(p.parse(text)) << text;
  }
}

// Verifies: REQ-ERR-001
TEST(Json, ReportsTooManyTokensWithoutOverrun) {
  Token tokens[4];
  Document doc(tokens, 4U);
  const char* text = "[1, 2, 3, 4, 5]";
  const auto status = doc.parse(text, std::strlen(text));
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, JsonError::TooManyTokens);
}

// The token array running out at each token of a document in turn (an
// object, a key, a string, a number, a literal, an array): always
// TooManyTokens, never a write past the array; one more token and it
// parses. Lookups on a token of the wrong type are refused.
// Verifies: REQ-ERR-001
TEST(Json, RunsOutOfTokensAtAnyTokenCleanlyAndRefusesWrongTypes) {
  const char* text = R"({"a": "s", "b": [1, true, null], "c": {"d": []}})";
  std::size_t needed = 0U;
  {
    Parsed p;
    ASSERT_TRUE(p.parse(text));
    needed = p.doc.token_count();
  }
  for (std::size_t capacity = 1U; capacity < needed; ++capacity) {
    Token tokens[32];
    Token& guard = tokens[capacity];
    guard.start = 0xABCDU;
    Document doc(tokens, capacity);
    const auto status = doc.parse(text, std::strlen(text));
    ASSERT_FALSE(status.ok()) << capacity;
    EXPECT_EQ(status.error().code, JsonError::TooManyTokens) << capacity;
    EXPECT_EQ(guard.start, 0xABCDU) << capacity;  // nothing written past the capacity
  }
  Token tokens[32];
  Document doc(tokens, needed);
  ASSERT_TRUE(doc.parse(text, std::strlen(text)).ok());

  const std::size_t root = doc.root();
  const std::size_t a = doc.member(root, "a").value();
  const std::size_t b = doc.member(root, "b").value();
  EXPECT_EQ(doc.member(a, "x").error(), LookupError::WrongType);      // a string is no object
  EXPECT_EQ(doc.element(root, 0U).error(), LookupError::WrongType);  // an object is no array
  EXPECT_EQ(doc.array_size(a), 0U);
  EXPECT_FALSE(doc.string_equals(b, "s"));
  double out[3];
  EXPECT_EQ(doc.numbers(a, out, 3U).error(), LookupError::WrongType);
  EXPECT_FALSE(doc.numbers(b, out, 3U).ok());  // true and null are not numbers
  char small[4];
  EXPECT_EQ(doc.string(b, small, sizeof small).error(), LookupError::WrongType);
  EXPECT_EQ(doc.string(a, small, 0U).error(), LookupError::TooLong);
  EXPECT_EQ(doc.member(needed + 5U, "a").error(), LookupError::WrongType);  // beyond the tokens
}

// Verifies: REQ-ERR-001
TEST(Json, RefusesNonFiniteNumbers) {
  Parsed p;
  ASSERT_TRUE(p.parse("[1e999]"));
  EXPECT_FALSE(p.doc.number(1U).ok());
}

// Seeded damage to a valid document: a parse is refused with an offset
// inside the text, or every token can be walked and read (numbers, strings
// into a short buffer, members, elements) without reading past the text or
// the token array (the sanitizer build runs this).
// Verifies: REQ-ERR-001
TEST(Json, DamagedTextIsRefusedOrSafeToWalk) {
  const std::string valid =
      R"({"format": "x-1", "corners": [[1.5, -2e3], null, [3, 4]], "prior": [0.1, 0.2, 0.3], "s": "a\"b\\u00e9",)"
      R"( "nested": {"a": [true, false, null, {"b": [[], {}]}]}, "n": -0.0})";
  test::Mutator mutator(3U);
  int refused = 0;
  for (int i = 0; i < 20000; ++i) {
    const std::string text = mutator.damage(valid);
    Token tokens[64];
    Document doc(tokens, 64U);
    const auto status = doc.parse(text.data(), text.size());
    if (!status.ok()) {
      EXPECT_LE(status.error().offset, text.size()) << text;
      ++refused;
      continue;
    }
    ASSERT_GE(doc.token_count(), 1U) << text;
    ASSERT_LE(doc.token_count(), 64U) << text;
    for (std::size_t t = 0; t < doc.token_count(); ++t) {
      const Token& token = doc.token(t);
      EXPECT_LE(token.start, token.end) << text;
      EXPECT_LE(token.end, text.size()) << text;
      EXPECT_LE(token.subtree_end, doc.token_count()) << text;
      char out[4];
      switch (token.type) {
        case TokenType::Number: {
          const auto number = doc.number(t);
          EXPECT_TRUE(!number.ok() || std::isfinite(number.value())) << text;
          break;
        }
        case TokenType::String:
          static_cast<void>(doc.string(t, out, sizeof out));  // TooLong is an answer too
          static_cast<void>(doc.string_equals(t, "a"));
          break;
        case TokenType::Object:
          static_cast<void>(doc.member(t, "corners"));
          break;
        case TokenType::Array:
          for (std::size_t e = 0; e <= doc.array_size(t); ++e) {
            static_cast<void>(doc.element(t, e));  // one past the end: OutOfRange
          }
          break;
        default:
          break;
      }
    }
  }
  EXPECT_GT(refused, 2000);
  EXPECT_GT(20000 - refused, 400);
}

}  // namespace
}  // namespace json
}  // namespace tcpest
