// The dense fit (ours, after the paper's pipeline): the pose fitted to every
// pixel around the instrument. The frame's a*b* chroma is compared with a
// rendering of the model's parts (shaft, blue and yellow stripes, grasper,
// tissue) with analytic anti-aliasing, the sensor's slight blur and the
// motion streak, under a mixture likelihood in which a pixel is either the
// rendering's or an occluder's (tissue-like) or an outlier. Robust
// Levenberg-Marquardt over r (and the streak), the appearance of each part
// solved linearly at every step. docs/vision.md, "The dense stage".
//
// Every buffer is allocated in create(); set_region() and fit() allocate
// nothing, and every loop has a fixed bound.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include <Eigen/Core>

#include "tcpest/common/image.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"
#include "tcpest/vision/color_model.hpp"
#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {

// The fine stage's work image (px): a whole PAL frame, so that the
// instrument's region is at the camera's own pixels whatever its size (at
// 10-15 mm of insertion the near tube's region can exceed 250000 px). The
// corners at the bend's far end move by pixels for hundredths of a radian,
// and 2x2 or 3x3 blocks cost frames there (docs/decisions/0038-dense-search.md).
// DenseFitConfig's capacity by default (about 117 MB of buffers, allocated
// once, only for the offline stage), and DenseOptions::fine_pixels.
constexpr int kDenseFineWorkPixels = 720 * 576;

struct DenseFitConfig {
  // The largest camera image (the ray table's size).
  int max_width = 1920;
  int max_height = 1080;
  // The work image: the region around the instrument averaged in square
  // blocks until it has at most this many pixels (set_region's target;
  // about 284 bytes of buffers each, allocated by create()).
  int max_work_pixels = kDenseFineWorkPixels;
  // Chords per stripe of the rendered bending section (their sagitta at
  // the tightest bend stays under 0.02 mm).
  int chords_per_stripe = 4;
  // The region holds the shaft's last this many mm (the shaft is drawn whole).
  double shaft_region_mm = 12.0;
  double margin_px = 10.0;
  // Mixture likelihood (L*a*b* units): the rendering's spread; an occluder
  // (anything in front of the instrument: tissue, blood, a highlight) with
  // its weight, which explains any colour but the stripes' (their position
  // on the blue-to-yellow axis, -1 to 1 at the colour model's means, within
  // occluder_stripe_width of 0 is what an occluder may show); the floor.
  double model_sigma = 10.0;
  double occluder_weight = 0.1;
  double occluder_stripe_width = 0.4;
  double outlier_floor = 1e-4;
  // Extra weight of the pixels where the observed colour changes along the
  // blue-to-yellow axis (the stripes' ends and sides): a pixel's share of
  // the cost and of the step is 1 + edge_emphasis x min(1, the gradient of
  // its position on that axis per work pixel). The many pixels of the
  // tube's long sides, where shading and highlights are modelled least
  // well, otherwise outweigh the few that place the stripes along the tube
  // (docs/decisions/0037-dense-edge-emphasis.md). The weight comes from the image alone,
  // so costs stay comparable between poses; the appearance's solve does
  // not use it. 0: every pixel alike.
  double edge_emphasis = 15.0;
  // The stripes' appearance is the colour model's means times one chroma
  // scale plus deviations, regularised with this share of the weights.
  double stripe_deviation_reg = 0.1;
  double stripe_shading_reg = 0.002;
  // The stripes' appearance solved from the pixels that show a stripe's
  // colour: a pixel the rendering gives to a stripe weighs in that solve
  // by its responsibility times 1 - (its occluder likelihood over
  // occluder_weight) x (its stripes' coverage). Without it an occluder over
  // a stripe is explained as that stripe faded (its chroma scale near 0),
  // and the stripe's own visible pixels become outliers, their corners
  // unreported (docs/decisions/0043-dense-stripe-colours.md). false: every pixel by its
  // responsibility alone.
  bool stripes_from_stripe_colours = true;
  // Longer steps tried along an accepted direction (doubling).
  int line_search_steps = 3;
  // Weak Gaussian prior of the channel's pose around its CAD values.
  double channel_prior_mm = 3.0;
  double channel_prior_rad = 0.1;
  // The motion streak (full length, px) is kept within this.
  double max_streak_px = 20.0;
  // Binomial passes of the sensor's blur at block size 1.
  int optical_blur_passes = 1;
  // Binomial passes of a* and b* alone at block size 1, after the blur in
  // linear light: the camera's chroma is coarser than its lightness. JPEG's
  // 4:2:0 subsampling averages it over 2 x 2 pixels and the decoder's
  // interpolation (libjpeg's "fancy" upsampling) spreads it further: per
  // axis, weights 1/8, 1/8, 3/8, 3/8 about the pixel, a variance of 1 px^2,
  // which two passes (0.5 px^2 each) match. Without them the fit reads the
  // chroma's wider edges as the stripes' (docs/decisions/0044-dense-chroma-blur.md).
  // 0: the chroma as sharp as the lightness (an uncompressed camera).
  int chroma_blur_passes = 2;
  // L* is compared beside a* and b*, scaled by this (it carries the
  // shading, and the shaft's and grasper's edges that chroma lacks).
  double lightness_weight = 0.5;
  // The blur modelled in linear light (false: in L*a*b*).
  bool linear_light_blur = true;
  // The bending section's end faces drawn: the ring at the base where the
  // shaft (narrower) ends and the one at the tip around the grasper, each
  // in its stripe's colour and by its share of a pixel, shaded by the
  // face's own cosine (false: the tube's ends are open cuts, as the
  // revisions before).
  bool end_faces = true;
};

// The robot's encoders and their accuracy: a pose's insertion and bend
// are held within the tolerances of the encoders' joints (model.md's
// coarse prior, "as a robot's encoders would give": lambda +/- 3 mm, phi
// and theta +/- 0.2 rad). docs/vision.md, "The dense stage".
struct EncoderBox {
  solver::PoseVector encoders = solver::PoseVector::Zero();  // their joints at kLambda, kPhi, kTheta
  double lambda_tolerance_mm = 0.0;                           // 0: no box
  double angle_tolerance_rad = 0.0;                           // phi and theta each; 0: no box
};

// True when both tolerances are positive and everything is finite.
bool encoder_box_active(const EncoderBox& box) noexcept;

// r's insertion, phi and theta moved to the nearest point of the box. A phi
// outside it is first written as the same bend nearest the encoders'
// (solver::nearest_equivalent_joints: a turn, or (phi + pi, -theta)). The
// channel's pose is not the encoders' and stays. Unchanged without an
// active box or for a non-finite r.
void hold_within_encoder_box(solver::PoseVector& r, const EncoderBox& box) noexcept;

// The joints (kLambda, kPhi, kTheta) of r that lie on an edge of the box
// with `descent` (the fit's right-hand side J^T W (obs - pred), the way
// the cost falls) pointing out of it: a step along them would only be cut
// back to the edge, so the fit holds them out of its step (an active set)
// and the other parameters move freely. None without an active box.
std::array<bool, solver::kNumParams> joints_held_at_encoder_box(const solver::PoseVector& r,
                                                               const solver::PoseVector& descent,
                                                               const EncoderBox& box) noexcept;

struct DenseFitSummary {
  bool ok = false;
  int iterations = 0;
  double cost = 0.0;           // at the final pose, comparable between fits in one region
  double initial_cost = 0.0;
  double inlier_share = 0.0;   // mean responsibility of the rendering over the region
  double chroma_scale = 1.0;   // the stripes' chroma relative to the colour model (haze < 1)
};

class DenseFit {
 public:
  static constexpr int kMaxChordsPerStripe = 8;
  static constexpr int kMaxSegments = 2 + kNumMarkers * kMaxChordsPerStripe;
  static constexpr int kParams = 9;  // r (7) and the streak (2)
  // Parts: 1 shaft, 2..6 markers 1..5, 7 grasper (0: none).
  static constexpr int kParts = 8;
  static constexpr int kShadeTerms = 3;        // a part's appearance: 1, c, c^2 (c: cosine of view and normal)
  static constexpr int kBackgroundTerms = 3;   // the tissue's: 1, x, y
  // Basis planes: tissue (3), shaft (3), grasper (3), each marker (1), the
  // blue and the yellow markers' c and c^2 (4).
  static constexpr int kBasis = 3 * kBackgroundTerms + kNumMarkers + 4;
  static constexpr int kMaxStreakTaps = 48;
  // A streak this long or shorter is no blur: neither modelled nor
  // fitted (px, full length).
  static constexpr double kMinStreakPx = 1.0;
  static constexpr int kChannels = 3;  // a*, b*, lightness_weight * L*
  // The fitted parameters: r (7) and the streak (2).
  using ParamVector = Eigen::Matrix<double, kParams, 1>;
  using ParamMatrix = Eigen::Matrix<double, kParams, kParams>;

  static Result<std::unique_ptr<DenseFit>, VisionError> create(const solver::CameraModel& camera,
                                                                const solver::InstrumentModel& model,
                                                                const ColorModel& colors,
                                                                const DenseFitConfig& config) noexcept;
  ~DenseFit();
  DenseFit(const DenseFit&) = delete;
  DenseFit& operator=(const DenseFit&) = delete;
  DenseFit(DenseFit&&) = delete;
  DenseFit& operator=(DenseFit&&) = delete;

  // The work region for the poses given (the union of their instruments,
  // grown by the margin and half the streak), averaged into blocks so that
  // at most `target_pixels` remain, and smoothed by `smoothing_passes`
  // binomial passes (the prediction gets the same: a wider basin). Fails
  // with NoInstrument when no pose projects into the image, BadImage for
  // an image of another size than the camera's.
  Status<VisionError> set_region(const ImageView& image, const solver::PoseVector* poses, int count,
                                 double streak_length_px, int target_pixels, int smoothing_passes) noexcept;
  // Levenberg-Marquardt from r and streak_px within the region; both are
  // updated. `constrained`: the stripes' colour only scaled, no shading
  // terms (a coarse start). The streak is fitted when it is longer than
  // 1 px and fit_streak is set.
  DenseFitSummary fit(solver::PoseVector& r, solver::Vec2& streak_px, int max_iterations, bool constrained,
                      bool fit_streak) noexcept;
  // How much of the image around each corner of r the rendering explains
  // (mean responsibility within a few pixels; 0 when outside the region or
  // hidden by the instrument), for the corners to report. After fit().
  void corner_support(const solver::PoseVector& r, const solver::Vec2& streak_px,
                      std::array<double, kNumCorners>& support) noexcept;
  // The pose's softest direction at r: the step along which the cost
  // rises least for a given motion of the model's corners in the image
  // (the generalised eigenvector of the fit's Gauss-Newton matrix against
  // the corners' own, smallest eigenvalue), scaled so that the corners in
  // the image move by rms_px (root mean square); docs/vision.md, "The
  // dense stage". After set_region(); false: no corner in the image, a
  // non-finite input or matrix, or a factorisation failed.
  bool softest_step(const solver::PoseVector& r, const solver::Vec2& streak_px, double rms_px,
                    solver::PoseVector& step) noexcept;
  // Every fit() from now on holds the pose within the box (its start and
  // each step: hold_within_encoder_box), and leaves out of each step the
  // joints pressed against its edges (joints_held_at_encoder_box); an
  // inactive box holds nothing.
  void set_encoder_box(const EncoderBox& box) noexcept { encoder_box_ = box; }
  int block_size() const noexcept { return scale_; }
  int work_pixels() const noexcept { return rw_ * rh_; }

 private:
  DenseFit() noexcept = default;
  struct Segment {
    float ax, ay, az, bx, by, bz, ex, ey, ez;   // ends and unit axis (mm, camera frame)
    float nax, nay, naz, nbx, nby, nbz;          // cut planes' normals at the ends
    float len, radius, s_a, ds;                  // length, radius, arc length at a, ds per mm of axis
    float unroll_mm;                             // added to s: the surface coordinate (compute_coverage)
    bool cap_a, cap_b;
    bool face_a, face_b;                         // a flat face at that end (seen from beyond its cut plane)
    std::uint8_t part;                           // 0 shaft, 1..5 marker, 6 grasper
    // The surface coordinate (mm) at a fraction of the way from the cut
    // plane at a to the one at b.
    float surface_mm(float frac) const noexcept { return s_a + len * ds * frac + unroll_mm; }
  };
  // A part's shift from the arc length to the surface coordinate (mm): the
  // rings (base_ring_mm_, tip_ring_mm_) lie before the markers' sides and
  // before the grasper's. The one place that order is written.
  float part_unroll_mm(std::uint8_t part) const noexcept {
    return part == 0U ? 0.0F : (part == 6U ? base_ring_mm_ + tip_ring_mm_ : base_ring_mm_);
  }
  void build_segments(const solver::PoseVector& r) noexcept;
  // The image box (px) of the instruments at the poses; false: none in front of the camera.
  bool instrument_bounds(const solver::PoseVector* poses, int count, double& xmin, double& xmax, double& ymin,
                         double& ymax) noexcept;
  // The work image's rays and block-averaged L*a*b* (region and block size set).
  void sample_work_image(const ImageView& image) noexcept;
  // Per work pixel, from the observation alone: the occluder's likelihood
  // and the pixel's share of the cost (edge_emphasis).
  void compute_pixel_terms() noexcept;
  bool occluded_by_instrument(const solver::Vec3& point, double s_point_mm) const noexcept;
  void render_geometry(const solver::PoseVector& r) noexcept;
  // A segment's reach in the work image: its box, and (bounded: both ends
  // in front of the camera) its projected axis and half width (work
  // pixels), so that each row is visited only where the segment's band
  // crosses it.
  struct SegmentWindow {
    int bx0 = 0, bx1 = 0, by0 = 0, by1 = 0;
    double pax = 0.0, pay = 0.0, pbx = 0.0, pby = 0.0, band = 0.0;
    bool bounded = false;
  };
  // The ray-segment terms that do not depend on the ray.
  struct RayConstants {
    float md = 0.0F, mpx = 0.0F, mpy = 0.0F, mpz = 0.0F, c0 = 0.0F, r2 = 0.0F;
  };
  // False: the segment misses the work image.
  bool segment_window(const Segment& s, SegmentWindow& w) const noexcept;
  // The columns [rx0, rx1] of row y the segment's band crosses; false: none.
  static bool row_span(const SegmentWindow& w, int y, int& rx0, int& rx1) noexcept;
  // One work pixel's ray against one segment: signed distance, first hit, shading.
  void trace_ray(const Segment& s, const RayConstants& k, std::size_t i) noexcept;
  // The same ray against the segment's end face (at_a: the face at a);
  // the pixel shows the face when it is the nearest hit so far.
  void trace_face(const Segment& s, bool at_a, float dx, float dy, std::size_t i) noexcept;
  // Each work pixel's coverage by the instrument and its two main parts.
  void compute_coverage() noexcept;
  void build_streak_kernel(const solver::Vec2& streak_px) noexcept;
  void blur_plane(float* plane) noexcept;
  // Every part's a*b* as 1, c, c^2 terms; the tissue's as 1, x, y (x, y
  // over the region from -1 to 1); the markers' chroma scales.
  struct Appearance {
    double tissue[kBackgroundTerms][kChannels] = {};
    double part[kParts][kShadeTerms][kChannels] = {};
    double scale[kNumMarkers] = {1.0, 1.0, 1.0, 1.0, 1.0};
  };
  // Predictions and Jacobian columns are kChannels planes of work pixels.
  void predict_sharp(const Appearance& appearance, float* pred) const noexcept;
  void render_prediction(const solver::PoseVector& r, const solver::Vec2& streak_px, const Appearance& appearance,
                         float* pred) noexcept;
  void render_basis(const solver::PoseVector& r, const solver::Vec2& streak_px) noexcept;
  void blur_prediction(const Appearance& appearance) noexcept;
  void blur_in_linear_light(float* pred) noexcept;
  // The chroma planes of a prediction blurred (chroma_blur_passes).
  void blur_chroma(float* pred) noexcept;
  void solve_appearance(bool constrained, Appearance& appearance) noexcept;
  void solve_lightness(bool constrained, Appearance& appearance) noexcept;
  double cost(const float* pred, bool update_weights) noexcept;
  // The pose part of theta held within encoder_box_ (when active).
  void hold_pose(ParamVector& theta) const noexcept;
  // The channel's prior, in the cost's units.
  double prior_cost(const ParamVector& theta) const noexcept;
  // The appearance at theta from the default; returns the cost there.
  double start_appearance(const ParamVector& theta, bool constrained, Appearance& app) noexcept;
  // Gauss-Newton's H and gradient at theta (the appearance held; the
  // Jacobian by forward differences); parameters from nparams on are held.
  void normal_equations(const ParamVector& theta, const Appearance& app, int nparams, ParamMatrix& H,
                        ParamVector& grad) noexcept;
  // Levenberg-Marquardt's step from theta with damping mu (both updated),
  // then longer ones along it; false: no step lowered the cost.
  bool damped_step(const ParamMatrix& H, const ParamVector& grad, const Appearance& app, double c_cur, double& mu,
                   ParamVector& theta) noexcept;
  void default_appearance(Appearance& appearance) noexcept;
  // The streak within max_streak_px, and the blur's taps and the spread
  // set for it (fit's and softest_step's start).
  solver::Vec2 prepare_streak(const solver::Vec2& streak_px) noexcept;

  solver::CameraModel camera_{};
  solver::InstrumentModel model_{};
  ColorModel colors_{};
  DenseFitConfig config_{};
  int width_ = 0;
  int height_ = 0;
  // Rays (normalised undistorted x, y) of every second pixel, interpolated.
  int ray_w_ = 0;
  int ray_h_ = 0;
  std::unique_ptr<float[]> ray_x_, ray_y_;
  std::array<Segment, kMaxSegments> segs_{};
  int seg_count_ = 0;
  // The end faces' ring widths (mm; 0 without faces; set by create). The surface
  // coordinate compute_coverage mixes the parts by is the arc length run
  // on across them: the shaft's side, the base's ring (crease to rim),
  // the markers' sides, the tip's ring (rim to crease), the grasper's.
  float base_ring_mm_ = 0.0F;
  float tip_ring_mm_ = 0.0F;
  // The parts' intervals in the surface coordinate (the shaft, markers
  // 1..5, the grasper: part k from [k] to [k + 1]) and the faces' rings
  // in it (empty without faces); set by create.
  std::array<float, 8> part_bounds_mm_{};
  std::array<std::array<float, 2>, 2> rings_mm_{};
  // The region (full resolution) and the work image.
  int fx0_ = 0, fy0_ = 0, fw_ = 0, fh_ = 0;
  int scale_ = 1, rw_ = 0, rh_ = 0, smoothing_ = 0;
  std::size_t capacity_ = 0U;
  std::unique_ptr<float[]> wrx_, wry_, obs_, occluder_;  // occluder_: the occluder's likelihood of each work pixel
  std::unique_ptr<float[]> emphasis_;                    // each work pixel's share of the cost (edge_emphasis)
  // Geometry per work pixel.
  std::unique_ptr<float[]> sd_, snear_, thit_, shit_, shade_, sval_;
  // shade_: the side's cosine (at a face's pixel, the side's where it meets
  // the face); shade_face_: the end face's beside it, if one is seen there.
  std::unique_ptr<float[]> shade_face_;
  std::unique_ptr<float[]> cov0_, cov1_;
  std::unique_ptr<std::uint8_t[]> cls0_, cls1_;
  // Blurred basis planes (kBasis), predictions, Jacobian (kParams x 2), weights, scratch.
  std::unique_ptr<float[]> basis_, pred_, trial_, jac_, weights_, tmp_, scratch_;
  // The streak's kernel: offsets (work pixels) and weights.
  static constexpr std::size_t kMaxKernelTaps = 4U * static_cast<std::size_t>(kMaxStreakTaps);
  std::array<int, kMaxKernelTaps> k_dx_{}, k_dy_{};
  std::array<float, kMaxKernelTaps> k_w_{};
  int k_count_ = 0;
  int k_reach_ = 0;
  bool blur_streak_ = false;
  int taps_ = 1;
  double sigma_ = 10.0;
  EncoderBox encoder_box_{};
  double tissue_[kBackgroundTerms][kChannels] = {};
  double chroma_scale_ = 1.0;
};

}  // namespace vision
}  // namespace tcpest
