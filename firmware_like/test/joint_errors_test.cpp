// The joints' report of evaluate and the demo: errors, phi only where the
// tube is bent, the other representation counted, non-finite pairs skipped.
#include "cli/joint_errors.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "tcpest/solver/instrument.hpp"

namespace tcpest {
namespace cli {
namespace {

solver::PoseVector pose(double lambda_mm, double phi_rad, double theta_rad) {
  return solver::InstrumentGeometry{}.nominal_pose(lambda_mm, phi_rad, theta_rad);
}

TEST(JointErrors, ScoresPhiWhereBentAndCountsTheOtherTurn) {
  JointErrors errors;
  char line[320];
  errors.format("x: ", line, sizeof line);
  EXPECT_STREQ(line,
               "x: error median lambda 0.00 mm, theta 0.000 rad, phi 0.000 rad (true theta of 0.2 rad or more: 0); "
               "(phi + pi, -theta) instead of the truth's joints: 0");
  errors.add(pose(20.5, 0.01, 0.52), pose(20.0, 0.0, 0.5));                         // bent: phi scored
  errors.add(pose(20.0, 1.0 - 2.0 * solver::kPi, 0.1), pose(20.0, 1.0, 0.1));       // straight: phi not scored
  errors.add(pose(20.0, 0.3 + solver::kPi, -0.6), pose(20.0, 0.3, 0.6));            // the other representation
  errors.add(pose(std::nan(""), 0.0, 0.5), pose(20.0, 0.0, 0.5));                   // skipped
  EXPECT_EQ(errors.count(), 3U);
  errors.format("", line, sizeof line);
  const std::string text(line);
  EXPECT_NE(text.find("error median lambda 0.00 mm, theta 0.020 rad, phi "), std::string::npos) << text;
  EXPECT_NE(text.find("(true theta of 0.2 rad or more: 2); (phi + pi, -theta) instead of the truth's joints: 1"),
            std::string::npos)
      << text;
  char small[8];
  errors.format("prefix", small, sizeof small);
  EXPECT_STREQ(small, "prefixe");  // truncated, terminated
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
