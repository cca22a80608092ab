#include "tcpest/loop/oracle_pipeline.hpp"

#include "tcpest/common/splitmix64.hpp"

namespace tcpest {
namespace loop {

namespace {
constexpr std::uint8_t kNoTruth = 1U;

// A small deterministic hash to [-1, 1] (splitmix64).
double unit_noise(std::uint64_t key) noexcept {
  return static_cast<double>(splitmix64(key) >> 11U) * (2.0 / 9007199254740992.0) - 1.0;
}
}  // namespace

void OraclePipeline::begin_frame(const hal::FrameInfo& info) noexcept {
  truth_ = info.truth;
  sequence_ = info.sequence;
}

Status<StageError> OraclePipeline::classify(const ImageView& image) noexcept {
  static_cast<void>(image);
  return truth_.valid ? ok_status<StageError>() : Status<StageError>::failure(StageError{kNoTruth});
}

Status<StageError> OraclePipeline::interpret(PriorSource source, const solver::PoseVector& prior_r) noexcept {
  static_cast<void>(source);
  static_cast<void>(prior_r);
  return ok_status<StageError>();
}

Status<StageError> OraclePipeline::borders(const ImageView& image) noexcept {
  static_cast<void>(image);
  return ok_status<StageError>();
}

Status<StageError> OraclePipeline::corners(const ImageView& image, solver::CornerObservation& out) noexcept {
  static_cast<void>(image);
  for (int k = 0; k < solver::kNumCorners; ++k) {
    const auto i = static_cast<std::size_t>(k);
    out.visible[i] = truth_.corner_visible[i];
    const std::uint64_t key = (static_cast<std::uint64_t>(sequence_) << 8U) + static_cast<std::uint64_t>(2 * k);
    out.pixel[i] = solver::Vec2(truth_.corners_px[i][0] + noise_px_ * unit_noise(key),
                                truth_.corners_px[i][1] + noise_px_ * unit_noise(key + 1U));
  }
  return ok_status<StageError>();
}

void OraclePipeline::end_frame(bool success) noexcept {
  if (success) {
    ++successes_;
  }
}

const char* OraclePipeline::describe(StageError error) const noexcept {
  return error.code == kNoTruth ? "no ground truth with this frame (oracle pipeline)" : "ok";
}

}  // namespace loop
}  // namespace tcpest
