#include "tcpest/loop/motion.hpp"

#include <cmath>
#include <cstring>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace loop {

solver::PoseVector MotionSequence::pose(const solver::InstrumentGeometry& geometry, std::uint32_t index) const noexcept {
  const double t = static_cast<double>(index) / (rate_hz > 0.0 ? rate_hz : 25.0);
  const double two_pi = 2.0 * solver::kPi;
  const double lambda = lambda_mid_mm + lambda_amp_mm * dmath::sin(two_pi * t / lambda_period_s);
  const double phi = phi_amp_rad * dmath::sin(two_pi * t / phi_period_s + 0.7);
  const double theta = theta_mid_rad + theta_amp_rad * dmath::sin(two_pi * t / theta_period_s + 1.9);
  return geometry.nominal_pose(lambda, phi, theta);
}

void model_truth(const solver::CameraModel& camera, const solver::InstrumentModel& model, const solver::PoseVector& r,
                 hal::FrameTruth& truth) noexcept {
  solver::CornerSet corners;
  model.corners(camera, r, corners, nullptr);
  truth.valid = true;
  for (int i = 0; i < solver::kNumParams; ++i) {
    truth.r[static_cast<std::size_t>(i)] = r[i];
  }
  truth.tcp_mm = {corners.tcp.x(), corners.tcp.y(), corners.tcp.z()};
  for (std::size_t k = 0; k < static_cast<std::size_t>(solver::kNumCorners); ++k) {
    truth.corners_px[k] = {corners.pixel[k].x(), corners.pixel[k].y()};
    truth.corner_visible[k] = corners.in_image[k];
  }
}

Status<hal::CameraError> ModelScene::render(std::uint32_t index, const MutableImageView& out,
                                            hal::FrameTruth& truth) noexcept {
  for (int y = 0; y < out.height; ++y) {
    std::memset(out.row(y), 96, static_cast<std::size_t>(out.width) * 3U);
  }
  if (index >= blind_from_ && index < blind_to_) {
    truth = hal::FrameTruth{};
    return ok_status<hal::CameraError>();
  }
  model_truth(camera_, model_, motion_.pose(model_.geometry(), index), truth);
  return ok_status<hal::CameraError>();
}

}  // namespace loop
}  // namespace tcpest
