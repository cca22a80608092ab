// Built with EIGEN_RUNTIME_NO_MALLOC and assertions on (-UNDEBUG), with the
// solver's sources compiled into this program under the same flags, so that
// any Eigen heap allocation inside a solve aborts.
#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "this test needs EIGEN_RUNTIME_NO_MALLOC"
#endif

#include <gtest/gtest.h>

#include <random>

#include "pose_problem.hpp"
#include "tcpest/solver/pose_solver.hpp"

namespace tcpest {
namespace solver {
namespace {

using test_support::draw_problem;
using test_support::Problem;

// Verifies: REQ-SOLVER-007
TEST(NoMalloc, SolveRunsWithEigenHeapForbidden) {
  const CameraModel camera = test_support::pal_camera();
  const InstrumentModel model = test_support::default_model();
  PoseSolver solver(camera, model);
  std::mt19937 rng(17);
  int converged = 0;
  for (int trial = 0; trial < 20; ++trial) {
    Problem p;
    ASSERT_TRUE(draw_problem(rng, camera, model, true, 1.0, 8, p));
    PoseVector r_adaptive = p.prior;
    PoseVector r_fixed = p.prior;
    Eigen::internal::set_is_malloc_allowed(false);
    const SolveSummary a = solver.solve(p.observed, SolveMode::Adaptive, r_adaptive);
    const SolveSummary f = solver.solve(p.observed, SolveMode::FixedModel, r_fixed);
    Eigen::internal::set_is_malloc_allowed(true);
    converged += (is_converged(a.status) ? 1 : 0) + (is_converged(f.status) ? 1 : 0);
  }
  EXPECT_GE(converged, 38);
}

// The guard is live in this build: a dynamic-size Eigen matrix aborts.
// Verifies: REQ-SOLVER-007
TEST(NoMallocDeathTest, GuardFiresOnADynamicEigenAllocation) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(
      {
        Eigen::internal::set_is_malloc_allowed(false);
        Eigen::MatrixXd m(6, 6);
        m.setOnes();
        std::printf("%f\n", m.sum());
      },
      "heap allocation is forbidden");
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
