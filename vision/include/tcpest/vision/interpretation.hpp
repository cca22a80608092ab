// Stage 2 of feature extraction (paper section 2.3): the interpretation
// tree. Which region is which marker (levels 1..5 from the base), with
// virtual nodes merging two regions of a level and the path chosen by its
// Bayesian posterior under per-marker priors: the generic one of a first
// frame, one predicted from the models at a configuration (the encoders),
// or one from the last successful frames (TemporalPriors). Allocation-free;
// no recursion; every loop has a fixed bound.
#pragma once

#include <array>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {

struct InterpretationConfig {
  // Colour of markers 1..5 from the base (the geometry's marker_colors).
  std::array<PixelClass, kNumMarkers> marker_classes{
      {PixelClass::Blue, PixelClass::Yellow, PixelClass::Blue, PixelClass::Yellow, PixelClass::Blue}};
  double max_link_angle_rad = 1.0471975511965976;  // 60 deg: the skeleton's largest turn per link
  double adjacency_factor = 1.35;           // centroid distance <= factor * (sum of half extents) + slack
  double adjacency_slack_px = 3.0;
  double level_reward = 9.0;                // log-likelihood credit of one more labelled level
  double orientation_weight = 0.0;          // log-likelihood of the dark-shaft / bright-grasper cue
};

// Per-marker Gaussian priors of stage 2: shape (half axes), distance to the
// previous marker's centroid, and (when known) position.
struct MarkerPrior {
  double half_major = 0.0, half_major_sd = 0.0;  // pixels
  double half_minor = 0.0, half_minor_sd = 0.0;
  double parent_distance = 0.0, parent_distance_sd = 0.0;
  Point centroid{};
  double centroid_sd = 0.0;  // 0 = position unknown
  bool in_image = true;      // the marker is expected in the image
};

struct MarkerPriors {
  std::array<MarkerPrior, kNumMarkers> marker{};
  bool relative_only = true;  // generic prior: shape/distance judged relative to neighbours
};

class Interpreter {
 public:
  Interpreter() noexcept = default;
  // Validates the configuration (BadParameter) and allocates the
  // interpreter (OutOfMemory); it needs no other buffer.
  static Result<std::unique_ptr<Interpreter>, VisionError> create(const InterpretationConfig& config) noexcept;

  // The interpretation of `region_set` of highest score into `out` (reset
  // first); NoInstrument when no region can be labelled. `image`: the frame
  // the regions came from, whose luminance beyond the chain's ends gives
  // the orientation cue (orientation_weight; an invalid view: no cue).
  Status<VisionError> interpret(const RegionSet& region_set, const ImageView& image, const MarkerPriors& priors,
                                Interpretation& out) const noexcept;

  const InterpretationConfig& config() const noexcept { return config_; }

 private:
  InterpretationConfig config_{};
};

// Stage-2 priors. `generic`: the documented prior of the very first frame
// (relative shape and distance terms, a weak position term from the model at
// the nominal pose). `from_model`: predicted from a configuration r (e.g. the
// encoders) through the instrument and camera models.
MarkerPriors generic_priors(const solver::CameraModel& camera, const solver::InstrumentModel& model) noexcept;
MarkerPriors model_priors(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                          const solver::PoseVector& r) noexcept;

// Gaussian priors per marker from the last kHistory successful frames of a
// sequence.
class TemporalPriors {
 public:
  static constexpr int kHistory = 5;
  void reset() noexcept { count_ = 0; next_ = 0; }
  // Adds a frame whose interpretation succeeded.
  void add(const Interpretation& interpretation) noexcept;
  // Needs at least kMinFrames frames; otherwise returns false.
  bool priors(MarkerPriors& out) const noexcept;
  int frames() const noexcept { return count_; }
  static constexpr int kMinFrames = 2;

 private:
  struct Entry {
    std::array<bool, kNumMarkers> found{};
    std::array<Region, kNumMarkers> region{};
  };
  std::array<Entry, kHistory> entries_{};
  int count_ = 0;
  int next_ = 0;
};

}  // namespace vision
}  // namespace tcpest
