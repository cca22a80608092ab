// The simulated endoscope: renders what the STRAS endoscope would see of one
// or two instruments in a given configuration, with exact ground truth.
//
// Geometry comes from the same InstrumentModel and CameraModel as the solver
// (model.md); every output pixel's ray is the exact inverse of the plumb_bob
// distortion, computed once per camera at creation. A Renderer allocates all
// its tables and scratch buffers in create(); render() never allocates.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace render {

enum class RenderError : std::uint8_t {
  OutOfMemory,     // the per-camera tables could not be allocated
  BadSettings,     // a render setting is out of its range
  BadImage,        // the output view is invalid or not the camera's size
  BadScene,        // a non-finite configuration or setting in the scene
  ImageTooLarge,   // the camera image exceeds kMaxPixels
};
const char* to_string(RenderError e) noexcept;

// Upper bound of the camera size a renderer accepts (8 Mpixel: 4K UHD).
constexpr long kMaxPixels = 3840L * 2160L;

// Fixed for the renderer's life (they size its tables).
struct RenderSettings {
  int supersample = 4;               // samples per axis in pixels on an edge (1..8)
  int segments_per_stripe = 16;      // chords per marker stripe of the bending section (2..32)
};

// Hard cases, each switchable per image (bit mask).
enum HardCase : std::uint32_t {
  kHardReflection = 1U << 0U,   // the instrument's mirror image on wet tissue
  kHardOccluder = 1U << 1U,     // a tissue flap or blood drop over part of the instrument
  kHardHaze = 1U << 2U,         // smoke / haze
  kHardDecoy = 1U << 3U,        // a blue or yellow blob on the tissue
  kHardNoise = 1U << 4U,        // strong sensor noise
  kHardMotionBlur = 1U << 5U,   // motion blur (camera/scene motion during exposure)
};
constexpr int kNumHardCases = 6;
constexpr std::uint32_t kAllHardCases = (1U << kNumHardCases) - 1U;
// Short names ("reflection", "occluder", "haze", "decoy", "noise", "motion_blur").
const char* hard_case_name(int bit_index) noexcept;

// How the instrument, the tissue and the sensor look: the defaults are the
// renderer's own look (every set rendered before this existed); `tcpest
// render --randomise` draws each frame's from documented ranges
// (docs/rendering.md, "Randomised appearance"). Linear reflectances 0..1.
struct Appearance {
  std::array<double, 3> blue_albedo{0.012, 0.06, 0.36};    // RGB of the blue stripes
  std::array<double, 3> yellow_albedo{0.62, 0.50, 0.04};   // RGB of the yellow stripes
  double stripe_gloss = 1.2;                               // the sleeve's specular weight
  std::array<double, 3> shaft_albedo{0.008, 0.008, 0.009};
  double shaft_gloss = 0.35;
  std::array<double, 3> grasper_albedo{0.42, 0.42, 0.44};
  double grasper_gloss = 1.6;
  std::array<double, 3> tissue_tint{1.0, 1.0, 1.0};        // multiplies the tissue's reflectance
  std::array<double, 3> white_balance{1.0, 1.0, 1.0};      // the sensor's gain per channel
  // The shaft's and the grasper's radii as multiples of the geometry's.
  // model.md gives those radii only as rendering defaults (the solver does
  // not use them), so a real instrument's may differ: the estimator must
  // not rely on them (docs/rendering.md, "Randomised appearance").
  double shaft_radius_scale = 1.0;
  double grasper_radius_scale = 1.0;
  // The lamp's position in the lens plane (mm, camera x and y; 0, 0: at the
  // lens, light and view coincide). An endoscope's light guides sit beside
  // the lens: shading and highlights then fall off-centre on the tube.
  std::array<double, 2> lamp_offset_mm{0.0, 0.0};
};
// True when every value is finite and within what a render can show
// (reflectances 0..1, gloss 0..4, tints and gains 0.25..4, radius scales
// 0.5..1.5, the lamp within 10 mm of the lens).
bool valid_appearance(const Appearance& appearance) noexcept;

// What one frame shows. Everything random in the frame is drawn from `seed`.
struct SceneSpec {
  solver::PoseVector r = solver::PoseVector::Zero();   // instrument 1 (left channel)
  bool second_instrument = false;
  solver::PoseVector r2 = solver::PoseVector::Zero();  // instrument 2 (right channel)
  std::uint32_t hard_cases = 0U;                       // HardCase bits
  std::uint64_t seed = 1U;        // this frame: sensor noise (and the world when world_seed is 0)
  // The world: tissue (texture placement, tilt, depth draw) and the hard
  // cases' layout. A video keeps it fixed while `seed` changes per frame;
  // 0 = derived from `seed` (every frame a different scene).
  std::uint64_t world_seed = 0U;
  // Sensor and optics. `clean` turns off noise, blur, vignetting and the
  // tissue's specular spots: the renders the geometric tests measure.
  bool clean = false;
  double noise_sigma = 1.5;        // 8-bit levels, at mid grey (strong noise: x4)
  double blur_sigma_px = 0.5;      // slight optical blur
  double vignetting = 0.45;        // brightness lost at the image corner (0..1)
  double exposure = 1.0;           // multiplies the light
  double tissue_depth_mm = 0.0;    // mean tissue depth; 0 = drawn in [40, 90] from the seed
  Appearance appearance{};
};

// Whether an instrument shows. BehindCamera: no part in front of the camera.
// OutOfView: in front, but nothing of it projects into the image (render()
// also says so when no pixel centre shows it, e.g. entirely hidden).
enum class InstrumentView : std::uint8_t { Visible, BehindCamera, OutOfView };
const char* to_string(InstrumentView v) noexcept;

struct InstrumentTruth {
  solver::PoseVector r = solver::PoseVector::Zero();
  solver::Vec3 tcp = solver::Vec3::Zero();                 // mm, camera frame
  std::array<solver::Vec2, solver::kNumCorners> corners{};  // pixels (valid when present)
  std::array<solver::Vec3, solver::kNumCorners> corner_points{};  // mm, camera frame
  std::array<bool, solver::kNumCorners> present{};        // the model gives the feature
  std::array<bool, solver::kNumCorners> in_image{};       // present and inside the image
  std::array<bool, solver::kNumCorners> visible{};        // in the image and not hidden (ray cast)
  InstrumentView view = InstrumentView::OutOfView;
  int corners_in_image = 0;
  int corners_visible = 0;
};

struct GroundTruth {
  std::array<InstrumentTruth, 2> instruments{};
  int instrument_count = 1;
  std::uint32_t hard_cases = 0U;
  double tissue_depth_mm = 0.0;  // the depth actually used
  std::uint64_t seed = 0U;
  // The motion blur's full streak (px, image; kHardMotionBlur, zero
  // without): the image is the mean over the streak centred on the
  // truth's (mid-exposure) image. In the sidecar as render.motion_blur_px.
  double motion_blur_dx_px = 0.0;
  double motion_blur_dy_px = 0.0;
};

// What the centre of each pixel shows in the last render (Renderer::labels):
// for colour-model training and for checking detectors against the truth.
enum PixelLabel : std::uint8_t {
  kPixelTissue = 0,
  kPixelDecoy = 1,        // the decoy blob on the tissue
  kPixelOccluder = 2,     // tissue flap or blood drop in front
  kPixelReflection = 3,   // tissue showing the instrument's mirror image
  kPixelInstrument = 8,   // + 8 * instrument (0, 1) + part: 0 shaft, 1..5 marker 1..5, 6 grasper
  kPixelNoRay = 255,      // beyond the calibration's fold: black
};
constexpr std::uint8_t kPartShaftLabel = 0U;
constexpr std::uint8_t kPartMarker1Label = 1U;
constexpr std::uint8_t kPartGrasperLabel = 6U;

class Renderer {
 public:
  // Builds the per-pixel ray tables (iterative undistortion) and scratch.
  static Result<std::unique_ptr<Renderer>, RenderError> create(const solver::CameraModel& camera,
                                                               const solver::InstrumentModel& instrument,
                                                               const RenderSettings& settings) noexcept;
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;
  Renderer(Renderer&&) = delete;
  Renderer& operator=(Renderer&&) = delete;

  const solver::CameraModel& camera() const noexcept;
  const solver::InstrumentModel& instrument() const noexcept;
  // The second instrument's nominal pose: the first's r_m* mirrored in x
  // (x_ch -> -x_ch, psi -> -psi), with the given joints.
  solver::PoseVector mirrored_nominal_pose(double lambda_mm, double phi_rad, double theta_rad) const noexcept;

  // Renders one frame into `out` (the camera's size) and fills `truth`.
  // `coverage`, when given (width * height floats), receives the
  // instrument's anti-aliased coverage per pixel (1 = fully covered by an
  // unoccluded instrument), the quantity the geometric tests measure.
  Status<RenderError> render(const SceneSpec& scene, MutableImageView out, GroundTruth& truth,
                             float* coverage = nullptr) noexcept;

  // Per pixel (row-major, width * height), the PixelLabel of the last
  // render()'s pixel centres; valid until the next render().
  const std::uint8_t* labels() const noexcept;

  // The ground truth alone (no pixels): corners, visibility, and the view
  // status from the geometry (centreline samples within 20 px of the image).
  Status<RenderError> ground_truth(const SceneSpec& scene, GroundTruth& truth) noexcept;

  struct Impl;

 private:
  explicit Renderer(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

}  // namespace render
}  // namespace tcpest
