// The reference experiment of model.md (the paper's laboratory test,
// simulated): a 7 x 7 x 6 grid of joint configurations (lambda 10..40 mm,
// phi -90..90 deg, theta -100..100 deg, range ends included), the mechanical
// play drawn per image around r*_m (sd 1.5 mm for x_ch, y_ch; 3 deg for psi,
// mu), configurations with fewer than 8 corners in the image dropped, ideal
// in-image corners plus Gaussian pixel noise, and both estimators started
// from the same coarse prior (r*_m; lambda +/- 3 mm, phi and theta
// +/- 0.2 rad, uniform). The play and the prior are drawn once per
// configuration and shared by every noise level; the noise is drawn per level.
#pragma once

#include <cstdint>

#include "tcpest/solver/pose_solver.hpp"

namespace tcpest {
namespace cli {

constexpr int kPlayGridLambda = 7;
constexpr int kPlayGridPhi = 7;
constexpr int kPlayGridTheta = 6;
constexpr int kPlayConfigurations = kPlayGridLambda * kPlayGridPhi * kPlayGridTheta;
constexpr int kPlayMinCorners = 8;
constexpr int kPlayMaxNoiseLevels = 8;

struct PlayModeStats {
  double rms_mm[3] = {0.0, 0.0, 0.0};  // TCP error RMS per camera axis x, y, z (all solves)
  double median_3d_mm = 0.0;           // median |TCP error| (all solves)
  double converged_share = 0.0;        // 0..1
  double mean_iterations = 0.0;
  int solves = 0;
};

struct PlayNoiseRow {
  double noise_px = 0.0;
  PlayModeStats adaptive;
  PlayModeStats fixed_model;
};

struct PlayStudyResult {
  int configurations = 0;  // grid size (294)
  int kept = 0;            // with >= 8 corners in the image
  int rows = 0;
  PlayNoiseRow row[kPlayMaxNoiseLevels];
};

// The paper's figures (TCP RMS x / y / z, mm) for comparison.
constexpr double kPaperAdaptiveRmsMm[3] = {2.1, 1.96, 3.18};
constexpr double kPaperFixedRmsMm[3] = {3.92, 3.61, 9.37};

// Runs the experiment for `noise_count` noise levels (px, each >= 0). False
// on bad arguments.
bool run_play_study(const solver::CameraModel& camera, const solver::InstrumentModel& model, std::uint64_t seed,
                    const double* noise_px, int noise_count, const solver::SolverOptions& options,
                    PlayStudyResult& out) noexcept;

}  // namespace cli
}  // namespace tcpest
