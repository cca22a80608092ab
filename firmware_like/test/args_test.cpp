#include "cli/args.hpp"

#include <gtest/gtest.h>

namespace tcpest {
namespace cli {
namespace {

const OptionSpec kSpecs[] = {
    {"r", "X,Y,...", "configuration"},
    {"calib", "FILE", "camera"},
    {"fixed-model", nullptr, "flag"},
};

TEST(Args, ValuesMayStartWithAMinusSign) {
  char a0[] = "project", a1[] = "--r", a2[] = "-13.3,6.2,0.17,0,20,-0.5,1", a3[] = "--fixed-model", a4[] = "img.jpg";
  char* argv[] = {a0, a1, a2, a3, a4};
  Args args;
  char error[128];
  ASSERT_TRUE(args.parse(5, argv, 1, kSpecs, 3, error, sizeof error)) << error;
  double r[7];
  ASSERT_TRUE(parse_number_list(args.value("r"), r, 7));
  EXPECT_DOUBLE_EQ(r[0], -13.3);
  EXPECT_DOUBLE_EQ(r[5], -0.5);
  EXPECT_TRUE(args.flag("fixed-model"));
  ASSERT_EQ(args.positional_count(), 1U);
  EXPECT_STREQ(args.positional(0), "img.jpg");
}

TEST(Args, EqualsFormWorksToo) {
  char a0[] = "project", a1[] = "--r=-13.3,6.2,0.17,0,20,-0.5,1";
  char* argv[] = {a0, a1};
  Args args;
  char error[128];
  ASSERT_TRUE(args.parse(2, argv, 1, kSpecs, 3, error, sizeof error));
  double r[7];
  ASSERT_TRUE(parse_number_list(args.value("r"), r, 7));
  EXPECT_DOUBLE_EQ(r[6], 1.0);
}

// Verifies: REQ-ERR-004
TEST(Args, RefusesUnknownOptionsAndMissingValues) {
  char a0[] = "x", a1[] = "--bogus";
  char* argv1[] = {a0, a1};
  Args args1;
  char error[128];
  EXPECT_FALSE(args1.parse(2, argv1, 1, kSpecs, 3, error, sizeof error));
  char b1[] = "--calib";
  char* argv2[] = {a0, b1};
  Args args2;
  EXPECT_FALSE(args2.parse(2, argv2, 1, kSpecs, 3, error, sizeof error));
  EXPECT_FALSE(parse_number_list("1,2", nullptr, 0));
  double v[3];
  EXPECT_FALSE(parse_number_list("1,,3", v, 3));
  EXPECT_FALSE(parse_number_list("1,2,nan", v, 3));
  EXPECT_FALSE(parse_number_list("1,2,3,4", v, 3));
}

// Every option value goes through one range check before any conversion:
// values past the range (or past what a narrower type holds) are refused,
// never wrapped, and `out` keeps its default.
// Verifies: REQ-ERR-004
TEST(Args, RangeCheckedNumbersRefuseWhatTheirUseCannotTake) {
  unsigned long long n = 7U;
  EXPECT_TRUE(parse_unsigned_in("0", 0U, 10U, n));
  EXPECT_EQ(n, 0U);
  EXPECT_TRUE(parse_unsigned_in("10", 0U, 10U, n));
  EXPECT_EQ(n, 10U);
  n = 7U;
  const char* bad_integers[] = {"11", "-1", "+1", " 1", "1 ", "", "1e3", "0x10", "4294967296",
                                "18446744073709551616", "abc"};
  for (const char* text : bad_integers) {
    EXPECT_FALSE(parse_unsigned_in(text, 0U, 10U, n)) << text;
    EXPECT_EQ(n, 7U) << text;
  }
  EXPECT_FALSE(parse_unsigned_in(nullptr, 0U, 10U, n));
  EXPECT_FALSE(parse_unsigned_in("0", 1U, 10U, n));
  EXPECT_TRUE(parse_unsigned_in("18446744073709551615", 0U, ~0ULL, n));
  double x = 2.5;
  EXPECT_TRUE(parse_number_in("-0.5", -1.0, 1.0, x));
  EXPECT_DOUBLE_EQ(x, -0.5);
  x = 2.5;
  const char* bad_numbers[] = {"1e308", "1e309", "inf", "-inf", "nan", "1.5", "-2", "", "1,0"};
  for (const char* text : bad_numbers) {
    EXPECT_FALSE(parse_number_in(text, -1.0, 1.0, x)) << text;
    EXPECT_DOUBLE_EQ(x, 2.5) << text;
  }
}

// Verifies: REQ-ERR-004
TEST(Args, OptionHelpersKeepTheDefaultWhenAbsentAndRefuseOutOfRange) {
  const OptionSpec specs[] = {{"frames", "N", "count"}, {"seconds", "S", "time"}, {"flag", nullptr, "flag"}};
  char a0[] = "bench", a1[] = "--frames", a2[] = "4294967296", a3[] = "--seconds=1e308";
  char* argv[] = {a0, a1, a2, a3};
  Args args;
  char error[128];
  ASSERT_TRUE(args.parse(4, argv, 1, specs, 3, error, sizeof error)) << error;
  unsigned long long frames = 5U;
  EXPECT_FALSE(unsigned_option(args, "bench", "frames", 0U, 100000U, frames));
  EXPECT_EQ(frames, 5U);
  EXPECT_TRUE(unsigned_option(args, "bench", "frames", 0U, ~0ULL, frames));
  EXPECT_EQ(frames, 4294967296ULL);
  double seconds = 20.0;
  EXPECT_FALSE(number_option(args, "bench", "seconds", 0.0, 86400.0, seconds));
  EXPECT_DOUBLE_EQ(seconds, 20.0);
  Args none;
  ASSERT_TRUE(none.parse(1, argv, 1, specs, 3, error, sizeof error));
  EXPECT_TRUE(unsigned_option(none, "bench", "frames", 1U, 2U, frames));
  EXPECT_TRUE(number_option(none, "bench", "seconds", 0.0, 1.0, seconds));
  EXPECT_EQ(frames, 4294967296ULL);
  EXPECT_DOUBLE_EQ(seconds, 20.0);
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
