// Simulated pose problems for the solver tests: the reference experiment's
// draws (model.md) on the default PAL camera and geometry.
#pragma once

#include <random>

#include "tcpest/solver/pose_solver.hpp"

namespace tcpest {
namespace solver {
namespace test_support {

struct Problem {
  PoseVector truth;
  PoseVector prior;  // r*_m with the coarse joint prior
  CornerObservation observed;
};

inline CameraModel pal_camera() { return CameraModel::create(default_pal_camera()).value(); }
inline InstrumentModel default_model() { return InstrumentModel::create(InstrumentGeometry{}).value(); }

// Draws a configuration in the experiment's joint range with the play of
// model.md (sd 1.5 mm, 3 deg; `play` = false: r_m = r*_m exactly), its ideal
// in-image corners plus Gaussian noise, and a coarse prior. Redraws until at
// least `min_corners` corners are in the image (bounded: 1000 draws).
inline bool draw_problem(std::mt19937& rng, const CameraModel& camera, const InstrumentModel& model, bool play,
                         double noise_px, int min_corners, Problem& out) {
  const InstrumentGeometry& g = model.geometry();
  std::normal_distribution<double> unit(0.0, 1.0);
  const double play_mm = play ? 1.5 : 0.0;
  const double play_rad = play ? deg_to_rad(3.0) : 0.0;
  std::uniform_real_distribution<double> lambda(10.0, 40.0);
  std::uniform_real_distribution<double> phi(-kPi / 2.0, kPi / 2.0);
  std::uniform_real_distribution<double> theta(deg_to_rad(-100.0), deg_to_rad(100.0));
  std::uniform_real_distribution<double> prior_mm(-3.0, 3.0);
  std::uniform_real_distribution<double> prior_rad(-0.2, 0.2);
  for (int attempt = 0; attempt < 1000; ++attempt) {
    const double l = lambda(rng);
    const double p = phi(rng);
    const double t = theta(rng);
    out.truth = g.nominal_pose(l, p, t);
    out.truth[kXch] += play_mm * unit(rng);
    out.truth[kYch] += play_mm * unit(rng);
    out.truth[kPsi] += play_rad * unit(rng);
    out.truth[kMu] += play_rad * unit(rng);
    out.prior = g.nominal_pose(l + prior_mm(rng), p + prior_rad(rng), t + prior_rad(rng));
    CornerSet corners;
    model.corners(camera, out.truth, corners);
    if (corners.count_in_image() < min_corners) {
      continue;
    }
    for (std::size_t k = 0; k < corners.pixel.size(); ++k) {
      out.observed.visible[k] = corners.in_image[k];
      out.observed.pixel[k] = corners.pixel[k];
      if (noise_px > 0.0) {
        const double du = noise_px * unit(rng);
        const double dv = noise_px * unit(rng);
        out.observed.pixel[k] += Vec2(du, dv);
      }
    }
    return true;
  }
  return false;
}

}  // namespace test_support
}  // namespace solver
}  // namespace tcpest
