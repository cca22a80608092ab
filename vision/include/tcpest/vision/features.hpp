// Feature extraction, paper section 2.3: from an endoscopic RGB frame to up to
// 12 labelled apparent corners (k = 2 j + side, model.md), with the regions
// and the Bezier borders they came from. Four stages:
//   1. classify pixels through a lookup table, connected components + moments
//   2. interpretation tree: which region is which marker (1..5 from the base)
//   3. borders: edge points along the skeleton's normals, a quadratic Bezier per
//      side fitted by IRLS with Tukey's biweight
//   4. corners: zero crossings of the (yellow - blue) chroma profile along
//      each border, plus the transitions to the shaft and the grasper.
// Every buffer is allocated once in FeatureExtractor::create(); running a
// frame allocates nothing. No recursion; every loop has a fixed bound.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/common/static_vector.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/classifier_lut.hpp"
#include "tcpest/vision/color_model.hpp"

namespace tcpest {
namespace vision {

enum class VisionError : std::uint8_t {
  BadImage,        // null data, bad size or stride
  ImageTooLarge,   // larger than the extractor was created for
  TooManyRuns,     // the classified image is too fragmented for the run buffer
  NoInstrument,    // no chain of marker regions found
  BorderFitFailed, // too few edge points on a side
  BadParameter,    // invalid configuration at creation
  OutOfMemory,     // the buffers could not be allocated at creation
};
const char* to_string(VisionError e) noexcept;

struct Point {
  double x = 0.0;  // pixels, (0, 0) = centre of the top-left pixel
  double y = 0.0;
};

// A connected component of one colour, with its moments.
struct Region {
  PixelClass cls = PixelClass::Background;
  std::int32_t area = 0;  // pixels
  Point centroid{};
  double cov_xx = 0.0, cov_xy = 0.0, cov_yy = 0.0;  // second central moments / area
  double half_major = 0.0;  // 2 sqrt(largest eigenvalue): the half axis of the equivalent ellipse
  double half_minor = 0.0;
  double orientation_rad = 0.0;  // of the major axis, image x towards y
  std::int32_t x_min = 0, x_max = 0, y_min = 0, y_max = 0;  // bounding box, inclusive
  // Adds the moments of another region (a virtual node of the tree).
  void merge(const Region& other) noexcept;
  // Recomputes half axes and orientation from the covariance.
  void update_shape() noexcept;
  // Half extent of the equivalent ellipse in unit direction (dx, dy).
  double extent_along(double dx, double dy) const noexcept;
};

constexpr std::size_t kMaxRegions = 64U;        // regions handed to stage 2 (the largest)
constexpr std::size_t kMaxCandidates = 1024U;   // regions above the minimum area before selection
constexpr int kNumMarkers = solver::kNumMarkers;
constexpr int kNumBoundaries = solver::kNumBoundaries;
constexpr int kNumCorners = solver::kNumCorners;

struct RegionSet {
  StaticVector<Region, kMaxRegions> regions;
  bool too_many_regions = false;  // more candidates than kMaxRegions: the smallest were dropped
  std::int32_t run_count = 0;
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

// One labelled marker (a level of the tree): a region or a virtual merge of two.
struct MarkerObservation {
  bool found = false;
  Region region{};
  std::array<std::int16_t, 2> region_index{{-1, -1}};  // into RegionSet::regions
  double log_posterior = 0.0;
};

struct Interpretation {
  std::array<MarkerObservation, kNumMarkers> markers{};
  int first_marker = -1;  // 0-based level of the first found marker, -1 if none
  int last_marker = -1;
  int found_count = 0;
  double score = 0.0;
};

// A quadratic Bezier curve B(t) = (1-t)^2 p0 + 2 (1-t) t p1 + t^2 p2, t in [0, 1].
struct Bezier {
  Point p0{}, p1{}, p2{};
  Point at(double t) const noexcept;
  Point derivative(double t) const noexcept;
};

constexpr std::size_t kMaxSkeletonSamples = 64U;
constexpr std::size_t kProfileInsets = 8U;
constexpr std::size_t kMaxProfileSamples = 512U;

struct EdgePoint {
  Point pixel{};
  double weight = 0.0;  // final IRLS weight
  double t = 0.0;       // chord-length parameter
};

struct Border {
  bool valid = false;
  Bezier curve{};
  StaticVector<EdgePoint, kMaxSkeletonSamples> points;
  double scale_px = 0.0;  // final MAD scale of the residuals
  int iterations = 0;
};

struct Corner {
  bool found = false;
  Point pixel{};
  double confidence = 0.0;  // 0..1
};

struct Extraction {
  RegionSet regions;
  Interpretation interpretation;
  std::array<Point, kMaxSkeletonSamples> skeleton{};
  int skeleton_count = 0;
  std::array<Border, 2> borders{};  // [side]: 0 = left, 1 = right (model.md's side rule)
  std::array<Corner, kNumCorners> corners{};
  int corner_count = 0;
  // Model-guided corners (refine_corners): stage 4's corners are kept here,
  // and each boundary's measured shift along the tube from the pose's.
  bool refined = false;
  std::array<Corner, kNumCorners> stage4_corners{};
  std::array<bool, kNumBoundaries> boundary_measured{};
  std::array<double, kNumBoundaries> boundary_shift_mm{};
};

// The largest smear search of the blurred edge's model (px either way;
// ExtractorConfig::refine_streak_edge_smear_search_px): 16 fits a reading.
constexpr double kMaxStreakEdgeSmearSearchPx = 16.0;

struct ExtractorConfig {
  int max_width = 1920;
  int max_height = 1080;
  // Colour of markers 1..5 from the base (the geometry's marker_colors).
  std::array<PixelClass, kNumMarkers> marker_classes{
      {PixelClass::Blue, PixelClass::Yellow, PixelClass::Blue, PixelClass::Yellow, PixelClass::Blue}};
  std::int32_t min_region_area = 12;        // pixels; smaller components are noise
  double max_link_angle_rad = 1.0471975511965976;  // 60 deg: the skeleton's largest turn per link
  double adjacency_factor = 1.35;           // centroid distance <= factor * (sum of half extents) + slack
  double adjacency_slack_px = 3.0;
  double level_reward = 9.0;                // log-likelihood credit of one more labelled level
  int skeleton_samples = 40;
  // The skeleton runs past the end markers' centroids by this many of their
  // half extents (a stripe's end lies at ~0.87): just past the end boundaries.
  double skeleton_extension = 1.3;
  double edge_search_min = 0.35;            // edge search window along the normal, in local half widths
  double edge_search_max = 1.9;
  // Outward correction of the gradient maximum: the tube's shading falls off
  // towards the silhouette, which pulls the maximum inwards (measured on
  // rendered frames, docs/vision.md).
  double edge_offset_px = 0.3;
  double tukey_c = 1.5;
  int irls_iterations = 10;
  int irls_scale_iterations = 4;            // the MAD scale is re-estimated during the first ones only (1..irls_iterations)
  int profile_samples = 160;                // chroma profile samples along each border
  // The profiles are read along curves parallel to the border, from this far
  // inside to profile_max_inset times the tube's half width (see find_corners).
  double profile_min_inset_px = 3.0;
  double profile_max_inset = 1.1;
  // Stage 4 refits each border locally, on the edge points within this many
  // tube widths of the corner.
  double local_border_window = 1.5;
  // At an end boundary the local fit keeps the edge points on the marker's
  // side, and at most this far beyond.
  double end_margin_px = 2.0;
  // Corners of lower confidence are not reported (docs/vision.md: below ~0.45
  // most are misplaced).
  double min_corner_confidence = 0.45;
  double orientation_weight = 0.0;          // log-likelihood of the dark-shaft / bright-grasper cue
  // Stage 1 classifies every classify_step-th pixel in x and y (1 or 2) and
  // builds the regions on that grid (moments scaled back to pixels); the
  // class image stays full size (each grid class fills its step x step
  // block) and stages 3-4 read the full-resolution RGB image. 0 = auto: 2
  // when the grid still has at least as many points as a PAL 720x576 frame
  // (kAutoStepMinPixels, e.g. 1920x1080), else 1 (docs/vision.md).
  int classify_step = 0;
  // Model-guided corners (refine_corners, docs/vision.md).
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
};

// What fit_channel_to_shaft did.
struct ShaftFitSummary {
  int iterations = 0;
  int readings = 0;        // silhouette readings at the last iteration (both sides)
  double rms_px = 0.0;     // robust RMS of their residuals
};

// The auto rule of ExtractorConfig::classify_step: step 2 from 4 x 720 x 576
// pixels on.
constexpr std::int64_t kAutoStepMinPixels = std::int64_t{4} * 720 * 576;
// The step stage 1 uses for an image of this size (resolves 0 = auto).
int classify_step_for(int configured_step, int width, int height) noexcept;

namespace detail {
class BlurredEdgeScratch;  // src/blurred_edge.hpp
}  // namespace detail

class FeatureExtractor {
 public:
  FeatureExtractor() noexcept = default;
  ~FeatureExtractor();  // out of line: the blurred edge's scratch is an incomplete type here
  // Owned through create()'s pointer, never copied or moved (its buffers are sized at create()).
  FeatureExtractor(const FeatureExtractor&) = delete;
  FeatureExtractor& operator=(const FeatureExtractor&) = delete;
  FeatureExtractor(FeatureExtractor&&) = delete;
  FeatureExtractor& operator=(FeatureExtractor&&) = delete;
  // Allocates every buffer (start-up only). The model and camera are used for
  // the model-predicted priors; the colour model builds the lookup table.
  static Result<std::unique_ptr<FeatureExtractor>, VisionError> create(const ExtractorConfig& config,
                                                                       const ColorModel& colors) noexcept;

  // Stage 1. Also keeps the class image for stage 3 and the overlay.
  Status<VisionError> find_regions(const ImageView& image) noexcept;
  // Stage 2, with the given priors.
  Status<VisionError> interpret(const MarkerPriors& priors) noexcept;
  // Stage 3.
  Status<VisionError> fit_borders(const ImageView& image) noexcept;
  // Stage 4.
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
  // `coarse_start`: r is rough (pose_from_regions): three iterations with
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
  // A rough pose from stage 2 alone (ours): x_ch, y_ch, lambda, phi, theta
  // moved from `r` so that the model's marker middles project onto the
  // labelled regions' centroids (damped Gauss-Newton, at most 15
  // iterations); needs 3 labelled markers and an RMS under 12 px. For frames
  // where stage 4's corners give the solver too little.
  Status<VisionError> pose_from_regions(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                                        solver::PoseVector& r) const noexcept;
  // A coarse pose from the class image alone (ours, for frames the borders
  // and corners cannot serve: a tube seen end-on, markers merged into one
  // region, a wrong labelling): r is moved so that points of every stripe's
  // visible face, projected, fall on pixels of the stripe's colour (chamfer
  // matching on the distance images of the blue and yellow classes;
  // Levenberg-Marquardt, finite differences, a weak prior around `r`, at
  // most kClassFitIterations). Updates `r` and returns the mean capped
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
  const ClassifierLut& lut() const noexcept { return lut_; }
  const ColorModel& colors() const noexcept { return colors_; }
  const ExtractorConfig& config() const noexcept { return config_; }
  // Class of each pixel of the last frame (row-major, width() per row).
  const std::uint8_t* class_image() const noexcept { return classes_.get(); }
  // The grid step stage 1 used on the last frame (1 = every pixel).
  int classify_step() const noexcept { return step_; }
  int width() const noexcept { return width_; }
  int height() const noexcept { return height_; }

 private:
  struct Run {
    std::int32_t parent = 0;
    std::int16_t y = 0;
    std::int16_t x0 = 0;  // first pixel
    std::int16_t x1 = 0;  // one past the last pixel
    std::uint8_t cls = 0;
  };
  std::int32_t find_root(std::int32_t run) noexcept;
  // Stage 1's row work: classes of `count` pixels `step` apart into `out`,
  // then the row's runs (grid coordinates) appended from run_count.
  void classify_row(const std::uint8_t* px, int count, int step, std::uint8_t* out) const noexcept;
  bool cut_runs(const std::uint8_t* classes, int count, int grid_y, std::int32_t& run_count) noexcept;
  // Mean luminance of a 5x5 patch, -1 outside the image.
  double patch_luminance(double x, double y) const noexcept;
  // Orientation cue of a chain: the shaft before marker 1 is dark, the
  // grasper after marker 5 is bright.
  double orientation_log(const Interpretation& hyp) const noexcept;
  void select_regions(std::size_t candidate_count) noexcept;
  // Stage 1's steps (find_regions): the grid's classes and runs, joined into
  // 8-connected components (false: the runs overflowed); the joins of a
  // row's runs [row_begin, row_end) with the previous row's of the same
  // class; the components of at least the minimum area into candidates_,
  // with their raw moment sums (`overflow`: more than kMaxCandidates); one
  // run's sums; and the sums turned into pixel moments and shapes, the
  // candidates still large enough first (returns how many).
  bool classify_and_label(const ImageView& image, int step, std::int32_t& run_count) noexcept;
  void join_with_previous_row(std::int32_t row_begin, std::int32_t row_end, std::int32_t prev_begin,
                              std::int32_t prev_end) noexcept;
  std::size_t accumulate_candidates(std::int32_t run_count, int step, bool& overflow) noexcept;
  static void add_run_moments(const Run& r, Region& reg) noexcept;
  std::size_t finish_candidates(std::size_t candidate_count, int step) noexcept;

  ExtractorConfig config_{};
  ColorModel colors_{};
  ClassifierLut lut_{};
  std::unique_ptr<std::uint8_t[]> classes_;
  std::unique_ptr<Run[]> runs_;
  std::unique_ptr<std::int32_t[]> region_of_root_;
  std::unique_ptr<Region[]> candidates_;
  std::unique_ptr<std::uint8_t[]> grid_row_;  // one row of grid classes (step > 1)
  // Chamfer distance (3-4 weights: 3 per pixel step) of every pixel to the
  // nearest blue [0] and yellow [1] pixel of the class image, capped;
  // computed by fit_pose_to_classes once per frame.
  std::unique_ptr<std::uint16_t[]> class_distance_[2];
  // The blurred edge's model's tables (refine_streak_edge_model), allocated
  // at create() and rebuilt by every reading that uses them.
  std::unique_ptr<detail::BlurredEdgeScratch> edge_scratch_;
  bool class_distance_ready_ = false;
  std::array<int, 4> distance_box_{};  // x0, y0, x1, y1 (inclusive) where the distances were computed
  void compute_class_distances() noexcept;
  double class_distance_px(int colour, double x, double y) const noexcept;
  std::int32_t max_runs_ = 0;
  int width_ = 0;
  int height_ = 0;
  int step_ = 1;
  Extraction result_{};
  std::array<Border, 2> local_borders_{};  // stage 4's borders around one boundary
  ImageView image_{};  // the frame of find_regions(), for the orientation cue
  // Stage 4's chroma profiles [side][inset][sample].
  std::array<std::array<std::array<double, kMaxProfileSamples>, kProfileInsets>, 2> profile_score_{};
  std::array<std::array<std::array<double, kMaxProfileSamples>, kProfileInsets>, 2> profile_margin_{};
  std::array<std::array<std::array<bool, kMaxProfileSamples>, kProfileInsets>, 2> profile_valid_{};
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

// The corners as the solver wants them (pixels, presence per k).
void corners_to_arrays(const Extraction& e, std::array<solver::Vec2, kNumCorners>& pixels,
                       std::array<bool, kNumCorners>& present) noexcept;

}  // namespace vision
}  // namespace tcpest
