// The datasets' poses: the reference experiment's grid of model.md (with the
// mechanical play and the coarse encoder prior drawn per image), the hard
// cases drawn per image, and a smooth surgeon-like sequence that a simulated
// camera can sample frame by frame. Pure functions of (index, seed).
#pragma once

#include <array>
#include <cstdint>

#include "tcpest/render/image_io.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace render {

// model.md's grid: lambda 7 values in [10, 40] mm, phi 7 in [-90, 90] deg,
// theta 6 in [-100, 100] deg, ends included; index = (i_lambda * 7 + i_phi) * 6 + i_theta.
constexpr int kLabGridLambda = 7;
constexpr int kLabGridPhi = 7;
constexpr int kLabGridTheta = 6;
constexpr int kLabGridSize = kLabGridLambda * kLabGridPhi * kLabGridTheta;  // 294
// Play (standard deviations) and prior half-widths of model.md.
constexpr double kPlayPositionSigmaMm = 1.5;
constexpr double kPlayAngleSigmaDeg = 3.0;
constexpr double kPriorLambdaMm = 3.0;
constexpr double kPriorAngleRad = 0.2;

struct PosePrior {
  std::array<double, 3> joints{};  // [lambda mm, phi rad, theta rad], as encoders would report
};

struct LabSample {
  solver::PoseVector r = solver::PoseVector::Zero();  // the truth (play included)
  PosePrior prior;
};

// The scene seed of dataset image `index` (tissue, hard-case layout, noise).
std::uint64_t image_seed(std::uint64_t seed, std::uint64_t index) noexcept;

// The grid's joints (no play) for index 0..293 (clamped).
void lab_grid_joints(int index, double& lambda_mm, double& phi_rad, double& theta_rad) noexcept;
// Grid pose `index` with play ~ N(0, 1.5 mm / 3 deg) around r_m* and a prior
// uniform within +/- 3 mm / 0.2 rad of the true joints; deterministic in (index, seed).
LabSample lab_sample(const solver::InstrumentGeometry& geometry, int index, std::uint64_t seed) noexcept;
// 1 to 3 distinct hard cases for image `index` (HardCase bits).
std::uint32_t hard_cases_for(int index, std::uint64_t seed) noexcept;

struct SequenceSample {
  solver::PoseVector r = solver::PoseVector::Zero();  // truth: joints and drifting play
  PosePrior prior;                                    // encoders: truth + slowly varying bias + noise
  double time_s = 0.0;
};

// Smooth, plausible motion: each joint a sum of three slow sinusoids (0.02
// to 0.18 Hz, random phases; peak speeds ~50 deg/s, ~8 mm/s) inside the working range (lambda 12..38 mm, phi
// +/- 80 deg, theta +/- 90 deg), the play a slow drift (< 0.03 Hz) of the
// lab's size around r_m*. Random access: sample(frame) needs no history.
class SequenceGenerator {
 public:
  SequenceGenerator(const solver::InstrumentGeometry& geometry, std::uint64_t seed,
                    double frame_rate_hz = 25.0) noexcept;
  SequenceSample sample(std::uint32_t frame) const noexcept;
  double frame_rate_hz() const noexcept { return frame_rate_hz_; }
  // The scene stays put during a sequence: use these for every frame
  // (SceneSpec::world_seed, SceneSpec::tissue_depth_mm), and a per-frame
  // SceneSpec::seed (image_seed(seed, frame)) for the sensor noise. The
  // tissue is 70-90 mm away: the tip may touch it (the depth test hides
  // what is inside, and the ground truth says which corners it hides).
  std::uint64_t world_seed() const noexcept { return world_seed_; }
  double tissue_depth_mm() const noexcept { return tissue_depth_mm_; }

 private:
  struct Wave {
    double amplitude = 0.0, frequency_hz = 0.0, phase = 0.0;
  };
  static constexpr int kWaves = 3;
  solver::InstrumentGeometry geometry_;
  std::uint64_t seed_ = 0U;
  double frame_rate_hz_ = 25.0;
  std::uint64_t world_seed_ = 1U;
  double tissue_depth_mm_ = 80.0;
  std::array<std::array<Wave, kWaves>, 3> joints_{};  // lambda, phi, theta
  std::array<std::array<Wave, 2>, 4> play_{};         // x_ch, y_ch, psi, mu
  std::array<std::array<Wave, 2>, 3> bias_{};         // encoder bias
};

// A randomised look (`tcpest render --randomise`): what one frame's
// instrument paint, tissue, light, sensor, optics and JPEG look like, drawn
// from `seed` over the ranges of docs/rendering.md ("Randomised
// appearance"), so that a set does not reward what one look alone shows.
struct RandomLook {
  Appearance appearance{};
  double exposure = 1.0;
  double noise_sigma = 1.5;
  double blur_sigma_px = 0.5;
  double vignetting = 0.45;
  int jpeg_quality = 92;
  ChromaSubsampling chroma = ChromaSubsampling::k420;
};
RandomLook random_look(std::uint64_t seed) noexcept;

// The build a randomised set is imaged with (`tcpest render --randomise`):
// the instrument's shaft and grasper radii (parts the solver does not
// model) and the endoscope's lamp beside the lens, drawn from the set's
// seed over docs/rendering.md's ranges into `appearance` (its other fields
// untouched). One per set: one instrument under one endoscope images a whole
// set, so that what an estimator learns of them from earlier frames holds.
void random_build(std::uint64_t set_seed, Appearance& appearance) noexcept;

}  // namespace render
}  // namespace tcpest
