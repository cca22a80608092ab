// The estimation policy, declared here and nowhere else: every step that
// may produce or judge a frame's estimate, in the order the frame estimator
// runs them, with when each runs, what its result must meet to be kept,
// and its time budget. Read top to bottom, it is the decision flow of
// docs/estimation.md. guided_rounds() walks the rows from kGuidedRounds to
// kFitAgreementCheck; FrameEstimator runs the first and the last row.
//
// The table holds only steps the shipped configuration runs
// (docs/decisions/0053-only-the-rows-that-run.md); the configuration
// (EstimatorConfig / GuidedOptions) sets their parameters (`rounds` 0
// leaves stage 4's solve alone: the paper's pipeline); the table fixes
// their order, their conditions and their acceptance.
#pragma once

#include <array>
#include <cstdint>

namespace tcpest {
namespace vision {

// What produced a frame's estimate, or judged it.
enum class StepKind : std::uint8_t {
  kStage4Solve = 0,     // the paper's pipeline: stages 1-4, then eq. 8 from their corners
  kGuidedRounds,        // model-guided rounds from stage 4's solve: image fit, corners re-measured, solved again
  kStartSeed,           // fallback: the start (encoders' or track's), its channel from the shaft, moved onto the classes
  kBaseRimSeed,         // no fit kept: channel from the shaft, insertion from the base's rim
  kFitAgreementCheck,   // a valid solve whose TCP lies far from its image fit's: degraded
  kEncoderCheck,        // an estimate beyond the encoders' accuracy: one level lower
};
constexpr int kNumStepKinds = 6;

// When a row runs (besides being enabled by the configuration).
enum class RunWhen : std::uint8_t {
  kAlways,             // every frame
  kSolved,             // the current result has a pose
  kNotValid,           // the current result is not valid (the fallback seed)
  kFitKept,            // a round was kept
  kNoFitKeptNotValid,  // no round kept and the result not valid
  kEncoderPrior,       // the frame's prior is the encoders'
};

// What a row's result must meet to replace the current one.
enum class Acceptance : std::uint8_t {
  kStarts,          // the first result of the frame
  kBetter,          // better by the comparison rule (guided_estimate.cpp, better())
  kSolvedDegraded,  // kept when solved, at most degraded (the tube beyond the base is unseen)
  kDemotes,         // keeps the pose, may lower the quality
};

struct PolicyStep {
  StepKind kind;
  const char* name;
  RunWhen when;
  Acceptance acceptance;
  // PAL, one core of the reference machine (docs/loop.md): what the step
  // may take on one frame. Measured by the loop against its schedule, never
  // read by the estimator, which is bounded by counts.
  std::int32_t budget_us;
};

// THE policy.
constexpr std::array<PolicyStep, kNumStepKinds> kEstimationPolicy = {{
    {StepKind::kStage4Solve, "stage4-solve", RunWhen::kAlways, Acceptance::kStarts, 300},
    {StepKind::kGuidedRounds, "guided-rounds", RunWhen::kSolved, Acceptance::kStarts, 1000},
    {StepKind::kStartSeed, "start-seed", RunWhen::kNotValid, Acceptance::kBetter, 3100},
    {StepKind::kBaseRimSeed, "base-rim-seed", RunWhen::kNoFitKeptNotValid, Acceptance::kSolvedDegraded, 1500},
    {StepKind::kFitAgreementCheck, "fit-agreement-check", RunWhen::kFitKept, Acceptance::kDemotes, 10},
    {StepKind::kEncoderCheck, "encoder-check", RunWhen::kEncoderPrior, Acceptance::kDemotes, 10},
}};

constexpr const PolicyStep& policy_step(StepKind kind) noexcept {
  return kEstimationPolicy[static_cast<std::size_t>(kind)];
}
// The rows are in StepKind order (a kind's row is its index): checked at compile time.
constexpr bool policy_in_order() noexcept {
  for (int i = 0; i < kNumStepKinds; ++i) {
    if (static_cast<int>(kEstimationPolicy[static_cast<std::size_t>(i)].kind) != i) {
      return false;
    }
  }
  return true;
}
static_assert(policy_in_order(), "kEstimationPolicy must list the steps in StepKind order");

// A set of steps (which ones a frame tried).
class StepSet {
 public:
  constexpr void add(StepKind kind) noexcept { bits_ |= bit(kind); }
  constexpr bool has(StepKind kind) const noexcept { return (bits_ & bit(kind)) != 0U; }
  constexpr bool empty() const noexcept { return bits_ == 0U; }

 private:
  static constexpr std::uint32_t bit(StepKind kind) noexcept { return 1U << static_cast<unsigned>(kind); }
  std::uint32_t bits_ = 0U;
};

}  // namespace vision
}  // namespace tcpest
