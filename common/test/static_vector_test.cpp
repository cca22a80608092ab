#include "tcpest/common/static_vector.hpp"

#include <gtest/gtest.h>

namespace tcpest {
namespace {

// Verifies: REQ-ERR-008
TEST(StaticVector, ReportsFullInsteadOfGrowing) {
  StaticVector<int, 3> v;
  EXPECT_TRUE(v.push_back(1));
  EXPECT_TRUE(v.push_back(2));
  EXPECT_TRUE(v.push_back(3));
  EXPECT_TRUE(v.full());
  EXPECT_FALSE(v.push_back(4));
  EXPECT_EQ(v.size(), 3U);
  EXPECT_EQ(v.back(), 3);
  v.truncate(1U);
  EXPECT_EQ(v.size(), 1U);
  v.clear();
  EXPECT_TRUE(v.empty());
}

}  // namespace
}  // namespace tcpest
