// Feature extraction, paper section 2.3: from an endoscopic RGB frame to up to
// 12 labelled apparent corners (k = 2 j + side, model.md), with the regions
// and the Bezier borders they came from. FeatureExtractor composes the four
// stages, each a component of its own:
//   1. regions.hpp: classify pixels through a lookup table, connected
//      components + moments (RegionFinder)
//   2. interpretation.hpp: the interpretation tree, which region is which
//      marker (1..5 from the base) (Interpreter)
//   3. borders.hpp: edge points along the skeleton's normals, a quadratic
//      Bezier per side fitted by IRLS with Tukey's biweight (BorderFitter)
//   4. corners.hpp: zero crossings of the (yellow - blue) chroma profile
//      along each border, plus the transitions to the shaft and the grasper
//      (CornerFinder)
// and adds the fits guided by the instrument's model after a first pose.
// Every buffer is allocated once in FeatureExtractor::create(); running a
// frame allocates nothing. No recursion; every loop has a fixed bound.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/borders.hpp"
#include "tcpest/vision/classifier_lut.hpp"
#include "tcpest/vision/color_model.hpp"
#include "tcpest/vision/corners.hpp"
#include "tcpest/vision/extraction.hpp"
#include "tcpest/vision/interpretation.hpp"
#include "tcpest/vision/regions.hpp"

namespace tcpest {
namespace vision {

// The largest smear search of the blurred edge's model (px either way;
// RefinerConfig::refine_streak_edge_smear_search_px): 16 fits a reading.
constexpr double kMaxStreakEdgeSmearSearchPx = 16.0;

// The model-guided fits' part of ExtractorConfig (refine_corners,
// fit_pose_to_image, read_motion_streak, fit_channel_to_shaft,
// fit_insertion_to_base_rim; docs/vision.md "Model-guided corners").
struct RefinerConfig {
  int refine_arc_samples = 16;              // points of each boundary's visible arc
  double refine_arc_span = 0.8;             // share of the half arc used (its ends graze the silhouette)
  double refine_search_mm = 1.2;            // along-tube search window of the colour change, +/-
  double refine_min_arc_share = 0.35;       // arc points that must see the colour change
  double refine_max_spread_mm = 0.25;       // MAD of their shifts
  double refine_edge_search_px = 4.0;       // silhouette search window along its normal, +/-
  int refine_min_edge_points = 3;           // silhouette points per corner (of 8)
  double refine_predicted_confidence = 0.5; // a corner whose boundary arc was not measured
  int refine_fit_iterations = 10;            // image fit: Gauss-Newton iterations (each re-measures), <= 20
  double refine_fit_tolerance_px = 0.05;    // ... converged when no point read moves more than this
  double refine_coarse_search_mm = 2.5;     // a coarse start's first iterations: along-tube window, +/-
  double refine_coarse_edge_search_px = 10.0;  // ... and silhouette window, +/-
  bool refine_shaft_readings = true;        // the image fit also reads the shaft's silhouette
  bool refine_grasper_readings = true;      // ... and the grasper's (docs/vision.md "The grasper")
  // A fine iteration of the image fit needs the arcs of 2 boundaries (they
  // hold the tube along its length), or of 1 when the silhouette is read at
  // this many points (of the 20 along the striped section, at the gradient
  // peak's centre): an occluder hiding all but one boundary of a tube whose
  // outline is still seen (docs/vision.md, "Occluders"). Such a fit gives at
  // most a Degraded estimate (GuidedOptions::min_valid_fit_boundaries).
  int refine_one_boundary_min_silhouette = 8;
  // Motion blur along the tube smears every boundary's colour change over
  // 5-14 px, so few arc readings pass the test of clear colours at the
  // crossing's neighbouring samples. The image fit then also reads a change
  // that is clear within refine_smear_clear_reach samples (1 px apart) of
  // its crossing, but keeps those readings only when the frame shows the
  // smear: they are at least refine_smear_share of the arc readings of the
  // iteration, and at least refine_smear_min_arc_readings readings in all
  // (fewer: a pose beside the tube reading stray colour; docs/vision.md).
  int refine_smear_clear_reach = 3;         // samples, 1..8 (1: no smeared reading)
  double refine_smear_share = 0.5;
  int refine_smear_min_arc_readings = 20;
  // At the first iteration whose arcs read as smeared, the streak itself is
  // read from the stripe boundaries' colour-change widths around their
  // arcs and the silhouette's widths across the blue stripes
  // (ImageFitSummary::streak_px). When it is refine_streak_min_px long or
  // longer, it holds for that and every later iteration: the silhouette
  // readings whose smear across (|streak . normal|) is
  // refine_streak_across_px or more take the outer end of the gradient's
  // plateau, moved in by half that smear, instead of the peak's centre, in
  // the image fit; refine_corners, given the fit's streak, reads no offset
  // beside such a silhouette (docs/vision.md).
  bool refine_streak = true;
  double refine_streak_min_px = 6.0;
  double refine_streak_across_px = 5.0;
  // Under that smear the silhouette is read by a model of the blurred edge
  // (the tube's shading falling to its limb, then the tissue, averaged over
  // the smear across) fitted to the linear-light profile, instead of the
  // gradient plateau's outer end moved in by half the smear: the outer end
  // leans on the streak's length and the plateau's shape, which the
  // shading bends (docs/vision.md "The blurred edge's model"). false: the
  // outer end.
  bool refine_streak_edge_model = true;
  // ... with the smear across also tried this much shorter and longer than
  // the read one, the fit of the least residual kept (0: the read smear
  // alone; docs/vision.md: three fits per reading, 2 px apart, did as well
  // as seven 1 px apart).
  double refine_streak_edge_smear_search_px = 2.0;  // 0..kMaxStreakEdgeSmearSearchPx
  // A smear across the tube leaves the arcs sharp, so they never read as
  // smeared: the streak is then also read at the first fine iteration that
  // reads refine_streak_unsmeared_min_boundaries boundaries or more (a pose
  // on the tube), and held when refine_streak_unsmeared_min_px long or
  // longer (a sharp frame's widths at a pose a little off can add up to
  // 6 px; docs/vision.md "The smear across the tube").
  bool refine_streak_unsmeared = true;
  int refine_streak_unsmeared_min_boundaries = 4;
  double refine_streak_unsmeared_min_px = 7.0;
  // A smear along the tube turns every boundary's colour change into a ramp
  // as long as the smear, clear only half of it from the crossing: at a
  // pose a few pixels off, the arcs read too few boundaries to hold the
  // tube and the fit fails. Then (at a fine iteration, once per fit) the
  // streak is read at that pose if none is held yet, and held when
  // refine_streak_arc_retry_min_px long or longer; with a streak the same
  // pose is read again, and every later iteration too, with each arc's
  // clear reach widened to half the smear along its normal plus one sample
  // (at most 8) and its window to that reach plus 2 px, its readings kept
  // as the frame's smear, and the silhouette read under that streak as
  // under any held one (docs/vision.md "Arcs under a streak"). Only a fit
  // that would have failed reads differently. The length gate is the
  // unsmeared read's, for the same reason: a sharp frame's widths at a pose
  // off the tube add up to 6-8 px (lab frame 180; 6 px lost 4 hard frames).
  bool refine_streak_arc_retry = true;
  double refine_streak_arc_retry_min_px = 7.0;
  // Under that streak, the tip arc's colour change (blue to the grey
  // grasper) crosses the blue margin's zero where the smeared mix is about
  // 65 % blue (L*a*b* chroma is not linear in the mix), not at its middle:
  // the reading lies this share of the smear across the arc short of the
  // boundary, towards the base, and is moved back by it (docs/vision.md
  // "The tip arc under a streak"). 0: no correction.
  double refine_smear_tip_bias = 0.15;
  // The base boundary's arc shows no usable colour change (the shaft's
  // outline), but the first stripe's end face, the ring between the
  // shaft's radius and the tube's at s = 0, faces the camera when the
  // camera is behind it and shows as a thin bright rim. refine_corners
  // reads the base's position along the tube on that rim: the lightness
  // ridge nearest to the model's, at refine_base_rim_share of the way from
  // the shaft's radius to the tube's (where the ring is seen past the
  // shaft), standing refine_base_rim_contrast (lightness, 0..1) above the
  // samples 3 px on either side; the median over the arc points, when
  // refine_min_arc_share of them see it with a MAD within
  // refine_base_rim_max_spread_mm (docs/vision.md).
  bool refine_base_rim = true;
  double refine_base_rim_share = 0.6;
  double refine_base_rim_contrast = 0.05;
  double refine_base_rim_max_spread_mm = 0.05;
  // fit_insertion_to_base_rim's steps along the insertion, and how far
  // they reach each way (mm; at most FeatureExtractor::kMaxRimScanSteps
  // steps each way).
  double refine_rim_scan_step_mm = 0.5;
  double refine_rim_scan_range_mm = 4.0;
};

// The extractor's configuration: each stage's, and the model-guided fits'.
// The model-guided fits also read two of the stages': the markers' colours
// (interpretation.marker_classes: which colour change each boundary shows)
// and the edge's outward correction (borders.edge_offset_px, on the
// silhouette's readings). Stage 4's local borders have their own IRLS
// parameters (corners.tukey_c, ...), stage 3's by default.
struct ExtractorConfig {
  RegionsConfig regions{};
  InterpretationConfig interpretation{};
  BordersConfig borders{};
  CornersConfig corners{};
  RefinerConfig refiner{};
};

// What fit_pose_to_image did.
struct ImageFitSummary {
  int iterations = 0;
  int arc_readings = 0;         // colour-change readings on the boundary arcs (last iteration)
  int silhouette_readings = 0;  // silhouette readings (last iteration)
  int grasper_readings = 0;     // the grasper's silhouette readings (last iteration; not in the above)
  int boundaries = 0;           // boundaries with arc readings
  // The longest run of consecutive colour boundaries (j = 1..4, blue
  // against yellow) with arc readings: what the validity rule counts
  // (GuidedOptions::min_valid_fit_boundaries). The tip's change (blue
  // against the grasper) is left out, and so is a boundary beyond a gap:
  // an occluder's edge over a blue stripe reads as the tip's change, and a
  // fit two stripes along reads a far boundary with a gap before it
  // (docs/vision.md, "Occluders").
  int boundary_run = 0;
  double rms_px = 0.0;          // robust RMS of the readings' residuals at the result (the grasper's left out)
  bool converged = false;
  bool smeared = false;         // the last iteration read the arcs as smeared (refine_smear_*)
  // The motion-blur streak (px, image; sign arbitrary) under which the last
  // iteration read the silhouette (refine_streak_*); zero when none was
  // read or it was too short.
  solver::Vec2 streak_px = solver::Vec2::Zero();
  // Of silhouette_readings, those the gradient peak's centre gives (all of
  // them without a streak): what the validity rule counts (GuidedOptions).
  int plain_silhouette_readings = 0;
  // How far outside the model's silhouettes the shaft's and the grasper's
  // were read on both sides alike (px, the mean of the two sides' median
  // offsets at the last iteration, before the learned width was taken off;
  // NaN: not read on both sides). What PartWidths learns from.
  double shaft_width_px = std::numeric_limits<double>::quiet_NaN();
  double grasper_width_px = std::numeric_limits<double>::quiet_NaN();
};

// The shaft's and the grasper's widths as the images show them (ours,
// docs/vision.md "Part widths"). model.md gives their radii as defaults for
// rendering, not as the instrument's; the edge's blur and shading move a
// silhouette reading too. A part read wider or narrower than the model
// moves both its silhouettes outwards or inwards alike, which the image fit
// would take for a change of depth. So the fit takes off each part's
// readings the median of what the last kWindow valid frames read
// (ImageFitSummary::*_width_px), once kMinFrames have and they agree on it
// (the median beyond kAgreement standard errors): learned from the scene,
// forgotten as it changes, reset with the node (docs/decisions/0054).
// Fixed size, no heap.
class PartWidths {
 public:
  static constexpr int kWindow = 15;
  static constexpr int kMinFrames = 3;
  static constexpr double kAgreement = 2.0;
  // A learned width is bounded: beyond it a reading is no silhouette of the part.
  static constexpr double kMaxWidthPx = 4.0;
  // Learns from the image fit of a frame whose estimate is valid.
  void learn(const ImageFitSummary& fit) noexcept;
  void reset() noexcept { *this = PartWidths{}; }
  // The learned widths (px; 0 until kMinFrames have been learned). Kept
  // from the last learn(): every iteration of every fit reads them.
  double shaft_px() const noexcept { return shaft_.learned_px(); }
  double grasper_px() const noexcept { return grasper_.learned_px(); }

 private:
  class Window {
   public:
    void add(double px) noexcept;
    double learned_px() const noexcept { return learned_px_; }

   private:
    double median_px() const noexcept;
    double values_[kWindow] = {};  // a ring of the last count_ readings (px)
    int count_ = 0;
    int next_ = 0;
    double learned_px_ = 0.0;  // median_px() after the last add()
  };
  Window shaft_{};
  Window grasper_{};
};

// What fit_channel_to_shaft did.
struct ShaftFitSummary {
  int iterations = 0;
  int readings = 0;        // silhouette readings at the last iteration (both sides)
  double rms_px = 0.0;     // robust RMS of their residuals
};

namespace detail {
class BlurredEdgeScratch;  // src/blurred_edge.hpp
struct FitScratch;         // src/fit_scratch.hpp
}  // namespace detail

class FeatureExtractor {
 public:
  FeatureExtractor() noexcept = default;
  ~FeatureExtractor();  // out of line: the scratch types are incomplete here
  // Owned through create()'s pointer, never copied or moved (its buffers are sized at create()).
  FeatureExtractor(const FeatureExtractor&) = delete;
  FeatureExtractor& operator=(const FeatureExtractor&) = delete;
  FeatureExtractor(FeatureExtractor&&) = delete;
  FeatureExtractor& operator=(FeatureExtractor&&) = delete;
  // Creates the four stages and allocates every buffer (start-up only); the
  // colour model builds stage 1's lookup table.
  static Result<std::unique_ptr<FeatureExtractor>, VisionError> create(const ExtractorConfig& config,
                                                                       const ColorModel& colors) noexcept;

  // Stage 1 (RegionFinder), on a new frame: the results of the last one
  // are cleared. Also keeps the class image for stage 3 and the overlay.
  Status<VisionError> find_regions(const ImageView& image) noexcept;
  // Stage 2 (Interpreter) on stage 1's regions, with the given priors.
  Status<VisionError> interpret(const MarkerPriors& priors) noexcept;
  // Stage 3 (BorderFitter) on the same frame.
  Status<VisionError> fit_borders(const ImageView& image) noexcept;
  // Stage 4 (CornerFinder) on the same frame.
  Status<VisionError> find_corners(const ImageView& image) noexcept;
  // After a first pose r (ours, not the paper's): each boundary's circle is
  // moved along the tube to where its visible arc meets the colour change in
  // the image, and its limb points are put on the silhouette measured next
  // to them. Replaces result().corners (stage 4's are kept in
  // stage4_corners); fails with NoInstrument when no boundary is measured.
  // The silhouette offsets are read at the gradient peak's centre even on
  // a frame the image fit read under a streak (ImageFitSummary::streak_px):
  // measured the same frames, two more corners found (docs/vision.md).
  // But where that streak (`streak_px`, px, image; zero: none) smears the
  // silhouette across by refine_streak_across_px or more, the peak's centre
  // is pulled towards the darker side: no offset is read there, and the
  // corner stays the fitted pose's limb point, which the image fit put on
  // the plateau's outer end.
  Status<VisionError> refine_corners(const ImageView& image, const solver::CameraModel& camera,
                                     const solver::InstrumentModel& model, const solver::PoseVector& r,
                                     const solver::Vec2& streak_px = solver::Vec2::Zero()) noexcept;
  // Fits the pose r to the image itself (ours): the visible arc of every
  // boundary onto its colour change and the model's silhouette onto the
  // colour-gradient maxima, by robust Gauss-Newton from `r` (a first pose),
  // re-measuring at every iteration. `r` is updated only on success.
  // `coarse_start`: r is rough (a fallback seed's): three iterations with
  // wider windows come first (fewer boundaries accepted there).
  Status<VisionError> fit_pose_to_image(const ImageView& image, const solver::CameraModel& camera,
                                        const solver::InstrumentModel& model, solver::PoseVector& r,
                                        ImageFitSummary& summary, bool coarse_start = false) noexcept;
  // The motion-blur streak at the pose r (ours; px, image, its sign
  // arbitrary): each stripe boundary is a sharp colour change between
  // surfaces shaded alike, so along an arc point's image normal n its
  // change is as wide as the streak along n (with the width of a sharp
  // change, 5.8 px); the arcs' turning normals give the streak along the
  // tube, and the red step across each blue stripe's silhouette (2.7 px
  // when sharp) gives it across. The image fit reads it so
  // (ImageFitSummary::streak_px). Fails with NoInstrument when too few
  // points read a width (docs/vision.md).
  Status<VisionError> read_motion_streak(const ImageView& image, const solver::CameraModel& camera,
                                         const solver::InstrumentModel& model, const solver::PoseVector& r,
                                         solver::Vec2& streak_px) const noexcept;
  // The channel's pose (x_ch, y_ch, psi, mu of r) from the shaft's
  // silhouette (ours): the shaft is a straight tube of known radius, so its
  // two apparent contours fix its axis. At 8 distances before the base, the
  // model's cross-section of the shaft (extended by 120, then 30, then 10
  // px) is searched for the run of neutral pixels (the shaft) between
  // chromatic tissue whose width matches the model's; its two ends are the
  // contours' readings. Robust Gauss-Newton over the four parameters with
  // a weak prior around `r`, 8 iterations. `r` is updated only on success
  // (both contours read, a robust RMS within 1.5 px). docs/vision.md.
  Status<VisionError> fit_channel_to_shaft(const ImageView& image, const solver::CameraModel& camera,
                                           const solver::InstrumentModel& model, solver::PoseVector& r,
                                           ShaftFitSummary& summary) const noexcept;
  // The insertion from the base's end-face rim (ours; docs/vision.md, "The
  // tube seen end-on"): for a tube that points away behind the shaft, where
  // the image fit cannot hold (one stripe shows, its arcs seen edge-on),
  // the base's rim still shows as a thin bright ring. With r's channel
  // pose already fitted to the shaft (fit_channel_to_shaft), lambda is
  // stepped from r's outwards, nearest first, by refine_rim_scan_step_mm up
  // to +/- refine_rim_scan_range_mm (beyond the encoders' +/- 3 mm,
  // model.md); at the first step whose base face is turned towards the
  // camera and whose rim reads (the check refine_corners makes), lambda is
  // moved by the rim's shift. `r` is updated only on success; NoInstrument
  // when no step reads the rim. At most 2 * kMaxRimScanSteps + 1 rim reads.
  static constexpr int kMaxRimScanSteps = 20;
  Status<VisionError> fit_insertion_to_base_rim(const ImageView& image, const solver::CameraModel& camera,
                                                const solver::InstrumentModel& model,
                                                solver::PoseVector& r) const noexcept;
  // A coarse pose from the class image alone (ours, for frames the borders
  // and corners cannot serve: a tube seen end-on, markers merged into one
  // region, a wrong labelling): r is moved so that points of every stripe's
  // visible face, projected, fall on pixels of the stripe's colour (chamfer
  // matching on the distance images of the blue and yellow classes;
  // Levenberg-Marquardt with Marquardt's damping schedule, forward
  // differences, a weak prior around `r`, at most kClassFitIterations + 4 trial
  // steps). Updates `r` and returns the mean capped
  // distance in pixels of the points to their colour (`cost_px`); fails
  // when too few points project into the image.
  static constexpr int kClassFitIterations = 12;
  Status<VisionError> fit_pose_to_classes(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                                          solver::PoseVector& r, double& cost_px, bool channel_known = false) noexcept;
  // Back to earlier corners after refine_corners (a refinement the caller
  // did not keep): stage 4's, or those of an earlier refinement.
  void restore_stage4_corners() noexcept;
  void restore_corners(const std::array<Corner, kNumCorners>& corners) noexcept;
  // The reported corners, whether they are refined ones and which
  // boundaries the refinement measured: taken before a trial refinement,
  // put back if the caller does not keep it.
  struct CornerSnapshot {
    std::array<Corner, kNumCorners> corners{};
    bool refined = false;
    std::array<bool, kNumBoundaries> boundary_measured{};
    std::array<double, kNumBoundaries> boundary_shift_mm{};
  };
  CornerSnapshot snapshot_corners() const noexcept {
    return CornerSnapshot{result_.corners, result_.refined, result_.boundary_measured, result_.boundary_shift_mm};
  }
  void restore_snapshot(const CornerSnapshot& snapshot) noexcept;
  // All four stages.
  Status<VisionError> extract(const ImageView& image, const MarkerPriors& priors) noexcept;

  const Extraction& result() const noexcept { return result_; }
  const ClassifierLut& lut() const noexcept { return regions_->lut(); }
  const ColorModel& colors() const noexcept { return colors_; }
  const ExtractorConfig& config() const noexcept { return config_; }
  // The part widths the image fit takes off its shaft and grasper readings.
  const PartWidths& part_widths() const noexcept { return part_widths_; }
  PartWidths& part_widths() noexcept { return part_widths_; }
  // Class of each pixel of the last frame (row-major, width() per row).
  const std::uint8_t* class_image() const noexcept { return regions_->class_image(); }
  // The grid step stage 1 used on the last frame (1 = every pixel).
  int classify_step() const noexcept { return regions_->classify_step(); }
  int width() const noexcept { return regions_->width(); }
  int height() const noexcept { return regions_->height(); }
  // The stages themselves.
  const RegionFinder& region_finder() const noexcept { return *regions_; }
  const Interpreter& interpreter() const noexcept { return *interpreter_; }
  const BorderFitter& border_fitter() const noexcept { return *border_fitter_; }
  const CornerFinder& corner_finder() const noexcept { return *corner_finder_; }

 private:
  ExtractorConfig config_{};
  ColorModel colors_{};
  // The four stages.
  std::unique_ptr<RegionFinder> regions_;
  std::unique_ptr<Interpreter> interpreter_;
  std::unique_ptr<BorderFitter> border_fitter_;
  std::unique_ptr<CornerFinder> corner_finder_;
  // Chamfer distance (3-4 weights: 3 per pixel step) of every pixel to the
  // nearest blue [0] and yellow [1] pixel of the class image, capped;
  // computed by fit_pose_to_classes once per frame.
  std::unique_ptr<std::uint16_t[]> class_distance_[2];
  // The blurred edge's model's tables (refine_streak_edge_model), allocated
  // at create() and rebuilt by every reading that uses them.
  std::unique_ptr<detail::BlurredEdgeScratch> edge_scratch_;
  // The model-guided fits' minimisers and rows, allocated at create().
  std::unique_ptr<detail::FitScratch> fit_scratch_;
  PartWidths part_widths_{};
  bool class_distance_ready_ = false;
  std::array<int, 4> distance_box_{};  // x0, y0, x1, y1 (inclusive) where the distances were computed
  void compute_class_distances() noexcept;
  double class_distance_px(int colour, double x, double y) const noexcept;
  Extraction result_{};
};

}  // namespace vision
}  // namespace tcpest
