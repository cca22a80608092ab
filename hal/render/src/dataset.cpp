#include "tcpest/render/dataset.hpp"

#include <algorithm>
#include <cmath>

#include "scene_random.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/render/renderer.hpp"

namespace tcpest {
namespace render {

using solver::deg_to_rad;
using solver::kPi;

std::uint64_t image_seed(std::uint64_t seed, std::uint64_t index) noexcept {
  return splitmix64(seed * 0x9E3779B97F4A7C15ULL + splitmix64(index));
}

void lab_grid_joints(int index, double& lambda_mm, double& phi_rad, double& theta_rad) noexcept {
  const int i = std::min(std::max(index, 0), kLabGridSize - 1);
  const int i_theta = i % kLabGridTheta;
  const int i_phi = (i / kLabGridTheta) % kLabGridPhi;
  const int i_lambda = i / (kLabGridTheta * kLabGridPhi);
  lambda_mm = 10.0 + 30.0 * i_lambda / (kLabGridLambda - 1);
  phi_rad = deg_to_rad(-90.0 + 180.0 * i_phi / (kLabGridPhi - 1));
  theta_rad = deg_to_rad(-100.0 + 200.0 * i_theta / (kLabGridTheta - 1));
}

LabSample lab_sample(const solver::InstrumentGeometry& geometry, int index, std::uint64_t seed) noexcept {
  LabSample out;
  double lambda = 0.0;
  double phi = 0.0;
  double theta = 0.0;
  lab_grid_joints(index, lambda, phi, theta);
  Random rng(seed, std::uint64_t{0x1AB00000U} + static_cast<unsigned>(index));
  out.r = geometry.nominal_pose(lambda, phi, theta);
  out.r[solver::kXch] += kPlayPositionSigmaMm * rng.normal();
  out.r[solver::kYch] += kPlayPositionSigmaMm * rng.normal();
  out.r[solver::kPsi] += deg_to_rad(kPlayAngleSigmaDeg) * rng.normal();
  out.r[solver::kMu] += deg_to_rad(kPlayAngleSigmaDeg) * rng.normal();
  out.prior.joints[0] = lambda + rng.uniform(-kPriorLambdaMm, kPriorLambdaMm);
  out.prior.joints[1] = phi + rng.uniform(-kPriorAngleRad, kPriorAngleRad);
  out.prior.joints[2] = theta + rng.uniform(-kPriorAngleRad, kPriorAngleRad);
  return out;
}

std::uint32_t hard_cases_for(int index, std::uint64_t seed) noexcept {
  Random rng(seed, std::uint64_t{0x4A2D0000U} + static_cast<unsigned>(index));
  const int count = 1 + rng.below(3);
  std::uint32_t mask = 0U;
  int chosen = 0;
  for (int attempt = 0; attempt < 64 && chosen < count; ++attempt) {
    const std::uint32_t bit = 1U << static_cast<unsigned>(rng.below(kNumHardCases));
    if ((mask & bit) == 0U) {
      mask |= bit;
      ++chosen;
    }
  }
  return mask;
}

SequenceGenerator::SequenceGenerator(const solver::InstrumentGeometry& geometry, std::uint64_t seed,
                                     double frame_rate_hz) noexcept
    : geometry_(geometry),
      seed_(seed),
      frame_rate_hz_(frame_rate_hz > 0.0 ? frame_rate_hz : 25.0),
      world_seed_(splitmix64(seed ^ 0x3D0C1DULL) | 1U) {  // never 0 (0 means "derive from the frame seed")
  Random rng(seed, 0x5E9ULL);
  tissue_depth_mm_ = rng.uniform(70.0, 90.0);
  // Amplitudes sum to the half range of each joint (the weights 0.5, 0.3, 0.2).
  const double half_range[3] = {13.0, deg_to_rad(80.0), deg_to_rad(90.0)};
  const double weight[kWaves] = {0.5, 0.3, 0.2};
  for (std::size_t j = 0; j < 3; ++j) {
    for (std::size_t w = 0; w < static_cast<std::size_t>(kWaves); ++w) {
      joints_[j][w].amplitude = half_range[j] * weight[w];
      joints_[j][w].frequency_hz = rng.uniform(0.02, 0.06) * (1.0 + static_cast<double>(w));
      joints_[j][w].phase = rng.uniform(0.0, 2.0 * kPi);
    }
  }
  const double play_sigma[4] = {kPlayPositionSigmaMm, kPlayPositionSigmaMm, deg_to_rad(kPlayAngleSigmaDeg),
                                deg_to_rad(kPlayAngleSigmaDeg)};
  for (std::size_t p = 0; p < 4; ++p) {
    for (std::size_t w = 0; w < 2; ++w) {
      play_[p][w].amplitude = play_sigma[p] * (w == 0 ? 1.0 : 0.5);
      play_[p][w].frequency_hz = rng.uniform(0.004, 0.03);
      play_[p][w].phase = rng.uniform(0.0, 2.0 * kPi);
    }
  }
  const double bias[3] = {1.5, 0.08, 0.08};
  for (std::size_t j = 0; j < 3; ++j) {
    for (std::size_t w = 0; w < 2; ++w) {
      bias_[j][w].amplitude = bias[j] * (w == 0 ? 1.0 : 0.5);
      bias_[j][w].frequency_hz = rng.uniform(0.01, 0.05);
      bias_[j][w].phase = rng.uniform(0.0, 2.0 * kPi);
    }
  }
}

SequenceSample SequenceGenerator::sample(std::uint32_t frame) const noexcept {
  SequenceSample out;
  out.time_s = static_cast<double>(frame) / frame_rate_hz_;
  const double t = out.time_s;
  auto wave_sum = [t](const auto& waves) {
    double v = 0.0;
    for (const auto& w : waves) {
      v += w.amplitude * dmath::sin(2.0 * kPi * w.frequency_hz * t + w.phase);
    }
    return v;
  };
  const double lambda = 25.0 + wave_sum(joints_[0]);
  const double phi = wave_sum(joints_[1]);
  const double theta = wave_sum(joints_[2]);
  out.r = geometry_.nominal_pose(lambda, phi, theta);
  for (std::size_t p = 0; p < 4; ++p) {
    out.r[static_cast<int>(p)] += wave_sum(play_[p]);
  }
  // Encoders: the truth plus a slowly varying bias (backlash, cable
  // stretch) and a little frame-to-frame noise.
  Random rng(seed_, 0xE7C0000000ULL + frame);
  const double joints[3] = {lambda, phi, theta};
  const double noise[3] = {0.1, 0.005, 0.005};
  for (std::size_t j = 0; j < 3; ++j) {
    out.prior.joints[j] = joints[j] + wave_sum(bias_[j]) + noise[j] * rng.normal();
  }
  return out;
}

RandomLook random_look(std::uint64_t seed) noexcept {
  Random rng(seed, 7U);  // a stream of its own: the scene's draws stay as they were
  RandomLook look;
  Appearance& a = look.appearance;
  // The paint: each channel of each colour within 0.7..1.3 of ours, the
  // whole 0.5..1.3 as bright, capped at a reflectance of 0.95.
  const auto paint = [&rng](std::array<double, 3>& rgb) noexcept {
    const double brightness = rng.uniform(0.5, 1.3);
    for (double& c : rgb) {
      c = std::min(0.95, c * brightness * rng.uniform(0.7, 1.3));
    }
  };
  paint(a.blue_albedo);
  paint(a.yellow_albedo);
  a.stripe_gloss = rng.uniform(0.3, 2.4);
  const double shaft = rng.uniform(0.005, 0.06);
  a.shaft_albedo = {shaft, shaft, shaft * rng.uniform(1.0, 1.2)};
  a.shaft_gloss = rng.uniform(0.1, 1.0);
  const double grasper = rng.uniform(0.25, 0.6);
  a.grasper_albedo = {grasper, grasper, grasper * rng.uniform(1.0, 1.1)};
  a.grasper_gloss = rng.uniform(0.6, 2.5);
  a.tissue_tint = {rng.uniform(0.8, 1.2), rng.uniform(0.7, 1.4), rng.uniform(0.7, 1.4)};
  a.white_balance = {rng.uniform(0.8, 1.25), 1.0, rng.uniform(0.8, 1.25)};
  look.exposure = rng.uniform(0.7, 1.4);
  look.noise_sigma = rng.uniform(0.5, 3.0);
  look.blur_sigma_px = rng.uniform(0.3, 1.2);
  look.vignetting = rng.uniform(0.2, 0.6);
  look.jpeg_quality = 70 + rng.below(26);  // 70..95
  const int chroma = rng.below(5);          // 4:2:0 three times in five, 4:2:2 and 4:4:4 once each
  look.chroma = chroma < 3 ? ChromaSubsampling::k420 : (chroma == 3 ? ChromaSubsampling::k422 : ChromaSubsampling::k444);
  return look;
}

void random_build(std::uint64_t set_seed, Appearance& appearance) noexcept {
  Random rng(set_seed, 8U);  // a stream of its own, as random_look's
  // The parts the solver does not model: the shaft from 0.9 to 1.03 times
  // model.md's default (at most the tube's 1.81 mm), the grasper from 0.85
  // to 1.15 times.
  appearance.shaft_radius_scale = rng.uniform(0.9, 1.03);
  appearance.grasper_radius_scale = rng.uniform(0.85, 1.15);
  // The lamp up to 4 mm from the lens, in any direction (light guides
  // beside the lens of a 10 mm endoscope).
  const double lamp_mm = rng.uniform(0.0, 4.0);
  const double lamp_rad = rng.uniform(0.0, 6.283185307179586);
  appearance.lamp_offset_mm = {lamp_mm * dmath::cos(lamp_rad), lamp_mm * dmath::sin(lamp_rad)};
}

}  // namespace render
}  // namespace tcpest
