// The cyclic executive's schedule, declared here and nowhere else: the steps
// of one cycle in the order they run, each with its time budget. The loop
// measures every step of every cycle against these budgets and counts each
// overrun; nothing is silently absorbed.
//
// Budgets are for PAL 720x576 on one core of the reference machine (see
// docs/loop.md for the measured numbers they come from); the cycle budget is
// their sum, and a cycle is also an overrun when it does not end before the
// next period starts.
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/vision/frame_estimator.hpp"

namespace tcpest {
namespace loop {

enum class Step : std::uint8_t {
  kAcquire = 0,   // wait-free part of input: frame into the RGB buffer (decode/convert), bus input
  kClassify,      // vision stage 1: pixel classes, regions
  kInterpret,     // vision stage 2: which region is which marker (with the chosen prior)
  kBorders,       // vision stage 3: Bezier borders
  kCorners,       // vision stage 4: the apparent corners
  kSolve,         // pose solver (Levenberg-Marquardt) on stage 4's corners
  kRefine,        // model-guided corners: image fit, corners re-measured, pose solved again; fallback seeds
  kPublish,       // TCP, JOINTS, MECHANICAL, QUALITY on the bus
  kHousekeeping,  // heartbeat, EMCY, recovery attempts, statistics
};
constexpr int kNumSteps = 9;

struct StepSpec {
  Step step;
  const char* name;
  std::int64_t budget_us;
};

// The refine step's budget, from the estimation policy's table
// (vision/estimation_policy.hpp): the guided rounds, then the start seed.
constexpr std::int64_t kRefineBudgetUs = vision::policy_step(vision::StepKind::kGuidedRounds).budget_us +
                                         vision::policy_step(vision::StepKind::kStartSeed).budget_us;

// THE schedule.
constexpr std::array<StepSpec, kNumSteps> kSchedule = {{
    {Step::kAcquire, "acquire", 1500},
    {Step::kClassify, "classify", 1000},
    // Interpret and solve: p99.9 0.08 and 0.13 ms measured (docs/loop.md);
    // 0.2 and 0.3 ms leave them 2.3-2.5 times that, and give the time to refine.
    {Step::kInterpret, "interpret", 200},
    {Step::kBorders, "borders", 500},
    {Step::kCorners, "corners", 700},
    {Step::kSolve, "solve", vision::policy_step(vision::StepKind::kStage4Solve).budget_us},
    // The guided rounds and the start seed tried on a frame not yet valid,
    // as the estimation policy budgets them.
    {Step::kRefine, "refine", kRefineBudgetUs},
    {Step::kPublish, "publish", 100},
    {Step::kHousekeeping, "housekeeping", 100},
}};

constexpr std::int64_t cycle_budget_us() noexcept {
  std::int64_t sum = 0;
  for (const StepSpec& s : kSchedule) {
    sum += s.budget_us;
  }
  return sum;
}

constexpr int index_of(Step step) noexcept { return static_cast<int>(step); }
constexpr const char* step_name(Step step) noexcept { return kSchedule[static_cast<std::size_t>(step)].name; }

// The estimator's steps are the schedule's, from kClassify to kRefine.
constexpr Step step_of(vision::EstimationStep step) noexcept {
  return static_cast<Step>(static_cast<int>(step) + static_cast<int>(Step::kClassify));
}
static_assert(step_of(vision::EstimationStep::kClassify) == Step::kClassify &&
                  step_of(vision::EstimationStep::kSolve) == Step::kSolve &&
                  step_of(vision::EstimationStep::kRefine) == Step::kRefine,
              "the estimator's steps must map onto the schedule's");

// The table is in Step order (index_of(s) is its row): checked at compile time.
constexpr bool schedule_in_order() noexcept {
  for (int i = 0; i < kNumSteps; ++i) {
    if (static_cast<int>(kSchedule[static_cast<std::size_t>(i)].step) != i) {
      return false;
    }
  }
  return true;
}
static_assert(schedule_in_order(), "kSchedule must list the steps in Step order");

}  // namespace loop
}  // namespace tcpest
