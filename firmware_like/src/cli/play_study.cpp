#include "cli/play_study.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

namespace tcpest {
namespace cli {

namespace {

using solver::CornerObservation;
using solver::CornerSet;
using solver::PoseVector;
using solver::SolveMode;
using solver::SolveSummary;
using solver::Vec2;
using solver::Vec3;

struct PlayCase {
  PoseVector truth;
  PoseVector prior;
  CornerSet corners;  // ideal, at the truth
};

double grid_value(double low, double high, int index, int count) noexcept {
  return low + (high - low) * static_cast<double>(index) / static_cast<double>(count - 1);
}

// Error accumulators for one mode at one noise level.
struct Accumulator {
  double sum_sq[3] = {0.0, 0.0, 0.0};
  std::array<double, kPlayConfigurations> error_3d{};
  int solves = 0;
  int converged = 0;
  long iterations = 0;

  void add(const Vec3& error, const SolveSummary& s) noexcept {
    for (int a = 0; a < 3; ++a) {
      sum_sq[a] += error[a] * error[a];
    }
    error_3d[static_cast<std::size_t>(solves)] = error.norm();
    ++solves;
    converged += solver::is_converged(s.status) ? 1 : 0;
    iterations += s.iterations;
  }

  PlayModeStats stats() noexcept {
    PlayModeStats out;
    out.solves = solves;
    if (solves == 0) {
      return out;
    }
    const double n = static_cast<double>(solves);
    for (int a = 0; a < 3; ++a) {
      out.rms_mm[a] = std::sqrt(sum_sq[a] / n);
    }
    const auto begin = error_3d.begin();
    const auto end = begin + solves;
    std::sort(begin, end);
    const auto half = static_cast<std::size_t>(solves / 2);
    out.median_3d_mm = (solves % 2 == 1) ? error_3d[half] : 0.5 * (error_3d[half - 1U] + error_3d[half]);
    out.converged_share = static_cast<double>(converged) / n;
    out.mean_iterations = static_cast<double>(iterations) / n;
    return out;
  }
};

}  // namespace

bool run_play_study(const solver::CameraModel& camera, const solver::InstrumentModel& model, std::uint64_t seed,
                    const double* noise_px, int noise_count, const solver::SolverOptions& options,
                    PlayStudyResult& out) noexcept {
  if (noise_px == nullptr || noise_count < 1 || noise_count > kPlayMaxNoiseLevels) {
    return false;
  }
  for (int i = 0; i < noise_count; ++i) {
    if (!(noise_px[i] >= 0.0) || !std::isfinite(noise_px[i])) {
      return false;
    }
  }
  static std::array<PlayCase, kPlayConfigurations> cases;  // ~100 KB: static, the command runs once
  static Accumulator adaptive;
  static Accumulator fixed_model;
  const solver::InstrumentGeometry& g = model.geometry();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> prior_lambda_mm(-3.0, 3.0);
  std::uniform_real_distribution<double> prior_angle_rad(-0.2, 0.2);
  constexpr double kPlayMm = 1.5;
  const double play_rad = solver::deg_to_rad(3.0);

  out = PlayStudyResult{};
  out.configurations = kPlayConfigurations;
  int kept = 0;
  for (int il = 0; il < kPlayGridLambda; ++il) {
    for (int ip = 0; ip < kPlayGridPhi; ++ip) {
      for (int it = 0; it < kPlayGridTheta; ++it) {
        const double lambda = grid_value(10.0, 40.0, il, kPlayGridLambda);
        const double phi = solver::deg_to_rad(grid_value(-90.0, 90.0, ip, kPlayGridPhi));
        const double theta = solver::deg_to_rad(grid_value(-100.0, 100.0, it, kPlayGridTheta));
        PlayCase& c = cases[static_cast<std::size_t>(kept)];
        c.truth = g.nominal_pose(lambda, phi, theta);
        c.truth[solver::kXch] += kPlayMm * unit(rng);
        c.truth[solver::kYch] += kPlayMm * unit(rng);
        c.truth[solver::kPsi] += play_rad * unit(rng);
        c.truth[solver::kMu] += play_rad * unit(rng);
        const double prior_lambda = lambda + prior_lambda_mm(rng);
        const double prior_phi = phi + prior_angle_rad(rng);
        const double prior_theta = theta + prior_angle_rad(rng);
        c.prior = g.nominal_pose(prior_lambda, prior_phi, prior_theta);
        model.corners(camera, c.truth, c.corners);
        if (c.corners.count_in_image() >= kPlayMinCorners) {
          ++kept;
        }
      }
    }
  }
  out.kept = kept;

  solver::PoseSolver solver(camera, model, options);
  for (int level = 0; level < noise_count; ++level) {
    adaptive = Accumulator{};
    fixed_model = Accumulator{};
    const double sd = noise_px[level];
    for (int i = 0; i < kept; ++i) {
      const PlayCase& c = cases[static_cast<std::size_t>(i)];
      CornerObservation observed;
      for (std::size_t k = 0; k < observed.pixel.size(); ++k) {
        observed.visible[k] = c.corners.in_image[k];
        const double du = sd * unit(rng);
        const double dv = sd * unit(rng);
        observed.pixel[k] = c.corners.pixel[k] + Vec2(du, dv);
      }
      const Vec3 true_tcp = c.corners.tcp;
      PoseVector r = c.prior;
      const SolveSummary a = solver.solve(observed, SolveMode::Adaptive, r);
      adaptive.add(model.tcp(r) - true_tcp, a);
      r = c.prior;
      const SolveSummary f = solver.solve(observed, SolveMode::FixedModel, r);
      fixed_model.add(model.tcp(r) - true_tcp, f);
    }
    PlayNoiseRow& row = out.row[level];
    row.noise_px = sd;
    row.adaptive = adaptive.stats();
    row.fixed_model = fixed_model.stats();
  }
  out.rows = noise_count;
  return true;
}

}  // namespace cli
}  // namespace tcpest
