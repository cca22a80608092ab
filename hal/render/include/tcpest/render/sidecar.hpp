// The ground-truth sidecar of a dataset image (docs/dataset-format.md): a
// JSON file with the image's stem (`0001.jpg` + `0001.json`) holding the
// configuration r, the TCP, the 12 apparent corners (k = 2 j + side, null
// when the model gives none), their visibility, the encoder prior and the
// render settings. The writer formats into a caller buffer; the reader
// tokenises without allocating and reports errors with the field's name.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "tcpest/common/diagnostic.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/solver/types.hpp"

namespace tcpest {
namespace render {

constexpr const char* kSidecarFormat = "tcpest-sidecar-1";
constexpr std::size_t kSidecarMaxBytes = 16384U;

struct SidecarInstrument {
  bool has_r = false;
  solver::PoseVector r = solver::PoseVector::Zero();
  bool has_tcp = false;
  solver::Vec3 tcp = solver::Vec3::Zero();
  std::array<solver::Vec2, solver::kNumCorners> corners{};
  std::array<bool, solver::kNumCorners> corner_present{};   // [u, v] given (not null)
  std::array<bool, solver::kNumCorners> corner_in_image{};
  std::array<bool, solver::kNumCorners> corner_visible{};
  InstrumentView view = InstrumentView::Visible;
};

struct Sidecar {
  char image[128] = {};   // file name of the image, same directory
  int width = 0;          // pixels (0 = not given)
  int height = 0;
  char set[16] = {};      // lab, hard, seq, single (free text for foreign datasets)
  int index = -1;
  std::uint64_t seed = 0U;          // the frame's scene seed (SceneSpec::seed)
  bool has_dataset_seed = false;
  std::uint64_t dataset_seed = 0U;  // `tcpest render --seed`
  SidecarInstrument instrument;
  bool has_prior = false;
  std::array<double, 3> prior{};  // [lambda mm, phi rad, theta rad]
  std::uint32_t hard_cases = 0U;  // HardCase bits
  bool has_time = false;
  double time_s = 0.0;
  // Render settings (informative).
  bool has_render = false;
  SceneSpec scene{};              // noise, blur, vignetting, exposure, clean, world_seed (r fields unused)
  double tissue_depth_mm = 0.0;
  int jpeg_quality = 0;           // 0 = raw frame
  int supersample = 0;
  // The motion blur's full streak (px, image; GroundTruth::motion_blur_*):
  // the image is the mean over this streak centred on the truth's image.
  // Written with the render settings when the frame has motion blur, so
  // that a reading of the streak can be checked against it.
  bool has_motion_blur = false;
  std::array<double, 2> motion_blur_px{};
  // A randomised appearance (`tcpest render --randomise`): scene.appearance
  // and the JPEG's chroma subsampling are written with the render settings,
  // and read back when given.
  bool has_appearance = false;
  ChromaSubsampling chroma = ChromaSubsampling::k420;
  bool has_second = false;
  SidecarInstrument second;
};

// Fills a sidecar from a render's ground truth and scene.
Sidecar make_sidecar(const GroundTruth& truth, const SceneSpec& scene, const RenderSettings& settings,
                     int width, int height) noexcept;

// Formats as JSON (UTF-8, LF). Returns the length, or 0 if `capacity` is too small.
std::size_t format_sidecar(const Sidecar& sidecar, char* out, std::size_t capacity) noexcept;

// Parses a sidecar. Required: "corners" (12 entries); everything else is
// optional (corner_visible defaults to "given and inside the image" when
// the size is known, else "given"). `file` names the source in errors.
Result<Sidecar, Diagnostic> parse_sidecar(const char* text, std::size_t length, const char* file) noexcept;

Result<Sidecar, Diagnostic> read_sidecar_file(const char* path) noexcept;
// False on an I/O error or a sidecar too large to format.
bool write_sidecar_file(const char* path, const Sidecar& sidecar) noexcept;

}  // namespace render
}  // namespace tcpest
