#include "tcpest/vision/dense_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {

using solver::PoseVector;
using solver::Vec2;
using solver::Vec3;

namespace {

// The point at t mm along a segment's axis from its end a (the segment's
// type is DenseFit's own, deduced here).
template <typename SegmentT>
Vec3 segment_point(const SegmentT& s, double t_mm) noexcept {
  return Vec3(static_cast<double>(s.ax) + t_mm * static_cast<double>(s.ex),
              static_cast<double>(s.ay) + t_mm * static_cast<double>(s.ey),
              static_cast<double>(s.az) + t_mm * static_cast<double>(s.ez));
}
Vec3 to_vec3(float x, float y, float z) noexcept {
  return Vec3(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
}
template <typename SegmentT>
Vec3 segment_end_a(const SegmentT& s) noexcept {
  return to_vec3(s.ax, s.ay, s.az);
}
template <typename SegmentT>
Vec3 segment_end_b(const SegmentT& s) noexcept {
  return to_vec3(s.bx, s.by, s.bz);
}
template <typename SegmentT>
Vec3 segment_axis(const SegmentT& s) noexcept {
  return to_vec3(s.ex, s.ey, s.ez);
}

constexpr float kFar = 1e30F;

// The cosine of the end face a side meets at its crease or rim, for a ray
// (dx, dy, 1) of length dn (compute_coverage mixes in the face's share of
// the pixel). The shaft's end and the grasper's start meet the faces on
// planes normal to their own axes. Only a face the ray could see (the
// base's looks back along the tube, the tip's forward) shows beside the
// side; else, and for a side that meets no face, the side's own cosine.
template <typename SegmentT>
float face_cosine_beside(const SegmentT& s, float dx, float dy, float dn, float side_cosine) noexcept {
  float fx = s.ex, fy = s.ey, fz = s.ez;
  if (s.face_a) {
    fx = s.nax;
    fy = s.nay;
    fz = s.naz;
  } else if (s.face_b) {
    fx = s.nbx;
    fy = s.nby;
    fz = s.nbz;
  }
  const float cf = (fx * dx + fy * dy + fz) / dn;
  const bool sees_base_face = (s.face_a || s.part == 0U) && cf > 0.0F;
  const bool sees_tip_face = (s.face_b || s.part == 6U) && cf < 0.0F;
  return sees_base_face || sees_tip_face ? (cf < 0.0F ? -cf : cf) : side_cosine;
}

// A side hit this far beyond a cut plane (mm) is still the segment's: two
// chords meet on their shared plane, and rounding must not let a ray
// through the joint miss both.
constexpr float kJointToleranceMm = 1e-3F;

using ParamVector = DenseFit::ParamVector;
using ParamMatrix = DenseFit::ParamMatrix;
// solve_appearance's unknowns (listed there).
constexpr int kAppearanceUnknowns = 35;
using AppearanceMatrix = Eigen::Matrix<double, kAppearanceUnknowns, kAppearanceUnknowns>;
using AppearanceRhs = Eigen::Matrix<double, kAppearanceUnknowns, 1>;

std::size_t idx(int x, int y, int w) noexcept {
  return static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
}

float clamp01(float v) noexcept { return v < 0.0F ? 0.0F : (v > 1.0F ? 1.0F : v); }

// How far along a chord a point lies, read between the chord's cut planes
// (the centreline's normal planes at its ends) from its signed distances
// beyond the plane at a and before the one at b (mm); fallback where the
// planes meet at the point.
float cut_plane_fraction(float beyond_a_mm, float before_b_mm, float fallback) noexcept {
  const float span = beyond_a_mm + before_b_mm;
  return span > 1e-6F ? clamp01(beyond_a_mm / span) : fallback;
}

// A work image's pixel columns and rows as -1..1 across it: the
// coordinates the tissue's linear terms are written in.
struct NormalisedAxes {
  float x_step = 0.0F;
  float y_step = 0.0F;
  NormalisedAxes(int width, int height) noexcept
      : x_step(width > 1 ? 2.0F / static_cast<float>(width - 1) : 0.0F),
        y_step(height > 1 ? 2.0F / static_cast<float>(height - 1) : 0.0F) {}
  float x(int column) const noexcept { return static_cast<float>(column) * x_step - 1.0F; }
  float y(int row) const noexcept { return static_cast<float>(row) * y_step - 1.0F; }
};

// Magnitude of a field's gradient at (x, y) from its four neighbours
// (kFar: not computed there; one-sided where only one neighbour is).
float gradient_norm(const float* f, int w, int h, int x, int y) noexcept {
  const std::size_t i = idx(x, y, w);
  const float c = f[i];
  const float l = x > 0 ? f[i - 1U] : kFar;
  const float r = x + 1 < w ? f[i + 1U] : kFar;
  const float u = y > 0 ? f[i - static_cast<std::size_t>(w)] : kFar;
  const float d = y + 1 < h ? f[i + static_cast<std::size_t>(w)] : kFar;
  float gx = 0.0F;
  float gy = 0.0F;
  if (l < kFar && r < kFar) {
    gx = 0.5F * (r - l);
  } else if (r < kFar) {
    gx = r - c;
  } else if (l < kFar) {
    gx = c - l;
  }
  if (u < kFar && d < kFar) {
    gy = 0.5F * (d - u);
  } else if (d < kFar) {
    gy = d - c;
  } else if (u < kFar) {
    gy = c - u;
  }
  return std::sqrt(gx * gx + gy * gy);
}

// One pass of the separable [1 2 1] / 4 filter, edges clamped.
void binomial_pass(float* p, float* tmp, int w, int h) noexcept {
  for (int y = 0; y < h; ++y) {
    const float* row = p + idx(0, y, w);
    float* out = tmp + idx(0, y, w);
    for (int x = 0; x < w; ++x) {
      const float l = row[x > 0 ? x - 1 : 0];
      const float r = row[x + 1 < w ? x + 1 : w - 1];
      out[x] = 0.25F * l + 0.5F * row[x] + 0.25F * r;
    }
  }
  for (int y = 0; y < h; ++y) {
    const float* up = tmp + idx(0, y > 0 ? y - 1 : 0, w);
    const float* mid = tmp + idx(0, y, w);
    const float* dn = tmp + idx(0, y + 1 < h ? y + 1 : h - 1, w);
    float* out = p + idx(0, y, w);
    for (int x = 0; x < w; ++x) {
      out[x] = 0.25F * up[x] + 0.5F * mid[x] + 0.25F * dn[x];
    }
  }
}

// One observation's row of a sparse linear model (its n non-zero
// coefficients `value` at `index`) added to the normal equations with
// weight w and observed value o.
template <typename MatrixT, typename VectorT>
void add_weighted_row(const int* index, const double* value, int n, double w, double o, MatrixT& M,
                      VectorT& rhs) noexcept {
  for (int x = 0; x < n; ++x) {
    const double wx = w * value[x];
    for (int y = 0; y < n; ++y) {
      M(index[x], index[y]) += wx * value[y];
    }
    rhs(index[x]) += wx * o;
  }
}

// The appearance's normal equations (solve_appearance's unknowns) over the
// work pixels, each weighted by its responsibility (and, where a stripe is
// drawn, by how much its colour is a stripe's); returns the
// responsibilities' sum.
struct AppearanceInputs {
  const float* basis = nullptr;     // DenseFit::kBasis planes
  const float* weights = nullptr;   // responsibilities
  const float* obs = nullptr;       // a*, b* planes
  const float* occluder = nullptr;  // the occluder's likelihood; null: not used
  double occluder_weight = 1.0;     // that likelihood's largest value
  std::size_t pixels = 0U;
  bool constrained = false;
  bool blue_marker[kNumMarkers] = {};
  double mean_a[kNumMarkers] = {};
  double mean_b[kNumMarkers] = {};
};
double accumulate_appearance(const AppearanceInputs& in, AppearanceMatrix& M, AppearanceRhs& rhs) noexcept {
  const std::size_t np = in.pixels;
  const float* basis = in.basis;
  const bool constrained = in.constrained;
  const int terms = constrained ? 1 : DenseFit::kShadeTerms;
  double wsum = 0.0;
  int ia[24];
  int ib[24];
  double va[24];
  double vb[24];
  for (std::size_t i = 0; i < np; ++i) {
    const double w = static_cast<double>(in.weights[i]);
    if (!(w > 0.0)) {
      continue;
    }
    int na = 0;
    int nb = 0;
    auto put = [](int* index, double* value, int& n, int u, double v) {
      if (v != 0.0) {
        index[n] = u;
        value[n] = v;
        ++n;
      }
    };
    auto plane = [&](std::size_t j) { return static_cast<double>(basis[j * np + i]); };
    for (int j = 0; j < DenseFit::kBackgroundTerms; ++j) {
      const double v = plane(static_cast<std::size_t>(j));
      put(ia, va, na, j, v);
      put(ib, vb, nb, 3 + j, v);
    }
    for (int t = 0; t < terms; ++t) {
      const double vs = plane(static_cast<std::size_t>(3) + static_cast<std::size_t>(t));
      const double vg = plane(static_cast<std::size_t>(6) + static_cast<std::size_t>(t));
      put(ia, va, na, 6 + t, vs);
      put(ib, vb, nb, 9 + t, vs);
      put(ia, va, na, 12 + t, vg);
      put(ib, vb, nb, 15 + t, vg);
    }
    double blue_sum = 0.0;
    double yellow_sum = 0.0;
    for (int m = 0; m < kNumMarkers; ++m) {
      const double v = plane(static_cast<std::size_t>(9) + static_cast<std::size_t>(m));
      put(ia, va, na, 18 + m, in.mean_a[m] * v);
      put(ib, vb, nb, 18 + m, in.mean_b[m] * v);
      (in.blue_marker[m] ? blue_sum : yellow_sum) += v;
    }
    if (!constrained) {
      put(ia, va, na, 23, blue_sum);
      put(ib, vb, nb, 26, blue_sum);
      put(ia, va, na, 29, yellow_sum);
      put(ib, vb, nb, 32, yellow_sum);
      for (int t = 1; t < DenseFit::kShadeTerms; ++t) {
        const double vbl = plane(static_cast<std::size_t>(13) + static_cast<std::size_t>(t));
        const double vye = plane(static_cast<std::size_t>(15) + static_cast<std::size_t>(t));
        put(ia, va, na, 23 + t, vbl);
        put(ib, vb, nb, 26 + t, vbl);
        put(ia, va, na, 29 + t, vye);
        put(ib, vb, nb, 32 + t, vye);
      }
    }
    const double oa = static_cast<double>(in.obs[i]);
    const double ob = static_cast<double>(in.obs[np + i]);
    // A pixel drawn as a stripe whose colour is no stripe's (an occluder's,
    // by its likelihood) does not set the stripe's colour.
    double w_solve = w;
    if (in.occluder != nullptr) {
      const double not_stripe = std::min(1.0, static_cast<double>(in.occluder[i]) / in.occluder_weight);
      w_solve = w * (1.0 - not_stripe * std::min(1.0, blue_sum + yellow_sum));
    }
    add_weighted_row(ia, va, na, w_solve, oa, M, rhs);
    add_weighted_row(ib, vb, nb, w_solve, ob, M, rhs);
    wsum += w;
  }
  return wsum;
}


}  // namespace

DenseFit::~DenseFit() = default;

Result<std::unique_ptr<DenseFit>, VisionError> DenseFit::create(const solver::CameraModel& camera,
                                                                const solver::InstrumentModel& model,
                                                                const ColorModel& colors,
                                                                const DenseFitConfig& config) noexcept {
  using R = Result<std::unique_ptr<DenseFit>, VisionError>;
  if (camera.width() <= 0 || camera.height() <= 0 || camera.width() > config.max_width ||
      camera.height() > config.max_height || config.max_width > 8192 || config.max_height > 8192 ||
      config.max_work_pixels < 256 || config.max_work_pixels > (1 << 20) || config.chords_per_stripe < 1 ||
      config.chords_per_stripe > kMaxChordsPerStripe || !(config.shaft_region_mm >= 0.0) ||
      !(config.margin_px >= 0.0 && config.margin_px <= 200.0) || !(config.model_sigma > 0.0) ||
      !(config.occluder_stripe_width > 0.0) || !(config.occluder_weight >= 0.0) || !(config.outlier_floor > 0.0) ||
      !(config.edge_emphasis >= 0.0 && config.edge_emphasis <= 100.0) ||
      !(config.stripe_deviation_reg >= 0.0) || config.line_search_steps < 0 || config.line_search_steps > 8 ||
      !(config.channel_prior_mm > 0.0) || !(config.channel_prior_rad > 0.0) || !(config.max_streak_px >= 0.0) ||
      !(config.lightness_weight > 0.0 && config.lightness_weight <= 4.0) ||
      config.optical_blur_passes < 0 || config.optical_blur_passes > 4 || config.chroma_blur_passes < 0 ||
      config.chroma_blur_passes > 4 || !colors.valid()) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<DenseFit> f(new (std::nothrow) DenseFit());
  if (f == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  f->camera_ = camera;
  f->model_ = model;
  f->colors_ = colors;
  f->config_ = config;
  const solver::InstrumentGeometry& g = model.geometry();
  f->base_ring_mm_ = config.end_faces ? static_cast<float>(std::max(0.0, g.radius_mm - g.shaft_radius_mm)) : 0.0F;
  f->tip_ring_mm_ = config.end_faces ? static_cast<float>(std::max(0.0, g.radius_mm - g.grasper_radius_mm)) : 0.0F;
  // In the surface coordinate (part_unroll_mm): each boundary where the
  // part above it begins, the rings counted with the markers, so the
  // base's crease in the shaft's coordinate and the grasper's in its own.
  f->part_bounds_mm_[0] = -1e9F;
  for (int j = 0; j < solver::kNumBoundaries; ++j) {
    const std::uint8_t part = j == 0 ? 0U : static_cast<std::uint8_t>(j + 1);
    f->part_bounds_mm_[static_cast<std::size_t>(j) + 1U] =
        static_cast<float>(g.boundaries_mm[static_cast<std::size_t>(j)]) + f->part_unroll_mm(part);
  }
  f->part_bounds_mm_[7] = 1e9F;
  f->rings_mm_ = {{{f->part_bounds_mm_[1], f->part_bounds_mm_[1] + f->base_ring_mm_},
                   {f->part_bounds_mm_[6] - f->tip_ring_mm_, f->part_bounds_mm_[6]}}};
  f->width_ = camera.width();
  f->height_ = camera.height();
  // Rays of every second pixel (the undistortion is smooth: bilinear
  // interpolation between them is within 0.01 px of the exact ray).
  f->ray_w_ = f->width_ / 2 + 1;
  f->ray_h_ = f->height_ / 2 + 1;
  const std::size_t rays = static_cast<std::size_t>(f->ray_w_) * static_cast<std::size_t>(f->ray_h_);
  f->ray_x_.reset(new (std::nothrow) float[rays]);
  f->ray_y_.reset(new (std::nothrow) float[rays]);
  const std::size_t n = static_cast<std::size_t>(config.max_work_pixels);
  f->capacity_ = n;
  auto make = [n](std::unique_ptr<float[]>& p, std::size_t planes) {
    p.reset(new (std::nothrow) float[n * planes]);
    return p != nullptr;
  };
  bool ok = f->ray_x_ != nullptr && f->ray_y_ != nullptr;
  ok = ok && make(f->wrx_, 1U) && make(f->wry_, 1U) && make(f->obs_, kChannels) && make(f->occluder_, 1U) &&
       make(f->emphasis_, 1U);
  ok = ok && make(f->sd_, 1U) && make(f->snear_, 1U) && make(f->thit_, 1U) && make(f->shit_, 1U);
  ok = ok && make(f->shade_, 1U) && make(f->shade_face_, 1U) && make(f->sval_, 1U);
  ok = ok && make(f->cov0_, 1U) && make(f->cov1_, 1U);
  ok = ok && make(f->basis_, static_cast<std::size_t>(kBasis)) && make(f->pred_, kChannels);
  ok = ok && make(f->trial_, kChannels) &&
       make(f->jac_, static_cast<std::size_t>(kChannels) * static_cast<std::size_t>(kParams));
  ok = ok && make(f->weights_, 1U) && make(f->tmp_, 1U) && make(f->scratch_, 2U);
  if (ok) {
    f->cls0_.reset(new (std::nothrow) std::uint8_t[n]);
    f->cls1_.reset(new (std::nothrow) std::uint8_t[n]);
    ok = f->cls0_ != nullptr && f->cls1_ != nullptr;
  }
  if (!ok) {
    return R::failure(VisionError::OutOfMemory);
  }
  for (int y = 0; y < f->ray_h_; ++y) {
    for (int x = 0; x < f->ray_w_; ++x) {
      Vec2 nrm;
      const std::size_t i = idx(x, y, f->ray_w_);
      if (camera.undistort(Vec2(2.0 * x, 2.0 * y), nrm)) {
        f->ray_x_[i] = static_cast<float>(nrm.x());
        f->ray_y_[i] = static_cast<float>(nrm.y());
      } else {
        f->ray_x_[i] = std::numeric_limits<float>::quiet_NaN();
        f->ray_y_[i] = std::numeric_limits<float>::quiet_NaN();
      }
    }
  }
  return R::success(std::move(f));
}

void DenseFit::build_segments(const PoseVector& r) noexcept {
  const solver::InstrumentGeometry& g = model_.geometry();
  const solver::PoseFrames f = model_.frames(r);
  const Vec3 axis = f.channel_rotation.col(2);
  int n = 0;
  auto add = [this, &n](const Vec3& a, const Vec3& b, const Vec3& na, const Vec3& nb, double radius, double s_a,
                        double s_b, bool cap_a, std::uint8_t part) {
    const Vec3 d = b - a;
    const double len = d.norm();
    if (!(len > 1e-9) || n >= kMaxSegments) {
      return;
    }
    const Vec3 e = d / len;
    Segment& s = segs_[static_cast<std::size_t>(n)];
    s.ax = static_cast<float>(a.x());
    s.ay = static_cast<float>(a.y());
    s.az = static_cast<float>(a.z());
    s.bx = static_cast<float>(b.x());
    s.by = static_cast<float>(b.y());
    s.bz = static_cast<float>(b.z());
    s.ex = static_cast<float>(e.x());
    s.ey = static_cast<float>(e.y());
    s.ez = static_cast<float>(e.z());
    s.nax = static_cast<float>(na.x());
    s.nay = static_cast<float>(na.y());
    s.naz = static_cast<float>(na.z());
    s.nbx = static_cast<float>(nb.x());
    s.nby = static_cast<float>(nb.y());
    s.nbz = static_cast<float>(nb.z());
    s.len = static_cast<float>(len);
    s.radius = static_cast<float>(radius);
    s.s_a = static_cast<float>(s_a);
    s.ds = static_cast<float>((s_b - s_a) / len);
    s.unroll_mm = part_unroll_mm(part);
    s.cap_a = cap_a;
    s.cap_b = true;
    s.face_a = false;
    s.face_b = false;
    s.part = part;
    ++n;
  };
  // The shaft from where it is 2 mm in front of the camera to the base.
  const double lambda = r[solver::kLambda];
  double shaft = lambda > 0.0 ? lambda : 0.0;
  if (axis.z() > 1e-6) {
    const double to_front = (f.base_origin.z() - 2.0) / axis.z();
    shaft = std::min(shaft, to_front > 0.0 ? to_front : 0.0);
  }
  if (shaft > 0.05) {
    add(f.base_origin - shaft * axis, f.base_origin, axis, axis, g.shaft_radius_mm, -shaft, 0.0, false, 0U);
  }
  const int per = config_.chords_per_stripe;
  for (int m = 0; m < solver::kNumMarkers; ++m) {
    const double sa = g.boundaries_mm[static_cast<std::size_t>(m)];
    const double sb = g.boundaries_mm[static_cast<std::size_t>(m) + 1U];
    for (int i = 0; i < per; ++i) {
      const double s0 = sa + (sb - sa) * i / per;
      const double s1 = (i + 1 == per) ? sb : sa + (sb - sa) * (i + 1) / per;
      const solver::CentrelineFrame c0 = model_.centreline(f, s0);
      const solver::CentrelineFrame c1 = model_.centreline(f, s1);
      const int before = n;
      add(c0.position, c1.position, c0.tangent, c1.tangent, g.radius_mm, s0, s1, true,
          static_cast<std::uint8_t>(1 + m));
      if (n > before && config_.end_faces) {
        // The first stripe's face where the narrower shaft ends and the
        // last one's around the grasper: the ring between the radii shows
        // (the shaft and the grasper hide the rest of the disc).
        Segment& added = segs_[static_cast<std::size_t>(before)];
        added.face_a = m == 0 && i == 0;
        added.face_b = m == solver::kNumMarkers - 1 && i + 1 == per;
      }
    }
  }
  const solver::CentrelineFrame end = model_.centreline(f, g.bend_length_mm);
  add(end.position, end.position + g.tcp_offset_mm * end.tangent, end.tangent, end.tangent, g.grasper_radius_mm,
      g.bend_length_mm, g.bend_length_mm + g.tcp_offset_mm, true, 6U);
  seg_count_ = n;
}

bool DenseFit::instrument_bounds(const PoseVector* poses, int count, double& xmin, double& xmax, double& ymin,
                                 double& ymax) noexcept {
  xmin = 1e9;
  xmax = -1e9;
  ymin = 1e9;
  ymax = -1e9;
  bool any = false;
  const double fx = camera_.intrinsics().fx;
  for (int pi = 0; pi < count; ++pi) {
    if (!poses[pi].allFinite()) {
      continue;
    }
    build_segments(poses[pi]);
    for (int i = 0; i < seg_count_; ++i) {
      const Segment& s = segs_[static_cast<std::size_t>(i)];
      const double from = s.part == 0U ? std::max(0.0, static_cast<double>(s.len) - config_.shaft_region_mm) : 0.0;
      for (int k = 0; k <= 8; ++k) {
        const double t = from + (static_cast<double>(s.len) - from) * k / 8.0;
        const Vec3 p = segment_point(s, t);
        Vec2 px;
        if (p.z() < 1.0 || !camera_.project(p, px)) {
          continue;
        }
        const double rad = static_cast<double>(s.radius) * fx / p.z();
        xmin = std::min(xmin, px.x() - rad);
        xmax = std::max(xmax, px.x() + rad);
        ymin = std::min(ymin, px.y() - rad);
        ymax = std::max(ymax, px.y() + rad);
        any = true;
      }
    }
  }
  return any;
}

Status<VisionError> DenseFit::set_region(const ImageView& image, const PoseVector* poses, int count,
                                         double streak_length_px, int target_pixels, int smoothing_passes) noexcept {
  if (!image.valid() || image.width != width_ || image.height != height_) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  double xmin = 0.0, xmax = 0.0, ymin = 0.0, ymax = 0.0;
  const bool any = instrument_bounds(poses, count, xmin, xmax, ymin, ymax);
  const double streak = std::min(std::max(streak_length_px, 0.0), config_.max_streak_px);
  const double m = config_.margin_px + 0.5 * streak + 2.0;
  if (!any || xmax + m < 0.0 || ymax + m < 0.0 || xmin - m > width_ - 1 || ymin - m > height_ - 1) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  const int x0 = std::max(0, static_cast<int>(std::floor(std::max(xmin - m, -1.0))));
  const int x1 = std::min(width_ - 1, static_cast<int>(std::ceil(std::min(xmax + m, width_ + 1.0))));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::max(ymin - m, -1.0))));
  const int y1 = std::min(height_ - 1, static_cast<int>(std::ceil(std::min(ymax + m, height_ + 1.0))));
  const int target = std::max(64, std::min(target_pixels, config_.max_work_pixels));
  int s = 1;
  while (s < 64 && static_cast<long>((x1 - x0 + 1) / s) * static_cast<long>((y1 - y0 + 1) / s) > target) {
    ++s;
  }
  fx0_ = x0;
  fy0_ = y0;
  fw_ = x1 - x0 + 1;
  fh_ = y1 - y0 + 1;
  scale_ = s;
  rw_ = fw_ / s;
  rh_ = fh_ / s;
  if (rw_ < 4 || rh_ < 4 || static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_) > capacity_) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  smoothing_ = std::max(0, std::min(smoothing_passes, 32));
  sample_work_image(image);
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  for (int k = 0; k < smoothing_; ++k) {
    for (int c = 0; c < kChannels; ++c) {
      binomial_pass(obs_.get() + static_cast<std::size_t>(c) * np, tmp_.get(), rw_, rh_);
    }
  }
  compute_pixel_terms();
  return ok_status<VisionError>();
}

void DenseFit::sample_work_image(const ImageView& image) noexcept {
  const int s = scale_;
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  // Rays of the blocks' centres, and the blocks' mean L*a*b*.
  const double half = 0.5 * (s - 1);
  const double inv = 1.0 / (static_cast<double>(s) * s);
  for (int y = 0; y < rh_; ++y) {
    for (int x = 0; x < rw_; ++x) {
      const double px = 0.5 * (fx0_ + s * x + half);
      const double py = 0.5 * (fy0_ + s * y + half);
      const int ix = std::min(static_cast<int>(px), ray_w_ - 2);
      const int iy = std::min(static_cast<int>(py), ray_h_ - 2);
      const float ax = static_cast<float>(px - ix);
      const float ay = static_cast<float>(py - iy);
      const std::size_t g = idx(ix, iy, ray_w_);
      const std::size_t w = static_cast<std::size_t>(ray_w_);
      const std::size_t i = idx(x, y, rw_);
      wrx_[i] = (1.0F - ax) * (1.0F - ay) * ray_x_[g] + ax * (1.0F - ay) * ray_x_[g + 1U] +
                (1.0F - ax) * ay * ray_x_[g + w] + ax * ay * ray_x_[g + w + 1U];
      wry_[i] = (1.0F - ax) * (1.0F - ay) * ray_y_[g] + ax * (1.0F - ay) * ray_y_[g + 1U] +
                (1.0F - ax) * ay * ray_y_[g + w] + ax * ay * ray_y_[g + w + 1U];
      // The block's mean light (a block is what the rendering's coverage
      // integrates), then its L*a*b*.
      double sr = 0.0;
      double sg = 0.0;
      double sb = 0.0;
      for (int dy = 0; dy < s; ++dy) {
        const std::uint8_t* row = image.row(fy0_ + s * y + dy);
        for (int dx = 0; dx < s; ++dx) {
          const std::uint8_t* p = row + static_cast<std::ptrdiff_t>(3) * (fx0_ + s * x + dx);
          sr += srgb_code_to_linear(p[0]);
          sg += srgb_code_to_linear(p[1]);
          sb += srgb_code_to_linear(p[2]);
        }
      }
      const Lab lab = linear_to_lab(sr * inv, sg * inv, sb * inv);
      obs_[i] = static_cast<float>(lab.a);
      obs_[np + i] = static_cast<float>(lab.b);
      obs_[2U * np + i] = static_cast<float>(config_.lightness_weight * lab.l);
    }
  }
}

void DenseFit::compute_pixel_terms() noexcept {
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  // The occluder's likelihood: anything but the stripes' colours. The
  // position on the blue-to-yellow axis is kept in tmp_ (free until the
  // first rendering) for the emphasis below.
  const double ma = 0.5 * (colors_.blue.mean_a + colors_.yellow.mean_a);
  const double mb = 0.5 * (colors_.blue.mean_b + colors_.yellow.mean_b);
  const double da = colors_.yellow.mean_a - colors_.blue.mean_a;
  const double db = colors_.yellow.mean_b - colors_.blue.mean_b;
  const double axis = 2.0 / (da * da + db * db);
  const double width2 = config_.occluder_stripe_width * config_.occluder_stripe_width;
  for (std::size_t i = 0; i < np; ++i) {
    const double t = ((static_cast<double>(obs_[i]) - ma) * da + (static_cast<double>(obs_[np + i]) - mb) * db) * axis;
    const double q = t * t / width2;
    occluder_[i] = static_cast<float>(config_.occluder_weight * (q < 60.0 ? dmath::exp(-0.5 * q) : 0.0));
    tmp_[i] = static_cast<float>(t);
  }
  // Each pixel's share of the cost: more where the axis position changes
  // (DenseFitConfig::edge_emphasis).
  const float emphasis = static_cast<float>(config_.edge_emphasis);
  for (int y = 0; y < rh_; ++y) {
    for (int x = 0; x < rw_; ++x) {
      const std::size_t i = idx(x, y, rw_);
      emphasis_[i] = emphasis > 0.0F ? 1.0F + emphasis * std::min(gradient_norm(tmp_.get(), rw_, rh_, x, y), 1.0F)
                                     : 1.0F;
    }
  }
}

bool DenseFit::segment_window(const Segment& s, SegmentWindow& w) const noexcept {
  const double fx = camera_.intrinsics().fx;
  const double half = 0.5 * (scale_ - 1);
  // The segment's box in the work image: its ends and middle, grown by
  // its radius and the anti-aliasing reach.
  double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9;
  bool bounded = true;
  for (int k = 0; k <= 2 && bounded; ++k) {
    const double t = 0.5 * static_cast<double>(s.len) * k;
    const Vec3 p = segment_point(s, t);
    Vec2 px;
    if (p.z() < 0.5 || !camera_.project(p, px)) {
      bounded = false;
      break;
    }
    const double rad = static_cast<double>(s.radius) * fx / p.z() + 3.0 * scale_ + 2.0;
    xmin = std::min(xmin, px.x() - rad);
    xmax = std::max(xmax, px.x() + rad);
    ymin = std::min(ymin, px.y() - rad);
    ymax = std::max(ymax, px.y() + rad);
  }
  w = SegmentWindow{};
  w.bx1 = rw_ - 1;
  w.by1 = rh_ - 1;
  if (bounded) {
    const double lx = (xmin - fx0_ - half) / scale_, hx = (xmax - fx0_ - half) / scale_;
    const double ly = (ymin - fy0_ - half) / scale_, hy = (ymax - fy0_ - half) / scale_;
    if (hx < 0.0 || hy < 0.0 || lx > rw_ - 1 || ly > rh_ - 1) {
      return false;
    }
    w.bx0 = std::max(0, static_cast<int>(std::floor(lx)));
    w.bx1 = std::min(rw_ - 1, static_cast<int>(std::ceil(hx)));
    w.by0 = std::max(0, static_cast<int>(std::floor(ly)));
    w.by1 = std::min(rh_ - 1, static_cast<int>(std::ceil(hy)));
    Vec2 qa, qb;
    const Vec3 a = segment_end_a(s), b = segment_end_b(s);
    if (camera_.project(a, qa) && camera_.project(b, qb)) {
      w.pax = (qa.x() - fx0_ - half) / scale_;
      w.pay = (qa.y() - fy0_ - half) / scale_;
      w.pbx = (qb.x() - fx0_ - half) / scale_;
      w.pby = (qb.y() - fy0_ - half) / scale_;
      w.band = (static_cast<double>(s.radius) * fx / std::min(a.z(), b.z()) + 3.0 * scale_ + 2.0) / scale_ + 1.5;
    } else {
      bounded = false;
    }
  }
  w.bounded = bounded;
  return true;
}

void DenseFit::trace_ray(const Segment& s, const RayConstants& k, std::size_t i) noexcept {
  const float dx = wrx_[i];
  const float dy = wry_[i];
  if (!(dx == dx) || !(dy == dy)) {
    return;
  }
  const float dd = dx * s.ex + dy * s.ey + s.ez;
  const float px = dx - dd * s.ex, py = dy - dd * s.ey, pz = 1.0F - dd * s.ez;
  const float A = px * px + py * py + pz * pz;
  if (A < 1e-12F) {
    return;
  }
  const float B = k.mpx * px + k.mpy * py + k.mpz * pz;
  const float tstar = -B / A;
  float u = tstar * dd + k.md;
  float dist2 = 0.0F;
  float near_frac = 0.0F;
  if (u >= 0.0F && u <= s.len) {
    dist2 = k.c0 - B * B / A;
    // The ray's point nearest the axis, placed between the cut planes as
    // a hit is below (at a grazing hit the two are one point, so the arc
    // length does not jump where a ray's hit begins).
    const float qx = tstar * dx, qy = tstar * dy;
    const float near_a = (qx - s.ax) * s.nax + (qy - s.ay) * s.nay + (tstar - s.az) * s.naz;
    const float near_b = -((qx - s.bx) * s.nbx + (qy - s.by) * s.nby + (tstar - s.bz) * s.nbz);
    near_frac = cut_plane_fraction(near_a, near_b, u / s.len);
  } else {
    u = u < 0.0F ? 0.0F : s.len;
    near_frac = u > 0.0F ? 1.0F : 0.0F;
    const float qx = s.ax + u * s.ex, qy = s.ay + u * s.ey, qz = s.az + u * s.ez;
    const float tp = (qx * dx + qy * dy + qz) / (dx * dx + dy * dy + 1.0F);
    const float ex = tp * dx - qx, ey = tp * dy - qy, ez = tp - qz;
    dist2 = ex * ex + ey * ey + ez * ez;
  }
  const float sdv = std::sqrt(dist2 > 0.0F ? dist2 : 0.0F) - s.radius;
  if (sdv < sd_[i]) {
    sd_[i] = sdv;
    snear_[i] = s.surface_mm(near_frac);
  }
  const float disc = B * B - A * (k.c0 - k.r2);
  if (disc < 0.0F) {
    return;
  }
  const float t = (-B - std::sqrt(disc)) / A;
  if (!(t > 0.0F) || !(t < thit_[i])) {
    return;
  }
  // Where the side's first hit lies beyond a cut plane, the ray enters the
  // tube through that end: its face, if the segment has one, is what shows.
  // (Within kJointToleranceMm of it the hit is still the segment's own.)
  const float hx = t * dx - s.ax, hy = t * dy - s.ay, hz = t - s.az;
  const float beyond_a = hx * s.nax + hy * s.nay + hz * s.naz;
  if (s.cap_a && beyond_a < -kJointToleranceMm) {
    if (s.face_a) {
      trace_face(s, true, dx, dy, i);
    }
    return;
  }
  const float gx = t * dx - s.bx, gy = t * dy - s.by, gz = t - s.bz;
  const float before_b = -(gx * s.nbx + gy * s.nby + gz * s.nbz);
  if (s.cap_b && before_b < -kJointToleranceMm) {
    if (s.face_b) {
      trace_face(s, false, dx, dy, i);
    }
    return;
  }
  const float along = hx * s.ex + hy * s.ey + hz * s.ez;
  const float nx = (hx - along * s.ex) / s.radius, ny = (hy - along * s.ey) / s.radius,
              nz = (hz - along * s.ez) / s.radius;
  const float dn = std::sqrt(dx * dx + dy * dy + 1.0F);
  thit_[i] = t;
  // The arc length between the cut planes (the centreline's normal planes
  // at the chord's ends), not along the chord: on a plane both of its
  // chords give its own arc length, so the stripes' ends stay continuous
  // where the hit passes from one chord to the next (along the chord it
  // jumps there by the mitre's slope times the radius).
  shit_[i] = s.surface_mm(cut_plane_fraction(beyond_a, before_b, along / s.len));
  const float c = (nx * dx + ny * dy + nz) / dn;
  shade_[i] = c < 0.0F ? -c : c;
  shade_face_[i] = face_cosine_beside(s, dx, dy, dn, shade_[i]);
}

void DenseFit::trace_face(const Segment& s, bool at_a, float dx, float dy, std::size_t i) noexcept {
  const float nx = at_a ? s.nax : s.nbx, ny = at_a ? s.nay : s.nby, nz = at_a ? s.naz : s.nbz;
  const float ox = at_a ? s.ax : s.bx, oy = at_a ? s.ay : s.by, oz = at_a ? s.az : s.bz;
  // The face at a looks back along -n_a, the one at b along +n_b: a ray
  // sees it only travelling the other way.
  const float dn = dx * nx + dy * ny + nz;
  if (at_a ? !(dn > 1e-6F) : !(dn < -1e-6F)) {
    return;
  }
  const float t = (ox * nx + oy * ny + oz * nz) / dn;
  if (!(t > 0.0F) || !(t < thit_[i])) {
    return;
  }
  const float hx = t * dx - ox, hy = t * dy - oy, hz = t - oz;
  const float along = hx * s.ex + hy * s.ey + hz * s.ez;
  const float radial2 = hx * hx + hy * hy + hz * hz - along * along;
  if (!(radial2 <= s.radius * s.radius)) {
    return;
  }
  thit_[i] = t;
  // The surface coordinate runs on across the ring between the crease
  // with the shaft (or the grasper), where the colour changes, and the
  // rim, where it meets the side's (compute_coverage): the base's from
  // its crease at s_a, the tip's from its rim.
  const float radial = std::sqrt(radial2 > 0.0F ? radial2 : 0.0F);
  shit_[i] = at_a ? s.s_a + std::max(0.0F, std::min(base_ring_mm_, radial - (s.radius - base_ring_mm_)))
                  : s.surface_mm(1.0F) + std::max(0.0F, std::min(tip_ring_mm_, s.radius - radial));
  const float dl = std::sqrt(dx * dx + dy * dy + 1.0F);
  const float c = dn / dl;
  shade_face_[i] = c < 0.0F ? -c : c;
  // The side's cosine where it meets the face (the radial direction), for
  // the sides' share of the pixel (compute_coverage).
  const float ax = hx - along * s.ex, ay = hy - along * s.ey, az = hz - along * s.ez;
  const float cs = radial > 1e-6F ? (ax * dx + ay * dy + az) / (radial * dl) : shade_face_[i];
  shade_[i] = cs < 0.0F ? -cs : cs;
}

bool DenseFit::row_span(const SegmentWindow& w, int y, int& rx0, int& rx1) noexcept {
  rx0 = w.bx0;
  rx1 = w.bx1;
  if (!w.bounded) {
    return true;
  }
  // Where |y(t) - y| <= band along the projected segment, x(t) +/- band.
  double t0 = 0.0, t1 = 1.0;
  const double dyp = w.pby - w.pay;
  if (std::fabs(dyp) > 1e-9) {
    const double ta = (y - w.band - w.pay) / dyp, tb = (y + w.band - w.pay) / dyp;
    t0 = std::max(0.0, std::min(ta, tb));
    t1 = std::min(1.0, std::max(ta, tb));
    if (t0 > t1) {
      return false;
    }
  } else if (std::fabs(y - w.pay) > w.band) {
    return false;
  }
  const double xa = w.pax + t0 * (w.pbx - w.pax), xb = w.pax + t1 * (w.pbx - w.pax);
  rx0 = std::max(w.bx0, static_cast<int>(std::floor(std::min(xa, xb) - w.band)));
  rx1 = std::min(w.bx1, static_cast<int>(std::ceil(std::max(xa, xb) + w.band)));
  return true;
}

void DenseFit::render_geometry(const PoseVector& r) noexcept {
  build_segments(r);
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  std::fill(sd_.get(), sd_.get() + np, kFar);
  std::fill(snear_.get(), snear_.get() + np, 0.0F);
  std::fill(thit_.get(), thit_.get() + np, kFar);
  std::fill(shit_.get(), shit_.get() + np, 0.0F);
  std::fill(shade_.get(), shade_.get() + np, 0.0F);
  std::fill(shade_face_.get(), shade_face_.get() + np, 0.0F);
  for (int si = 0; si < seg_count_; ++si) {
    const Segment& s = segs_[static_cast<std::size_t>(si)];
    SegmentWindow w;
    if (!segment_window(s, w)) {
      continue;
    }
    // Per ray d = (x, y, 1) from the camera: the closest approach to the
    // segment (its distance to the axis minus the radius: the signed
    // distance the anti-aliasing reads) and the first hit on the cylinder
    // between the cut planes.
    RayConstants k;
    k.md = -(s.ax * s.ex + s.ay * s.ey + s.az * s.ez);
    k.mpx = -s.ax - k.md * s.ex;
    k.mpy = -s.ay - k.md * s.ey;
    k.mpz = -s.az - k.md * s.ez;
    k.c0 = k.mpx * k.mpx + k.mpy * k.mpy + k.mpz * k.mpz;
    k.r2 = s.radius * s.radius;
    for (int y = w.by0; y <= w.by1; ++y) {
      int rx0 = 0;
      int rx1 = -1;
      if (!row_span(w, y, rx0, rx1)) {
        continue;
      }
      for (int x = rx0; x <= rx1; ++x) {
        trace_ray(s, k, idx(x, y, rw_));
      }
    }
  }
  compute_coverage();
}

void DenseFit::compute_coverage() noexcept {
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  // The arc length each pixel shows: the first hit's, else the nearest point's.
  for (std::size_t i = 0; i < np; ++i) {
    sval_[i] = sd_[i] < kFar ? (thit_[i] < kFar ? shit_[i] : snear_[i]) : kFar;
  }
  // Coverage from the signed distance over its gradient (a pixel's width),
  // and the parts along s mixed over the arc length's gradient likewise.
  const float* const bounds = part_bounds_mm_.data();
  // The part of each interval of s: the shaft, markers 1..5, the grasper.
  const std::uint8_t cls_of[7] = {1U, 2U, 3U, 4U, 5U, 6U, 7U};
  for (int y = 0; y < rh_; ++y) {
    for (int x = 0; x < rw_; ++x) {
      const std::size_t i = idx(x, y, rw_);
      cov0_[i] = 0.0F;
      cov1_[i] = 0.0F;
      cls0_[i] = 0U;
      cls1_[i] = 0U;
      if (!(sd_[i] < kFar)) {
        continue;
      }
      const float gsd = std::max(gradient_norm(sd_.get(), rw_, rh_, x, y), 1e-4F);
      const float cov = clamp01(0.5F - sd_[i] / gsd);
      if (cov <= 0.0F) {
        continue;
      }
      const float gs = std::max(gradient_norm(sval_.get(), rw_, rh_, x, y), 1e-4F);
      const float sv = sval_[i];
      // The pixel's footprint along the surface, [sv - gs/2, sv + gs/2]:
      // the share of it on a face's ring takes the face's cosine, the rest
      // the side's (one cosine per pixel, so that the shading does not
      // jump where the hit passes from the side to the face).
      float on_face = 0.0F;
      for (const auto& ring : rings_mm_) {
        const float lo = std::max(sv - 0.5F * gs, ring[0]);
        const float hi = std::min(sv + 0.5F * gs, ring[1]);
        on_face += hi > lo ? (hi - lo) / gs : 0.0F;
      }
      shade_[i] += clamp01(on_face) * (shade_face_[i] - shade_[i]);
      // The two parts of largest share (a transition between stripes is
      // narrower than a stripe).
      float best0 = 0.0F, best1 = 0.0F;
      std::uint8_t c0 = 0U, c1 = 0U;
      float prev = 1.0F;
      for (int k = 0; k < 7; ++k) {
        const float next = k == 6 ? 0.0F : clamp01(0.5F + (sv - bounds[k + 1]) / gs);
        const float frac = prev - next;
        prev = next;
        if (frac > best0) {
          best1 = best0;
          c1 = c0;
          best0 = frac;
          c0 = cls_of[k];
        } else if (frac > best1) {
          best1 = frac;
          c1 = cls_of[k];
        }
      }
      const float total = best0 + best1;
      if (total <= 0.0F) {
        continue;
      }
      cov0_[i] = cov * best0 / total;
      cov1_[i] = cov * best1 / total;
      cls0_[i] = c0;
      cls1_[i] = c1;
    }
  }
}

void DenseFit::build_streak_kernel(const Vec2& streak_px) noexcept {
  k_count_ = 0;
  k_reach_ = 0;
  blur_streak_ = taps_ > 1;
  if (!blur_streak_) {
    return;
  }
  const double sx = streak_px.x() / scale_;
  const double sy = streak_px.y() / scale_;
  const float inv = 1.0F / static_cast<float>(taps_);
  for (int k = 0; k < taps_; ++k) {
    const double f = static_cast<double>(k) / (taps_ - 1) - 0.5;
    const double px = f * sx;
    const double py = f * sy;
    const int ix = static_cast<int>(std::floor(px));
    const int iy = static_cast<int>(std::floor(py));
    const float ax = static_cast<float>(px - ix);
    const float ay = static_cast<float>(py - iy);
    const int ox[4] = {ix, ix + 1, ix, ix + 1};
    const int oy[4] = {iy, iy, iy + 1, iy + 1};
    const float w[4] = {(1.0F - ax) * (1.0F - ay) * inv, ax * (1.0F - ay) * inv, (1.0F - ax) * ay * inv,
                        ax * ay * inv};
    for (int c = 0; c < 4; ++c) {
      if (w[c] == 0.0F) {
        continue;
      }
      int j = 0;
      while (j < k_count_ &&
             (k_dx_[static_cast<std::size_t>(j)] != ox[c] || k_dy_[static_cast<std::size_t>(j)] != oy[c])) {
        ++j;
      }
      if (j == k_count_) {
        k_dx_[static_cast<std::size_t>(j)] = ox[c];
        k_dy_[static_cast<std::size_t>(j)] = oy[c];
        k_w_[static_cast<std::size_t>(j)] = 0.0F;
        ++k_count_;
        k_reach_ = std::max(k_reach_, std::max(std::abs(ox[c]), std::abs(oy[c])));
      }
      k_w_[static_cast<std::size_t>(j)] += w[c];
    }
  }
}

void DenseFit::blur_plane(float* plane) noexcept {
  const int passes = (scale_ == 1 ? config_.optical_blur_passes : 0) + smoothing_;
  for (int k = 0; k < passes; ++k) {
    binomial_pass(plane, tmp_.get(), rw_, rh_);
  }
  if (!blur_streak_) {
    return;
  }
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  float* src = tmp_.get();
  std::copy(plane, plane + np, src);
  std::fill(plane, plane + np, 0.0F);
  const int reach = k_reach_;
  // Inside, a kernel entry at a time along whole row spans (the compiler
  // vectorises these); the border pixels with clamped offsets.
  const int x_lo = std::min(reach, rw_);
  const int x_hi = std::max(x_lo, rw_ - reach);
  for (int y = 0; y < rh_; ++y) {
    const bool inner_row = y >= reach && y < rh_ - reach;
    float* out = plane + idx(0, y, rw_);
    if (inner_row) {
      for (int k = 0; k < k_count_; ++k) {
        const float w = k_w_[static_cast<std::size_t>(k)];
        const std::size_t tap = static_cast<std::size_t>(k);
        const float* in = src + idx(0, y + k_dy_[tap], rw_) + k_dx_[tap];
        for (int x = x_lo; x < x_hi; ++x) {
          out[x] += w * in[x];
        }
      }
    }
    for (int x = 0; x < rw_; ++x) {
      if (inner_row && x >= x_lo && x < x_hi) {
        continue;
      }
      float acc = 0.0F;
      for (int k = 0; k < k_count_; ++k) {
        const int sx = std::min(rw_ - 1, std::max(0, x + k_dx_[static_cast<std::size_t>(k)]));
        const int sy = std::min(rh_ - 1, std::max(0, y + k_dy_[static_cast<std::size_t>(k)]));
        acc += k_w_[static_cast<std::size_t>(k)] * src[idx(sx, sy, rw_)];
      }
      out[x] = acc;
    }
  }
}

void DenseFit::predict_sharp(const Appearance& app, float* pred) const noexcept {
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  float cp[kChannels][kParts][kShadeTerms] = {};
  float bg[kChannels][kBackgroundTerms] = {};
  for (int c = 0; c < kChannels; ++c) {
    for (int p = 1; p < kParts; ++p) {
      for (int t = 0; t < kShadeTerms; ++t) {
        cp[c][p][t] = static_cast<float>(app.part[p][t][c]);
      }
    }
    for (int t = 0; t < kBackgroundTerms; ++t) {
      bg[c][t] = static_cast<float>(app.tissue[t][c]);
    }
  }
  const NormalisedAxes axes(rw_, rh_);
  for (int y = 0; y < rh_; ++y) {
    const float yn = axes.y(y);
    for (int x = 0; x < rw_; ++x) {
      const float xn = axes.x(x);
      const std::size_t i = idx(x, y, rw_);
      const float w0 = cov0_[i];
      const float w1 = cov1_[i];
      const float wb = 1.0F - w0 - w1;
      const float sh = shade_[i];
      const std::uint8_t c0 = cls0_[i];
      const std::uint8_t c1 = cls1_[i];
      for (int c = 0; c < kChannels; ++c) {
        float v = wb * (bg[c][0] + bg[c][1] * xn + bg[c][2] * yn);
        if (w0 > 0.0F) {
          v += w0 * (cp[c][c0][0] + sh * (cp[c][c0][1] + sh * cp[c][c0][2]));
          if (w1 > 0.0F) {
            v += w1 * (cp[c][c1][0] + sh * (cp[c][c1][1] + sh * cp[c][c1][2]));
          }
        }
        pred[static_cast<std::size_t>(c) * np + i] = v;
      }
    }
  }
}

void DenseFit::blur_in_linear_light(float* pred) noexcept {
  // Light mixes linearly: the prediction's L*a*b* to linear sRGB, each
  // plane blurred, and back (an edge between a bright stripe and the dark
  // shaft under a 10 px streak sits some 2 px off where L*a*b* mixes).
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  const bool any = blur_streak_ || smoothing_ > 0 || (scale_ == 1 && config_.optical_blur_passes > 0);
  if (!any) {
    return;
  }
  if (!config_.linear_light_blur) {
    for (int c = 0; c < kChannels; ++c) {
      blur_plane(pred + static_cast<std::size_t>(c) * np);
    }
    return;
  }
  const double inv_w = 1.0 / config_.lightness_weight;
  float* pa = pred;
  float* pb = pred + np;
  float* pl = pred + 2U * np;
  for (std::size_t i = 0; i < np; ++i) {
    double r = 0.0;
    double g = 0.0;
    double b = 0.0;
    const Lab lab{static_cast<double>(pl[i]) * inv_w, static_cast<double>(pa[i]), static_cast<double>(pb[i])};
    lab_to_linear(lab, r, g, b);
    pa[i] = static_cast<float>(r);
    pb[i] = static_cast<float>(g);
    pl[i] = static_cast<float>(b);
  }
  for (int c = 0; c < kChannels; ++c) {
    blur_plane(pred + static_cast<std::size_t>(c) * np);
  }
  for (std::size_t i = 0; i < np; ++i) {
    const Lab lab = linear_to_lab(static_cast<double>(pa[i]), static_cast<double>(pb[i]), static_cast<double>(pl[i]));
    pa[i] = static_cast<float>(lab.a);
    pb[i] = static_cast<float>(lab.b);
    pl[i] = static_cast<float>(config_.lightness_weight * lab.l);
  }
}

void DenseFit::blur_chroma(float* pred) noexcept {
  // The camera's chroma is coarser than its lightness (4:2:0 subsampling:
  // DenseFitConfig::chroma_blur_passes). Coarser blocks average it away.
  if (scale_ != 1) {
    return;
  }
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  for (int k = 0; k < config_.chroma_blur_passes; ++k) {
    binomial_pass(pred, tmp_.get(), rw_, rh_);       // a*
    binomial_pass(pred + np, tmp_.get(), rw_, rh_);  // b*
  }
}

void DenseFit::render_prediction(const PoseVector& r, const Vec2& streak_px, const Appearance& app,
                                 float* pred) noexcept {
  render_geometry(r);
  build_streak_kernel(streak_px);
  predict_sharp(app, pred);
  blur_in_linear_light(pred);
  blur_chroma(pred);
}

void DenseFit::blur_prediction(const Appearance& app) noexcept {
  // The prediction from the geometry already rendered (render_basis).
  predict_sharp(app, pred_.get());
  blur_in_linear_light(pred_.get());
  blur_chroma(pred_.get());
}

void DenseFit::render_basis(const PoseVector& r, const Vec2& streak_px) noexcept {
  render_geometry(r);
  build_streak_kernel(streak_px);
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  float* basis = basis_.get();
  std::fill(basis, basis + np * static_cast<std::size_t>(kBasis), 0.0F);
  const solver::InstrumentGeometry& g = model_.geometry();
  // Plane of each part's terms: shaft 3..5, grasper 6..8; marker m: its
  // constant 9 + m, its colour's c and c^2 at 14, 15 (blue) or 16, 17.
  std::size_t plane_c[kParts] = {};
  std::size_t plane_c2[kParts] = {};
  std::size_t plane_1[kParts] = {};
  plane_1[1] = 3U;
  plane_c[1] = 4U;
  plane_c2[1] = 5U;
  plane_1[7] = 6U;
  plane_c[7] = 7U;
  plane_c2[7] = 8U;
  for (int m = 0; m < kNumMarkers; ++m) {
    const bool blue = g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue;
    plane_1[2 + m] = static_cast<std::size_t>(9) + static_cast<std::size_t>(m);
    plane_c[2 + m] = blue ? 14U : 16U;
    plane_c2[2 + m] = blue ? 15U : 17U;
  }
  const NormalisedAxes axes(rw_, rh_);
  for (int y = 0; y < rh_; ++y) {
    const float yn = axes.y(y);
    for (int x = 0; x < rw_; ++x) {
      const float xn = axes.x(x);
      const std::size_t i = idx(x, y, rw_);
      const float bg = 1.0F - cov0_[i] - cov1_[i];
      basis[i] = bg;
      basis[np + i] = bg * xn;
      basis[2U * np + i] = bg * yn;
      const float sh = shade_[i];
      const float w[2] = {cov0_[i], cov1_[i]};
      const std::uint8_t c[2] = {cls0_[i], cls1_[i]};
      for (int k = 0; k < 2; ++k) {
        if (w[k] <= 0.0F || c[k] == 0U) {
          continue;
        }
        basis[plane_1[c[k]] * np + i] += w[k];
        basis[plane_c[c[k]] * np + i] += w[k] * sh;
        basis[plane_c2[c[k]] * np + i] += w[k] * sh * sh;
      }
    }
  }
  for (int j = 0; j < kBasis; ++j) {
    blur_plane(basis + static_cast<std::size_t>(j) * np);
  }
}

void DenseFit::default_appearance(Appearance& app) noexcept {
  // The tissue: the median of each channel over the region's first and
  // last rows. The markers: the colour model's means, as light as the tissue.
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  app = Appearance{};
  float* v = scratch_.get();
  for (int c = 0; c < kChannels; ++c) {
    const float* o = obs_.get() + static_cast<std::size_t>(c) * np;
    int k = 0;
    for (int x = 0; x < rw_; ++x) {
      v[k++] = o[idx(x, 0, rw_)];
      v[k++] = o[idx(x, rh_ - 1, rw_)];
    }
    std::nth_element(v, v + k / 2, v + k);
    app.tissue[0][c] = k > 0 ? static_cast<double>(v[k / 2]) : 0.0;
  }
  const solver::InstrumentGeometry& g = model_.geometry();
  for (int m = 0; m < kNumMarkers; ++m) {
    const ColorGaussian& c =
        g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue ? colors_.blue : colors_.yellow;
    app.part[2 + m][0][0] = c.mean_a;
    app.part[2 + m][0][1] = c.mean_b;
    app.part[2 + m][0][2] = app.tissue[0][2];
  }
  app.part[1][0][2] = app.tissue[0][2];
  app.part[7][0][2] = app.tissue[0][2];
  for (int t = 0; t < kBackgroundTerms; ++t) {
    for (int c = 0; c < kChannels; ++c) {
      tissue_[t][c] = app.tissue[t][c];
    }
  }
  chroma_scale_ = 1.0;
}

void DenseFit::solve_appearance(bool constrained, Appearance& app) noexcept {
  // Unknowns: the tissue (1, x, y) for a* [0..2] and b* [3..5]; the shaft
  // (1, c, c^2) [6..11] and the grasper [12..17] likewise; each marker's
  // chroma scale k_m of its colour's mean [18..22]; the blue [23..28] and
  // the yellow [29..34] markers' deviation from k_m times the mean (1, c,
  // c^2; regularised: the markers keep the colour model's hue).
  // Constrained: no shading terms and no deviations.
  constexpr int kU = kAppearanceUnknowns;
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  const solver::InstrumentGeometry& g = model_.geometry();
  bool blue_marker[kNumMarkers];
  double mean_a[kNumMarkers];
  double mean_b[kNumMarkers];
  for (int m = 0; m < kNumMarkers; ++m) {
    blue_marker[m] = g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue;
    mean_a[m] = blue_marker[m] ? colors_.blue.mean_a : colors_.yellow.mean_a;
    mean_b[m] = blue_marker[m] ? colors_.blue.mean_b : colors_.yellow.mean_b;
  }
  AppearanceInputs in;
  in.basis = basis_.get();
  in.weights = weights_.get();
  in.obs = obs_.get();
  if (config_.stripes_from_stripe_colours && config_.occluder_weight > 0.0) {
    in.occluder = occluder_.get();
    in.occluder_weight = config_.occluder_weight;
  }
  in.pixels = np;
  in.constrained = constrained;
  for (int m = 0; m < kNumMarkers; ++m) {
    in.blue_marker[m] = blue_marker[m];
    in.mean_a[m] = mean_a[m];
    in.mean_b[m] = mean_b[m];
  }
  AppearanceMatrix M = AppearanceMatrix::Zero();
  AppearanceRhs rhs = AppearanceRhs::Zero();
  const double wsum = accumulate_appearance(in, M, rhs);
  // A small ridge holds what the region does not show at its last value;
  // the markers' scales are pulled to their last values too.
  const double ridge = 1e-4 * wsum + 1e-6;
  for (int u = 0; u < kU; ++u) {
    M(u, u) += ridge;
  }
  for (int t = 0; t < kBackgroundTerms; ++t) {
    rhs(t) += ridge * app.tissue[t][0];
    rhs(3 + t) += ridge * app.tissue[t][1];
  }
  for (int m = 0; m < kNumMarkers; ++m) {
    rhs(18 + m) += ridge * app.scale[m];
  }
  // The markers' hue is held to the colour model's (their constant
  // deviation regularised); their shading terms much less (a highlight
  // along the crest takes the chroma out of the middle of the tube).
  const double reg = config_.stripe_deviation_reg * wsum + 1e-6;
  const double reg_shade = config_.stripe_shading_reg * wsum + 1e-6;
  for (int u = 23; u < kU; ++u) {
    const bool constant = u == 23 || u == 26 || u == 29 || u == 32;
    M(u, u) += constant ? reg : reg_shade;
  }
  const AppearanceRhs sol = M.ldlt().solve(rhs);
  if (!sol.allFinite()) {
    return;  // the previous appearance stays
  }
  Appearance next = app;  // the lightness terms are solve_lightness's
  for (int t = 0; t < kBackgroundTerms; ++t) {
    next.tissue[t][0] = sol(t);
    next.tissue[t][1] = sol(3 + t);
  }
  for (int t = 0; t < kShadeTerms; ++t) {
    next.part[1][t][0] = sol(6 + t);
    next.part[1][t][1] = sol(9 + t);
    next.part[7][t][0] = sol(12 + t);
    next.part[7][t][1] = sol(15 + t);
  }
  double scale_sum = 0.0;
  for (int m = 0; m < kNumMarkers; ++m) {
    const double k = std::max(0.05, sol(18 + m));
    next.scale[m] = k;
    scale_sum += k;
    const int dev = blue_marker[m] ? 23 : 29;
    next.part[2 + m][0][0] = k * mean_a[m] + sol(dev);
    next.part[2 + m][0][1] = k * mean_b[m] + sol(dev + 3);
    for (int t = 1; t < kShadeTerms; ++t) {
      next.part[2 + m][t][0] = sol(dev + t);
      next.part[2 + m][t][1] = sol(dev + 3 + t);
    }
  }
  chroma_scale_ = scale_sum / kNumMarkers;
  app = next;
  solve_lightness(constrained, app);
  for (int t = 0; t < kBackgroundTerms; ++t) {
    for (int c = 0; c < kChannels; ++c) {
      tissue_[t][c] = app.tissue[t][c];
    }
  }
}

void DenseFit::solve_lightness(bool constrained, Appearance& app) noexcept {
  // L* (scaled): the tissue (1, x, y), the shaft, the grasper, the blue
  // and the yellow markers (1, c, c^2 each; constrained: constants only).
  constexpr int kU = 15;
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  const float* basis = basis_.get();
  const float* obs = obs_.get() + 2U * np;
  const solver::InstrumentGeometry& g = model_.geometry();
  Eigen::Matrix<double, kU, kU> M = Eigen::Matrix<double, kU, kU>::Zero();
  Eigen::Matrix<double, kU, 1> rhs = Eigen::Matrix<double, kU, 1>::Zero();
  const int terms = constrained ? 1 : kShadeTerms;
  double wsum = 0.0;
  int iu[16];
  double vu[16];
  for (std::size_t i = 0; i < np; ++i) {
    const double w = static_cast<double>(weights_[i]);
    if (!(w > 0.0)) {
      continue;
    }
    int n = 0;
    auto put = [&](int u, double v) {
      if (v != 0.0) {
        iu[n] = u;
        vu[n] = v;
        ++n;
      }
    };
    auto plane = [&](int j) { return static_cast<double>(basis[static_cast<std::size_t>(j) * np + i]); };
    for (int j = 0; j < kBackgroundTerms; ++j) {
      put(j, plane(j));
    }
    double blue_sum = 0.0;
    double yellow_sum = 0.0;
    for (int m = 0; m < kNumMarkers; ++m) {
      const bool blue = g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue;
      (blue ? blue_sum : yellow_sum) += plane(9 + m);
    }
    for (int t = 0; t < terms; ++t) {
      put(3 + t, plane(3 + t));
      put(6 + t, plane(6 + t));
    }
    put(9, blue_sum);
    put(12, yellow_sum);
    for (int t = 1; t < terms; ++t) {
      put(9 + t, plane(13 + t));
      put(12 + t, plane(15 + t));
    }
    const double o = static_cast<double>(obs[i]);
    add_weighted_row(iu, vu, n, w, o, M, rhs);
    wsum += w;
  }
  // A small ridge towards the last values: parts the region hides keep theirs.
  const double ridge = 1e-4 * wsum + 1e-6;
  double last[kU] = {};
  for (int t = 0; t < kShadeTerms; ++t) {
    last[3 + t] = app.part[1][t][2];
    last[6 + t] = app.part[7][t][2];
    last[9 + t] = app.part[2][t][2];
    last[12 + t] = app.part[3][t][2];
  }
  for (int t = 0; t < kBackgroundTerms; ++t) {
    last[t] = app.tissue[t][2];
  }
  for (int u = 0; u < kU; ++u) {
    M(u, u) += ridge;
    rhs(u) += ridge * last[u];
  }
  const Eigen::Matrix<double, kU, 1> sol = M.ldlt().solve(rhs);
  if (!sol.allFinite()) {
    return;
  }
  for (int t = 0; t < kBackgroundTerms; ++t) {
    app.tissue[t][2] = sol(t);
  }
  for (int t = 0; t < kShadeTerms; ++t) {
    const bool used = t < terms;
    app.part[1][t][2] = used ? sol(3 + t) : 0.0;
    app.part[7][t][2] = used ? sol(6 + t) : 0.0;
    for (int m = 0; m < kNumMarkers; ++m) {
      const bool blue = g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue;
      app.part[2 + m][t][2] = used ? sol((blue ? 9 : 12) + t) : 0.0;
    }
  }
}

double DenseFit::cost(const float* pred, bool update_weights) noexcept {
  // -sigma^2 log of the mixture: the rendering (sigma), an occluder
  // (occluder_: anything but a stripe's colour), a uniform floor. A stripe
  // drawn where something else shows costs a bounded amount (it may be
  // hidden); a stripe shown where the model draws none costs the floor.
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  const double s2 = sigma_ * sigma_;
  double total = 0.0;
  for (std::size_t i = 0; i < np; ++i) {
    double qm = 0.0;
    for (int c = 0; c < kChannels; ++c) {
      const std::size_t ci = static_cast<std::size_t>(c) * np + i;
      const double r = static_cast<double>(obs_[ci]) - static_cast<double>(pred[ci]);
      qm += r * r;
    }
    qm /= s2;
    const double pm = qm < 60.0 ? dmath::exp(-0.5 * qm) : 0.0;
    const double den = pm + static_cast<double>(occluder_[i]) + config_.outlier_floor;
    total -= s2 * static_cast<double>(emphasis_[i]) * dmath::log(den);
    if (update_weights) {
      weights_[i] = static_cast<float>(pm / den);
    }
  }
  return total;
}

namespace {
PoseVector pose_of(const DenseFit::ParamVector& theta) noexcept {
  return PoseVector(theta.head<solver::kNumParams>());
}
Vec2 streak_of(const DenseFit::ParamVector& theta) noexcept {
  return Vec2(theta[7], theta[8]);
}
}  // namespace

bool encoder_box_active(const EncoderBox& box) noexcept {
  return box.encoders.allFinite() && box.lambda_tolerance_mm > 0.0 && box.angle_tolerance_rad > 0.0 &&
         std::isfinite(box.lambda_tolerance_mm) && std::isfinite(box.angle_tolerance_rad);
}

void hold_within_encoder_box(PoseVector& r, const EncoderBox& box) noexcept {
  if (!encoder_box_active(box) || !r.allFinite()) {
    return;
  }
  const PoseVector& e = box.encoders;
  const double a = box.angle_tolerance_rad;
  const double l = box.lambda_tolerance_mm;
  // A phi outside the box may be the same bend written another way (a turn
  // more, or (phi + pi, -theta)): written the encoders' way first. Only
  // there, so that a pose inside the box stays bit for bit.
  if (std::fabs(r[solver::kPhi] - e[solver::kPhi]) > a) {
    r = solver::nearest_equivalent_joints(r, e);
  }
  r[solver::kPhi] = std::min(std::max(r[solver::kPhi], e[solver::kPhi] - a), e[solver::kPhi] + a);
  r[solver::kTheta] = std::min(std::max(r[solver::kTheta], e[solver::kTheta] - a), e[solver::kTheta] + a);
  r[solver::kLambda] = std::min(std::max(r[solver::kLambda], e[solver::kLambda] - l), e[solver::kLambda] + l);
}

std::array<bool, solver::kNumParams> joints_held_at_encoder_box(const PoseVector& r, const PoseVector& descent,
                                                               const EncoderBox& box) noexcept {
  std::array<bool, solver::kNumParams> held{};
  if (!encoder_box_active(box)) {
    return held;
  }
  const PoseVector& e = box.encoders;
  const int joints[3] = {solver::kLambda, solver::kPhi, solver::kTheta};
  for (const int p : joints) {
    const double tol = p == solver::kLambda ? box.lambda_tolerance_mm : box.angle_tolerance_rad;
    // hold_within_encoder_box writes an edge as exactly e +/- tol.
    held[static_cast<std::size_t>(p)] =
        (r[p] >= e[p] + tol && descent[p] > 0.0) || (r[p] <= e[p] - tol && descent[p] < 0.0);
  }
  return held;
}

void DenseFit::hold_pose(ParamVector& theta) const noexcept {
  if (!encoder_box_active(encoder_box_)) {
    return;
  }
  PoseVector r = pose_of(theta);
  hold_within_encoder_box(r, encoder_box_);
  theta.head<solver::kNumParams>() = r;
}

double DenseFit::prior_cost(const ParamVector& theta) const noexcept {
  // The channel's pose (x, y, psi, mu) around its CAD values, in the
  // likelihood's units (times the rendering's variance).
  const PoseVector nominal = model_.geometry().nominal_pose(0.0, 0.0, 0.0);
  double c = 0.0;
  for (int i = 0; i < 4; ++i) {
    const double sd = i < 2 ? config_.channel_prior_mm : config_.channel_prior_rad;
    const double u = (theta[i] - nominal[i]) / sd;
    c += 0.5 * u * u;
  }
  return c * config_.model_sigma * config_.model_sigma;
}

double DenseFit::start_appearance(const ParamVector& theta, bool constrained, Appearance& app) noexcept {
  // The constrained solve twice (uniform, then the responsibilities'
  // weights), then the full one if asked.
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  default_appearance(app);
  render_basis(pose_of(theta), streak_of(theta));
  std::fill(weights_.get(), weights_.get() + np, 1.0F);
  solve_appearance(true, app);
  blur_prediction(app);
  (void)cost(pred_.get(), true);  // weights only
  solve_appearance(true, app);
  if (!constrained) {
    render_prediction(pose_of(theta), streak_of(theta), app, pred_.get());
    (void)cost(pred_.get(), true);  // weights only
    solve_appearance(false, app);
  }
  render_prediction(pose_of(theta), streak_of(theta), app, pred_.get());
  return cost(pred_.get(), true) + prior_cost(theta);
}

void DenseFit::normal_equations(const ParamVector& theta, const Appearance& app, int nparams, ParamMatrix& H,
                                ParamVector& grad) noexcept {
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  // Jacobian by forward differences, the appearance held. Steps: 0.01 mm,
  // 0.5 mrad, 1 mrad, 0.05 px.
  const double steps[kParams] = {0.01, 0.01, 0.0005, 0.0005, 0.01, 0.001, 0.001, 0.05, 0.05};
  for (int p = 0; p < nparams; ++p) {
    ParamVector th = theta;
    th[p] += steps[p];
    float* j = jac_.get() + static_cast<std::size_t>(kChannels) * static_cast<std::size_t>(p) * np;
    render_prediction(pose_of(th), streak_of(th), app, j);
    const float inv = static_cast<float>(1.0 / steps[p]);
    const std::size_t n3 = static_cast<std::size_t>(kChannels) * np;
    for (std::size_t i = 0; i < n3; ++i) {
      j[i] = (j[i] - pred_[i]) * inv;
    }
  }
  H = ParamMatrix::Zero();
  grad = ParamVector::Zero();
  for (std::size_t i = 0; i < np; ++i) {
    const double w = static_cast<double>(weights_[i]) * static_cast<double>(emphasis_[i]);
    if (w < 1e-6) {
      continue;
    }
    for (int c = 0; c < kChannels; ++c) {
      const std::size_t ci = static_cast<std::size_t>(c) * np + i;
      const double res = static_cast<double>(obs_[ci]) - static_cast<double>(pred_[ci]);
      double jc[kParams];
      for (int p = 0; p < nparams; ++p) {
        jc[p] = static_cast<double>(jac_[static_cast<std::size_t>(kChannels) * static_cast<std::size_t>(p) * np + ci]);
      }
      for (int p = 0; p < nparams; ++p) {
        grad[p] += w * jc[p] * res;
        for (int q = 0; q <= p; ++q) {
          H(p, q) += w * jc[p] * jc[q];
        }
      }
    }
  }
  for (int p = 0; p < nparams; ++p) {
    for (int q = p + 1; q < nparams; ++q) {
      H(p, q) = H(q, p);
    }
  }
  const PoseVector nominal = model_.geometry().nominal_pose(0.0, 0.0, 0.0);
  const double s2 = config_.model_sigma * config_.model_sigma;
  for (int i = 0; i < 4; ++i) {
    const double sd = i < 2 ? config_.channel_prior_mm : config_.channel_prior_rad;
    const double wgt = s2 / (sd * sd);
    H(i, i) += wgt;
    grad[i] -= wgt * (theta[i] - nominal[i]);
  }
  for (int p = nparams; p < kParams; ++p) {  // parameters held: the streak
    H(p, p) = 1.0;
    grad[p] = 0.0;
  }
}

bool DenseFit::damped_step(const ParamMatrix& H, const ParamVector& grad, const Appearance& app, double c_cur,
                           double& mu, ParamVector& theta) noexcept {
  for (int tries = 0; tries < 8; ++tries) {
    ParamMatrix A = H;
    for (int p = 0; p < kParams; ++p) {
      A(p, p) += mu * std::max(H(p, p), 1e-9);
    }
    ParamVector delta = A.ldlt().solve(grad);
    if (!delta.allFinite()) {
      return false;
    }
    ParamVector th = theta + delta;
    hold_pose(th);
    render_prediction(pose_of(th), streak_of(th), app, trial_.get());
    double c_new = cost(trial_.get(), false) + prior_cost(th);
    if (!(c_new < c_cur)) {
      mu *= 4.0;
      continue;
    }
    mu = std::max(mu / 3.0, 1e-7);
    theta = th;
    // Longer steps along the accepted direction while they still lower the cost.
    for (int k = 0; k < config_.line_search_steps && tries == 0; ++k) {
      th = theta + delta;
      hold_pose(th);
      render_prediction(pose_of(th), streak_of(th), app, trial_.get());
      const double c2 = cost(trial_.get(), false) + prior_cost(th);
      if (!(c2 < c_new)) {
        break;
      }
      c_new = c2;
      theta = th;
      delta *= 2.0;
    }
    return true;
  }
  return false;
}

Vec2 DenseFit::prepare_streak(const Vec2& streak_px) noexcept {
  sigma_ = config_.model_sigma;
  Vec2 streak = streak_px;
  if (streak.norm() > config_.max_streak_px) {
    streak *= config_.max_streak_px / streak.norm();
  }
  const bool blur = streak.norm() > kMinStreakPx;
  taps_ = blur ? std::min(kMaxStreakTaps, static_cast<int>(std::ceil((streak.norm() + 4.0) / scale_)) + 2) : 1;
  return streak;
}

DenseFitSummary DenseFit::fit(PoseVector& r, Vec2& streak_px, int max_iterations, bool constrained,
                              bool fit_streak) noexcept {
  DenseFitSummary summary;
  if (rw_ <= 0 || rh_ <= 0 || !r.allFinite() || !streak_px.allFinite()) {
    return summary;
  }
  const std::size_t np = static_cast<std::size_t>(rw_) * static_cast<std::size_t>(rh_);
  const Vec2 streak = prepare_streak(streak_px);
  const bool streak_free = taps_ > 1 && fit_streak;
  const int nparams = streak_free ? kParams : solver::kNumParams;
  ParamVector theta;
  theta.head<solver::kNumParams>() = r;
  theta[7] = streak.x();
  theta[8] = streak.y();
  hold_pose(theta);
  Appearance app;
  double c_cur = start_appearance(theta, constrained, app);
  summary.initial_cost = c_cur;
  double mu = 1e-3;
  int it = 0;
  for (; it < max_iterations; ++it) {
    ParamMatrix H;
    ParamVector grad;
    normal_equations(theta, app, nparams, H, grad);
    // Joints pressed against the encoders' box leave the step, as the streak does when held.
    const std::array<bool, solver::kNumParams> held =
        joints_held_at_encoder_box(pose_of(theta), grad.head<solver::kNumParams>(), encoder_box_);
    for (int p = 0; p < solver::kNumParams; ++p) {
      if (held[static_cast<std::size_t>(p)]) {
        H.row(p).setZero();
        H.col(p).setZero();
        H(p, p) = 1.0;
        grad[p] = 0.0;
      }
    }
    if (!damped_step(H, grad, app, c_cur, mu, theta)) {
      break;
    }
    // The streak within its bounds.
    const double sl = streak_of(theta).norm();
    if (sl > config_.max_streak_px) {
      theta[7] *= config_.max_streak_px / sl;
      theta[8] *= config_.max_streak_px / sl;
    }
    // The responsibilities and the appearance at the new pose.
    render_basis(pose_of(theta), streak_of(theta));
    blur_prediction(app);
    (void)cost(pred_.get(), true);  // weights only
    solve_appearance(constrained, app);
    render_prediction(pose_of(theta), streak_of(theta), app, pred_.get());
    const double c_prev = c_cur;
    c_cur = cost(pred_.get(), true) + prior_cost(theta);
    if (std::fabs(c_prev - c_cur) < 1e-6 * std::fabs(c_prev)) {
      ++it;
      break;
    }
  }
  r = pose_of(theta);
  streak_px = streak_of(theta);
  summary.ok = true;
  summary.iterations = it;
  summary.cost = c_cur;
  summary.chroma_scale = chroma_scale_;
  double wsum = 0.0;
  for (std::size_t i = 0; i < np; ++i) {
    wsum += static_cast<double>(weights_[i]);
  }
  summary.inlier_share = wsum / static_cast<double>(np);
  return summary;
}

bool DenseFit::softest_step(const PoseVector& r, const Vec2& streak_px, double rms_px, PoseVector& step) noexcept {
  using Mat7 = Eigen::Matrix<double, solver::kNumParams, solver::kNumParams>;
  if (rw_ <= 0 || rh_ <= 0 || !r.allFinite() || !streak_px.allFinite() || !(rms_px > 0.0)) {
    return false;
  }
  // The corners' metric: sum over the corners in the image of J_k^T J_k.
  solver::CornerSet corners;
  solver::CornerJacobians jacobians;
  model_.corners(camera_, r, corners, &jacobians);
  Mat7 metric = Mat7::Zero();
  int count = 0;
  for (std::size_t k = 0; k < static_cast<std::size_t>(kNumCorners); ++k) {
    if (corners.in_image[k] && jacobians[k].allFinite()) {
      metric.noalias() += jacobians[k].transpose() * jacobians[k];
      ++count;
    }
  }
  if (count == 0) {
    return false;
  }
  // A direction the corners do not see at all is not a slide: a small
  // floor keeps the metric definite (px^2 per unit of r). The step is
  // scaled by the corners' own motion, without it.
  const Mat7 floored = metric + 1e-6 * metric.trace() * Mat7::Identity();
  // The fit's Gauss-Newton matrix at r (the pose's block; the streak held).
  const Vec2 streak = prepare_streak(streak_px);
  ParamVector theta;
  theta.head<solver::kNumParams>() = r;
  theta[7] = streak.x();
  theta[8] = streak.y();
  Appearance app;
  (void)start_appearance(theta, false, app);  // the cost is not needed, only the appearance and weights
  ParamMatrix H;
  ParamVector grad;
  normal_equations(theta, app, solver::kNumParams, H, grad);
  const Mat7 h7 = H.topLeftCorner<solver::kNumParams, solver::kNumParams>();
  if (!h7.allFinite() || !floored.allFinite()) {
    return false;
  }
  Eigen::GeneralizedSelfAdjointEigenSolver<Mat7> eig(h7, floored, Eigen::ComputeEigenvectors | Eigen::Ax_lBx);
  if (eig.info() != Eigen::Success) {
    return false;
  }
  const PoseVector v = eig.eigenvectors().col(0);  // eigenvalues ascending
  const double moved_px2 = v.dot(metric * v) / static_cast<double>(count);
  if (!(moved_px2 > 0.0) || !v.allFinite()) {
    return false;
  }
  step = v * (rms_px / std::sqrt(moved_px2));
  return true;
}

bool DenseFit::occluded_by_instrument(const Vec3& point, double s_point) const noexcept {
  // The ray from the camera to the point against every segment (the
  // segments of the last build_segments): a hit in front of it, farther
  // than 0.3 mm from it (a limb point is grazed by its own surface), hides it.
  if (!(point.z() > 0.0)) {
    return true;
  }
  const Vec3 d = point / point.z();
  for (int si = 0; si < seg_count_; ++si) {
    const Segment& s = segs_[static_cast<std::size_t>(si)];
    const Vec3 a = segment_end_a(s), b = segment_end_b(s), e = segment_axis(s);
    const Vec3 na = to_vec3(s.nax, s.nay, s.naz), nb = to_vec3(s.nbx, s.nby, s.nbz);
    const double dd = d.dot(e);
    const Vec3 dp = d - dd * e;
    const Vec3 m = -a;
    const Vec3 mp = m - m.dot(e) * e;
    const double A = dp.squaredNorm();
    if (A < 1e-12) {
      continue;
    }
    const double B = mp.dot(dp);
    const double C = mp.squaredNorm() - static_cast<double>(s.radius) * static_cast<double>(s.radius);
    const double disc = B * B - A * C;
    if (disc < 0.0) {
      continue;
    }
    for (int root = 0; root < 2; ++root) {
      const double t = (-B + (root == 0 ? -1.0 : 1.0) * std::sqrt(disc)) / A;
      if (!(t > 0.0) || t >= point.z()) {
        continue;
      }
      const Vec3 x = t * d;
      if ((s.cap_a && (x - a).dot(na) < 0.0) || (s.cap_b && (x - b).dot(nb) > 0.0)) {
        continue;
      }
      // Near a limb point the ray grazes the chords, which cut it anywhere
      // along a fraction of a millimetre of arc: only another stretch of
      // the instrument (over 1 mm of arc away) hides the point.
      const double s_hit = static_cast<double>(s.s_a) + (x - a).dot(e) * static_cast<double>(s.ds);
      if ((x - point).squaredNorm() > 0.09 && std::fabs(s_hit - s_point) > 1.0) {
        return true;
      }
    }
  }
  return false;
}

void DenseFit::corner_support(const PoseVector& r, const Vec2& streak_px,
                              std::array<double, kNumCorners>& support) noexcept {
  support.fill(0.0);
  if (rw_ <= 0 || rh_ <= 0) {
    return;
  }
  (void)streak_px;
  solver::CornerSet corners;
  model_.corners(camera_, r, corners);
  render_geometry(r);
  const double half = 0.5 * (scale_ - 1);
  const int reach = std::max(1, static_cast<int>(std::ceil(3.0 / scale_)));
  for (int k = 0; k < kNumCorners; ++k) {
    const std::size_t kk = static_cast<std::size_t>(k);
    if (!corners.in_image[kk]) {
      continue;
    }
    // Hidden behind another part of the instrument: a first hit well in
    // front of the corner's depth at its pixel.
    const double wx = (corners.pixel[kk].x() - fx0_ - half) / scale_;
    const double wy = (corners.pixel[kk].y() - fy0_ - half) / scale_;
    const int cx = static_cast<int>(std::lround(wx));
    const int cy = static_cast<int>(std::lround(wy));
    if (cx < 0 || cy < 0 || cx >= rw_ || cy >= rh_) {
      continue;
    }
    const bool hidden = occluded_by_instrument(corners.point[kk], model_.geometry().boundaries_mm[kk / 2U]);
    double sum = 0.0;
    double n = 0.0;
    for (int y = cy - reach; y <= cy + reach; ++y) {
      for (int x = cx - reach; x <= cx + reach; ++x) {
        if (x < 0 || y < 0 || x >= rw_ || y >= rh_) {
          continue;
        }
        const std::size_t i = idx(x, y, rw_);
        if (cov0_[i] + cov1_[i] < 0.5F) {
          continue;
        }
        sum += static_cast<double>(weights_[i]);
        n += 1.0;
      }
    }
    support[kk] = (hidden || n < 1.0) ? 0.0 : sum / n;
  }
}

}  // namespace vision
}  // namespace tcpest
