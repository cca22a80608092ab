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

}  // namespace
}  // namespace cli
}  // namespace tcpest
