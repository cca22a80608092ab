// Start-up helpers shared by the subcommands: load the camera calibration and
// the instrument configuration named on the command line (or the built-in
// defaults), reporting any problem on stderr with file, line and field.
#pragma once

#include <cstddef>

#include "cli/args.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"

namespace tcpest {
namespace cli {

// The options every model-using command takes, with one help text.
constexpr OptionSpec kCalibOption{"calib", "CAM.yaml",
                                  "camera calibration (ROS camera_info or OpenCV FileStorage YAML); "
                                  "default: the PAL camera of model.md"};
constexpr OptionSpec kInstrumentConfigOption{"config", "CFG.yaml",
                                             "configuration: the instrument and the loop:/can:/rt: sections, as "
                                             "`tcpest run` reads them; default: the built-in geometry and defaults"};

constexpr OptionSpec kGuidedRoundsOption{"guided-rounds", "N",
                                         "model-guided corner rounds after the first solve, 0..4 (default: the "
                                         "configuration's loop.guided_rounds, 1; 0: stage 4's corners, the paper's "
                                         "pipeline)"};
constexpr OptionSpec kDenseOption{"dense", nullptr,
                                  "the dense fit (every pixel around the instrument against a rendering of the "
                                  "model) on each frame not yet valid, on each valid one where at most 7 corners "
                                  "were measured on the image, and on each where a motion streak was read; its "
                                  "fits held within 3 mm and 0.2 rad of the encoders' joints when given; its "
                                  "corners, blended with the pipeline's where the two lie within 3 px, are solved, "
                                  "and the estimate is reported degraded, or valid where it replaced a valid one "
                                  "within 2 mm of its TCP; offline only: several seconds per such frame "
                                  "(docs/vision.md)"};

struct ModelSetup {
  solver::CameraModel camera;
  solver::InstrumentModel instrument;
};

// calib_path / config_path may be nullptr: built-in PAL camera / default
// geometry. `command` prefixes error messages. False after printing an error.
bool load_model_setup(const char* command, const char* calib_path, const char* config_path,
                      ModelSetup& out) noexcept;

// Creates a directory (one level) unless it exists; true when `path` is a
// directory afterwards (errno ENOTDIR when it exists as something else).
bool make_directory(const char* path) noexcept;

// Creates `path` and its missing parents, at most kMaxDirectoryDepth levels
// deep (paths up to kMaxDirectoryPath characters); true when `path` is a
// directory afterwards. On failure `failed` holds the directory that could
// not be made (the whole path when it is too long or too deep) and errno
// says why.
constexpr std::size_t kMaxDirectoryDepth = 32U;
constexpr std::size_t kMaxDirectoryPath = 4095U;
bool make_directories(const char* path, char* failed, std::size_t failed_capacity) noexcept;

}  // namespace cli
}  // namespace tcpest
