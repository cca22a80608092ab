// A small ray-cast endoscopic scene for the vision tests: the shaft, the
// bending section with its five stripes and the grasper as cylinders in front
// of a tissue-like background, seen through the CameraModel (distortion
// included), anti-aliased at the silhouettes. Ground truth comes from the
// InstrumentModel (model.md), with a ray-cast visibility test per corner.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "tcpest/common/image.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {
namespace test {

struct SceneStyle {
  std::array<std::uint8_t, 3> blue{{35, 75, 190}};
  std::array<std::uint8_t, 3> yellow{{225, 190, 40}};
  std::array<std::uint8_t, 3> shaft{{45, 45, 50}};
  std::array<std::uint8_t, 3> grasper{{150, 150, 158}};
  std::array<std::uint8_t, 3> tissue{{185, 95, 85}};
  double noise_sd = 0.0;        // per channel, 8-bit units
  double tissue_texture = 18.0; // amplitude of the background's smooth variation
  double ambient = 0.35;        // shading: ambient + (1 - ambient) |n . view|
  int supersampling = 4;        // per axis, at silhouettes
  std::uint32_t seed = 1U;
};

struct Truth {
  solver::CornerSet corners;
  std::array<bool, solver::kNumCorners> visible{};  // in the image and not self-occluded
  int visible_count = 0;
};

class Scene {
 public:
  Scene(const solver::CameraModel& camera, const solver::InstrumentModel& model) noexcept
      : camera_(camera), model_(model) {}
  // Renders into `pixels` (resized to W*H*3) and fills the truth. `classes`
  // (optional) receives the true class of each pixel centre (for training).
  void render(const solver::PoseVector& r, const SceneStyle& style, std::vector<std::uint8_t>& pixels,
              Truth& truth, std::vector<PixelClass>* classes = nullptr) const;
  ImageView view(const std::vector<std::uint8_t>& pixels) const noexcept {
    return ImageView{pixels.data(), camera_.width(), camera_.height(), static_cast<std::size_t>(camera_.width()) * 3U};
  }

 private:
  solver::CameraModel camera_;
  solver::InstrumentModel model_;
};

// The poses of model.md's reference grid (lambda 10..40 mm, phi -90..90 deg,
// theta -100..100 deg, 7 x 7 x 6) at the nominal channel pose, keeping those
// with at least `min_corners` corners in the image.
std::vector<solver::PoseVector> reference_grid(const solver::CameraModel& camera,
                                               const solver::InstrumentModel& model, int min_corners);

}  // namespace test
}  // namespace vision
}  // namespace tcpest
