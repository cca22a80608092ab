#include "tcpest/render/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <new>

#include "scene_random.hpp"
#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace render {

using solver::kNumBoundaries;
using solver::kNumCorners;
using solver::kNumMarkers;
using solver::PoseVector;
using solver::Vec2;
using solver::Vec3;

namespace {

constexpr int kTileSize = 16;
constexpr int kMaxShaftPieces = 16;
constexpr int kMaxSegmentsPerStripe = 32;
constexpr int kMaxPrimsPerInstrument = kMaxShaftPieces + kNumMarkers * kMaxSegmentsPerStripe + 1;
constexpr int kMaxPrims = 2 * kMaxPrimsPerInstrument;
constexpr int kTexBits = 9;
constexpr int kTexSize = 1 << kTexBits;  // tileable procedural textures, kTexSize^2 texels
constexpr int kTexMask = kTexSize - 1;
constexpr double kTexelMm = 0.3;         // texel size on the tissue surface
constexpr int kGaussTableSize = 4096;
constexpr int kToneLutSize = 4096;
constexpr double kShaftPieceMm = 4.0;    // shaft split so that each piece has a tight image bound
// A hit counts as hiding a corner only if it is farther than this from the
// corner's 3D point (the ray to a limb point grazes the tube there).
constexpr double kVisibilityToleranceMm = 0.3;
constexpr double kPlaneEps = 1.0e-7;     // mm: overlap of neighbouring chords (no cracks)
// Irradiance follows 1/d^2 beyond this distance and stays at its value
// nearer: the light guides sit beside the lens and have a finite size, so
// the parts next to the camera (the shaft at the channel exit) are not lit
// a hundred times more than the scene.
constexpr double kLightNearMm = 15.0;
double falloff(double dist2) noexcept { return 1.0 / std::max(dist2, kLightNearMm * kLightNearMm); }
// What lights tissue in the instrument's shadow: the scene's scattered light,
// as a share of the lamp's.
constexpr double kShadowLight = 0.2;

// Instrument parts (label = kLabelInstrument + 8 * instrument + part), the
// public PixelLabel codes.
enum Part : std::uint8_t { kPartShaft = kPartShaftLabel, kPartStripe0 = kPartMarker1Label, kPartGrasper = kPartGrasperLabel };
enum Label : std::uint8_t {
  kLabelTissue = kPixelTissue,
  kLabelDecoy = kPixelDecoy,
  kLabelOccluder = kPixelOccluder,
  kLabelReflection = kPixelReflection,
  kLabelInstrument = kPixelInstrument,
  kLabelNoRay = kPixelNoRay,
};

struct Rgb {
  double r = 0.0, g = 0.0, b = 0.0;
};
Rgb operator+(const Rgb& a, const Rgb& b) noexcept { return Rgb{a.r + b.r, a.g + b.g, a.b + b.b}; }
Rgb operator*(const Rgb& a, double s) noexcept { return Rgb{a.r * s, a.g * s, a.b * s}; }
Rgb per_channel(const Rgb& a, const Rgb& gain) noexcept { return Rgb{a.r * gain.r, a.g * gain.g, a.b * gain.b}; }
Rgb mix(const Rgb& a, const Rgb& b, double t) noexcept { return a * (1.0 - t) + b * t; }

// A straight tube piece: a cylinder of `radius` around p0 -> p1, cut by the
// planes through p0 and p1 with normals n0 and n1 (the true centreline
// tangents: for a circular arc's chords these are exactly the mitre planes,
// so neighbouring chords join without gap or overlap). Optional flat caps.
struct Primitive {
  Vec3 p0, p1, axis, n0, n1;
  double radius = 0.0;
  double s0 = 0.0, s1 = 0.0;  // arc length range (bending section) for shading
  Vec3 centre;                // bounding sphere
  double bound_radius = 0.0;
  double xmin = 0.0, xmax = 0.0, ymin = 0.0, ymax = 0.0;  // bound on the z = 1 plane
  bool cap0 = false, cap1 = false;
  std::uint8_t part = 0U;
  std::uint8_t instrument = 0U;
};

struct Hit {
  double t = std::numeric_limits<double>::infinity();
  Vec3 point, normal;
  int prim = -1;
};

double dot3(const Vec3& a, const Vec3& b) noexcept { return a.dot(b); }

// Nearest hit of origin + t d (t in (tmin, tmax)) with a primitive's outside.
bool intersect(const Primitive& p, const Vec3& origin, const Vec3& d, double tmin, double tmax, Hit& hit) noexcept {
  const Vec3 w = origin - p.p0;
  const double da = dot3(d, p.axis);
  const double wa = dot3(w, p.axis);
  const Vec3 dp = d - da * p.axis;
  const Vec3 wp = w - wa * p.axis;
  const double a = dp.squaredNorm();
  bool found = false;
  if (a > 1e-18) {
    const double b = dot3(dp, wp);  // half of B
    const double c = wp.squaredNorm() - p.radius * p.radius;
    const double disc = b * b - a * c;
    if (disc >= 0.0 && c > 0.0) {  // c <= 0: origin inside the tube, no outside hit
      const double t = (-b - std::sqrt(disc)) / a;
      if (t > tmin && t < tmax) {
        const Vec3 x = origin + t * d;
        if (dot3(x - p.p0, p.n0) >= -kPlaneEps && dot3(x - p.p1, p.n1) <= kPlaneEps) {
          hit.t = t;
          hit.point = x;
          hit.normal = (wp + t * dp) / p.radius;
          tmax = t;
          found = true;
        }
      }
    }
  }
  for (int cap = 0; cap < 2; ++cap) {
    const bool enabled = (cap == 0) ? p.cap0 : p.cap1;
    if (!enabled) {
      continue;
    }
    const Vec3& n = (cap == 0) ? p.n0 : p.n1;
    const Vec3& centre = (cap == 0) ? p.p0 : p.p1;
    const double denom = dot3(d, n);
    // Cap 0 faces -n0 (seen from behind the piece), cap 1 faces +n1.
    if ((cap == 0 && !(denom > 1e-12)) || (cap == 1 && !(denom < -1e-12))) {
      continue;
    }
    const double t = dot3(centre - origin, n) / denom;
    if (!(t > tmin && t < tmax)) {
      continue;
    }
    const Vec3 x = origin + t * d;
    const Vec3 rel = x - centre;
    const double along = dot3(rel, p.axis);
    if ((rel - along * p.axis).squaredNorm() <= p.radius * p.radius) {
      hit.t = t;
      hit.point = x;
      hit.normal = (cap == 0) ? Vec3(-n) : n;
      tmax = t;
      found = true;
    }
  }
  return found;
}

// Ray through the origin (the camera) misses the bounding sphere?
bool misses_sphere(const Vec3& origin, const Vec3& d_unit, const Vec3& centre, double radius) noexcept {
  const Vec3 oc = centre - origin;
  const double along = dot3(oc, d_unit);
  if (along < -radius) {
    return true;
  }
  return (oc - along * d_unit).squaredNorm() > radius * radius;
}

// Bound on the z = 1 plane of the box around the piece p0 -> p1 grown by
// `reach` (mm), z clipped to > 0: sets p.xmin, xmax, ymin, ymax.
void set_image_bound(Primitive& p, const Vec3& p0, const Vec3& p1, double reach) noexcept {
  const Vec3 lo = p0.cwiseMin(p1) - Vec3::Constant(reach);
  const Vec3 hi = p0.cwiseMax(p1) + Vec3::Constant(reach);
  const double inf = std::numeric_limits<double>::infinity();
  if (!(hi.z() > 0.0)) {
    p.xmin = inf;  // entirely behind the camera: matches no ray
    p.xmax = -inf;
    p.ymin = inf;
    p.ymax = -inf;
    return;
  }
  const double zlo = std::max(lo.z(), 1e-9);
  const double zhi = hi.z();
  // x / z over the box: extremes at the corners (z > 0).
  p.xmin = std::min(lo.x() / zlo, lo.x() / zhi);
  p.xmax = std::max(hi.x() / zlo, hi.x() / zhi);
  p.ymin = std::min(lo.y() / zlo, lo.y() / zhi);
  p.ymax = std::max(hi.y() / zlo, hi.y() / zhi);
  if (lo.z() <= 1e-9) {  // reaches the camera plane: unbounded where the sign allows
    if (lo.x() <= 0.0) {
      p.xmin = -inf;
    }
    if (hi.x() >= 0.0) {
      p.xmax = inf;
    }
    if (lo.y() <= 0.0) {
      p.ymin = -inf;
    }
    if (hi.y() >= 0.0) {
      p.ymax = inf;
    }
  }
}

double clamp01(double v) noexcept { return v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v); }
double smoothstep(double e0, double e1, double x) noexcept {
  const double t = clamp01((x - e0) / (e1 - e0));
  return t * t * (3.0 - 2.0 * t);
}
double pow32(double c) noexcept {
  double v = c * c;  // ^2
  v *= v;            // ^4
  v *= v;            // ^8
  v *= v;            // ^16
  return v * v;      // ^32
}

// Tileable value noise for the texture bake (creation time only).
double lattice(std::uint64_t seed, int ix, int iy, int period) noexcept {
  const auto ux = static_cast<std::uint64_t>((ix % period + period) % period);
  const auto uy = static_cast<std::uint64_t>((iy % period + period) % period);
  const std::uint64_t h = splitmix64(seed ^ (ux * 0x9E3779B1ULL) ^ (uy * 0x85EBCA77ULL << 20U));
  return static_cast<double>(h >> 11U) * (2.0 / 9007199254740992.0) - 1.0;
}
double value_noise(std::uint64_t seed, double x, double y, int period) noexcept {
  const double fx = std::floor(x);
  const double fy = std::floor(y);
  const int ix = static_cast<int>(fx);
  const int iy = static_cast<int>(fy);
  double tx = x - fx;
  double ty = y - fy;
  tx = tx * tx * (3.0 - 2.0 * tx);
  ty = ty * ty * (3.0 - 2.0 * ty);
  const double a = lattice(seed, ix, iy, period);
  const double b = lattice(seed, ix + 1, iy, period);
  const double c = lattice(seed, ix, iy + 1, period);
  const double e = lattice(seed, ix + 1, iy + 1, period);
  return (a + (b - a) * tx) + ((c + (e - c) * tx) - (a + (b - a) * tx)) * ty;
}
// Fractal noise over the texture (u, v in texels), periodic over kTexSize.
double fractal(std::uint64_t seed, double u, double v, int base_period_texels, int octaves) noexcept {
  double sum = 0.0;
  double amplitude = 1.0;
  double norm = 0.0;
  int cells = kTexSize / base_period_texels;
  for (int o = 0; o < octaves; ++o) {
    const double scale = static_cast<double>(cells) / static_cast<double>(kTexSize);
    sum += amplitude * value_noise(seed + static_cast<std::uint64_t>(o) * 7919U, u * scale, v * scale, cells);
    norm += amplitude;
    amplitude *= 0.5;
    cells *= 2;
  }
  return sum / norm;
}

struct Texture {
  std::unique_ptr<float[]> data;
  bool allocate() noexcept {
    data.reset(new (std::nothrow) float[static_cast<std::size_t>(kTexSize) * kTexSize]);
    return data != nullptr;
  }
  float& at(int x, int y) noexcept { return data[static_cast<std::size_t>(y) * kTexSize + static_cast<std::size_t>(x)]; }
};

// All tissue channels of one texel side by side: one bilinear fetch of four
// texels gives every channel the shading needs (cache-friendly).
struct TissueTexel {
  float height, height_du, height_dv;  // bumps [-1, 1] and their slope per texel
  float colour, fat, vessel, wet;      // albedo variation, fat patches, vessels, wet film
  float wet_du, wet_dv;                // slope of the wet film's fine relief per texel
  float pad;
};
struct TissueSample {
  double height, height_du, height_dv, colour, fat, vessel, wet, wet_du, wet_dv;
};

enum TextureId : int {
  kTexHeight = 0,   // large bumps, [-1, 1]
  kTexHeightDu,     // its derivative per texel
  kTexHeightDv,
  kTexDetailDu,     // derivative of the fine wet relief
  kTexDetailDv,
  kTexColour,       // albedo variation, [-1, 1]
  kTexFat,          // yellowish patches, [0, 1]
  kTexVessel,       // vessel density, [0, 1]
  kTexWet,          // wet (specular) areas, [0, 1]
  kNumTextures
};

// Per-frame random layout of the scene (all from the seed).
struct SceneLayout {
  double depth_mm = 60.0;     // mean tissue depth
  double tilt_x = 0.0, tilt_y = 0.0;
  double bump_mm = 4.0;
  double tex_cos = 1.0, tex_sin = 0.0, tex_u0 = 0.0, tex_v0 = 0.0;
  double light = 1.0;         // intensity: radiance = light / d^2 * brdf
  Vec3 lamp = Vec3::Zero();   // the lamp's position (mm, camera frame): Appearance::lamp_offset_mm
  bool lamp_at_lens = true;
  bool clean = false;
  // Hard cases.
  bool reflection = false;
  double reflection_strength = 0.0;
  bool occluder = false;
  double occ_x = 0.0, occ_y = 0.0, occ_radius = 0.0, occ_depth = 0.0, occ_p1 = 0.0, occ_p2 = 0.0;
  bool occ_blood = false;
  bool decoy = false;
  double decoy_x = 0.0, decoy_y = 0.0, decoy_radius = 0.0;  // tissue surface mm
  Rgb decoy_albedo;
  bool haze = false;
  double haze_density = 0.0;
  Rgb haze_radiance;
  bool motion_blur = false;
  double blur_dx = 0.0, blur_dy = 0.0;  // full streak, pixels
  double noise_sigma = 0.0, blur_sigma = 0.0, vignetting = 0.0;
  Rgb tissue_tint{1.0, 1.0, 1.0};
  std::array<double, 3> white_balance{1.0, 1.0, 1.0};
};

struct Sample {
  Rgb colour;
  std::uint8_t label = kLabelTissue;
  bool instrument = false;
};

// A pixel's ray (cx, cy on the z = 1 plane) and its derivatives per pixel
// step in x (gxx, gxy) and in y (gyx, gyy).
struct RayFootprint {
  double cx = 0.0, cy = 0.0;
  double gxx = 0.0, gxy = 0.0, gyx = 0.0, gyy = 0.0;
};

struct Materials {
  Rgb albedo[7];
  double specular[7];
};

}  // namespace

struct Renderer::Impl {
  solver::CameraModel camera;
  solver::InstrumentModel model;
  RenderSettings settings;
  int width = 0, height = 0;
  std::size_t pixels = 0U;
  std::unique_ptr<float[]> ray_x, ray_y;  // normalised ray per pixel (NaN: no ray)
  int tiles_x = 0, tiles_y = 0;
  std::unique_ptr<double[]> tile_rect;      // xmin, xmax, ymin, ymax per tile
  std::unique_ptr<std::uint16_t[]> tile_prims;
  std::unique_ptr<std::uint16_t[]> tile_count;
  Texture tex[kNumTextures];                // bake scratch, released after creation
  std::unique_ptr<TissueTexel[]> tissue;   // kTexSize^2 interleaved texels
  std::unique_ptr<float[]> linear;   // 3 * pixels, linear radiance
  std::unique_ptr<float[]> scratch;  // 3 * pixels, blur pass
  std::unique_ptr<std::uint8_t[]> labels;
  float gauss[kGaussTableSize] = {};
  float tone[kToneLutSize + 1] = {};  // linear [0, kToneMax] -> 8-bit level (float)
  double max_radius2 = 1.0;           // pixel distance^2 from the centre to the farthest corner

  Primitive prims[kMaxPrims];
  int prim_count = 0;
  int inst_first[2] = {0, 0};
  int inst_count[2] = {0, 0};
  Vec3 inst_centre[2];
  double inst_radius[2] = {0.0, 0.0};
  Vec3 grasper_binormal[2];
  Materials materials{};
  SceneLayout layout;

  bool allocate() noexcept;
  void build_rays() noexcept;
  void bake_textures() noexcept;
  // The parts' radii of the scene being built (Appearance's scales applied).
  double shaft_radius_mm = 0.0;
  double grasper_radius_mm = 0.0;
  void build_instrument(const PoseVector& r, std::uint8_t index) noexcept;
  void bin_tiles() noexcept;
  void make_layout(const SceneSpec& scene, const GroundTruth& truth) noexcept;
  void set_materials(const Appearance& appearance) noexcept;
  bool nearest_instrument_hit(const Vec3& origin, const Vec3& d, double tmax, Hit& hit,
                              const std::uint16_t* candidates, int candidate_count) const noexcept;
  TissueSample sample_tissue(double u, double v) const noexcept;
  double tissue_depth(double x, double y) const noexcept;
  bool in_occluder(double x, double y) const noexcept;
  // Where the lamp lies from a surface point seen along `view` (unit, to
  // the camera; `view_dist2` the squared distance to it): the unit vector
  // to the lamp, the half vector between it and the view, and the squared
  // distance the falloff uses. All three are the view's when the lamp sits
  // at the lens.
  struct LampView {
    Vec3 to_lamp;
    Vec3 half;
    double dist2;
  };
  LampView lamp_view(const Vec3& point, const Vec3& view, double view_dist2) const noexcept {
    if (layout.lamp_at_lens) {
      return LampView{view, view, view_dist2};
    }
    const Vec3 d = layout.lamp - point;
    const double d2 = d.squaredNorm();
    const Vec3 to = d / std::sqrt(d2);
    return LampView{to, (to + view).normalized(), d2};
  }
  // Whether an instrument lies between `point` and the lamp.
  bool shadowed(const Vec3& point, const LampView& lamp) const noexcept {
    const double reach = std::sqrt(lamp.dist2);
    for (int k = 0; k < 2; ++k) {
      if (inst_count[k] == 0 || misses_sphere(point, lamp.to_lamp, inst_centre[k], inst_radius[k])) {
        continue;
      }
      Hit hit;
      for (int i = inst_first[k]; i < inst_first[k] + inst_count[k]; ++i) {
        const Primitive& p = prims[i];
        if (!misses_sphere(point, lamp.to_lamp, p.centre, p.bound_radius) &&
            intersect(p, point, lamp.to_lamp, 1e-3, reach, hit)) {
          return true;
        }
      }
    }
    return false;
  }
  Rgb shade_instrument(const Hit& hit) const noexcept;
  // The tissue's reflectance at (sx, sy) on its mean plane (mm), a decoy's
  // over it; `label` says which.
  Rgb tissue_albedo(double sx, double sy, const TissueSample& t, std::uint8_t& label) const noexcept;
  Rgb shade_tissue(double x, double y, double plane, const TissueSample& t, std::uint8_t& label) const noexcept;
  Rgb shade_occluder(double x, double y) const noexcept;
  Sample shade(double x, double y, const std::uint16_t* candidates, int candidate_count) const noexcept;
  Rgb apply_haze(const Rgb& c, double depth, double x, double y) const noexcept;
  void compute_truth(const SceneSpec& scene, GroundTruth& truth) noexcept;
  void shade_pixel_centres(float* coverage, long* instrument_pixels) noexcept;
  bool on_label_edge(int x, int y, std::uint8_t label) const noexcept;
  RayFootprint ray_footprint(int x, int y) const noexcept;
  void supersample_pixel(int x, int y, float* coverage) noexcept;
  void supersample_edges(float* coverage) noexcept;
  void apply_motion_blur(const float* src, float* dst) const noexcept;
  void apply_optical_blur(float* image, float* tmp) const noexcept;
  void tone_map(const SceneSpec& scene, const float* src, const MutableImageView& out) const noexcept;
  void post_process(const SceneSpec& scene, const MutableImageView& out) noexcept;
};

const char* to_string(RenderError e) noexcept {
  switch (e) {
    case RenderError::OutOfMemory: return "not enough memory for the renderer's tables";
    case RenderError::BadSettings: return "render settings out of range (supersample 1..8, segments 2..32)";
    case RenderError::BadImage: return "output image invalid or not the camera's size";
    case RenderError::BadScene: return "scene has a non-finite configuration or setting";
    case RenderError::ImageTooLarge: return "camera image larger than the renderer accepts (3840x2160)";
  }
  return "unknown render error";
}

const char* hard_case_name(int bit_index) noexcept {
  switch (bit_index) {
    case 0: return "reflection";
    case 1: return "occluder";
    case 2: return "haze";
    case 3: return "decoy";
    case 4: return "noise";
    case 5: return "motion_blur";
    default: return "unknown";
  }
}

const char* to_string(InstrumentView v) noexcept {
  switch (v) {
    case InstrumentView::Visible: return "visible";
    case InstrumentView::BehindCamera: return "behind_camera";
    case InstrumentView::OutOfView: return "out_of_view";
  }
  return "unknown";
}

bool Renderer::Impl::allocate() noexcept {
  const std::size_t n = pixels;
  ray_x.reset(new (std::nothrow) float[n]);
  ray_y.reset(new (std::nothrow) float[n]);
  linear.reset(new (std::nothrow) float[3U * n]);
  scratch.reset(new (std::nothrow) float[3U * n]);
  labels.reset(new (std::nothrow) std::uint8_t[n]);
  tiles_x = (width + kTileSize - 1) / kTileSize;
  tiles_y = (height + kTileSize - 1) / kTileSize;
  const auto tiles = static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y);
  tile_rect.reset(new (std::nothrow) double[4U * tiles]);
  tile_prims.reset(new (std::nothrow) std::uint16_t[tiles * static_cast<std::size_t>(kMaxPrims)]);
  tile_count.reset(new (std::nothrow) std::uint16_t[tiles]);
  bool ok = ray_x && ray_y && linear && scratch && labels && tile_rect && tile_prims && tile_count;
  for (auto& t : tex) {
    ok = ok && t.allocate();
  }
  tissue.reset(new (std::nothrow) TissueTexel[static_cast<std::size_t>(kTexSize) * kTexSize]);
  return ok && tissue;
}

void Renderer::Impl::build_rays() noexcept {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      Vec2 n;
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u);
      if (camera.undistort(Vec2(u, v), n)) {
        ray_x[i] = static_cast<float>(n.x());
        ray_y[i] = static_cast<float>(n.y());
      } else {
        ray_x[i] = static_cast<float>(nan);
        ray_y[i] = static_cast<float>(nan);
      }
    }
  }
  // Per tile: the bound of its rays, one pixel wider (sub-samples reach half a
  // pixel past the centres).
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      double xmin = std::numeric_limits<double>::infinity();
      double xmax = -xmin;
      double ymin = xmin;
      double ymax = -xmin;
      const int u0 = std::max(0, tx * kTileSize - 1);
      const int u1 = std::min(width - 1, tx * kTileSize + kTileSize);
      const int v0 = std::max(0, ty * kTileSize - 1);
      const int v1 = std::min(height - 1, ty * kTileSize + kTileSize);
      for (int v = v0; v <= v1; ++v) {
        for (int u = u0; u <= u1; ++u) {
          const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u);
          const auto x = static_cast<double>(ray_x[i]);
          if (std::isnan(x)) {
            continue;
          }
          const auto y = static_cast<double>(ray_y[i]);
          xmin = std::min(xmin, x);
          xmax = std::max(xmax, x);
          ymin = std::min(ymin, y);
          ymax = std::max(ymax, y);
        }
      }
      // Widen by a pixel's footprint at the edge of the tile (and a margin).
      const double margin = 2.0 * (xmax - xmin + ymax - ymin) / static_cast<double>(kTileSize) + 1e-6;
      double* rect = &tile_rect[4U * (static_cast<std::size_t>(ty) * static_cast<std::size_t>(tiles_x) +
                                      static_cast<std::size_t>(tx))];
      rect[0] = xmin - margin;
      rect[1] = xmax + margin;
      rect[2] = ymin - margin;
      rect[3] = ymax + margin;
    }
  }
  const auto& k = camera.intrinsics();
  const double dx = std::max(k.cx, static_cast<double>(width - 1) - k.cx);
  const double dy = std::max(k.cy, static_cast<double>(height - 1) - k.cy);
  max_radius2 = std::max(1.0, dx * dx + dy * dy);
}

void Renderer::Impl::bake_textures() noexcept {
  constexpr std::uint64_t kBakeSeed = 0x7C3E5A1DULL;  // fixed: the scene seed picks where to look
  for (int y = 0; y < kTexSize; ++y) {
    for (int x = 0; x < kTexSize; ++x) {
      const double u = x;
      const double v = y;
      tex[kTexHeight].at(x, y) = static_cast<float>(fractal(kBakeSeed + 1U, u, v, 128, 4));
      tex[kTexColour].at(x, y) = static_cast<float>(fractal(kBakeSeed + 2U, u, v, 32, 5));
      tex[kTexFat].at(x, y) = static_cast<float>(smoothstep(0.25, 0.6, fractal(kBakeSeed + 3U, u, v, 128, 3)));
      // Vessels: thin ridges of two noise fields (the zero crossings), the
      // second finer; looks like a branching vessel network.
      const double n1 = fractal(kBakeSeed + 4U, u, v, 128, 3);
      const double n2 = fractal(kBakeSeed + 5U, u, v, 64, 3);
      const double v1 = dmath::exp(-(n1 * n1) / (2.0 * 0.018 * 0.018));
      const double v2 = 0.7 * dmath::exp(-(n2 * n2) / (2.0 * 0.012 * 0.012));
      // Faded in places: segments and branches rather than closed loops.
      const double fade = smoothstep(-0.25, 0.35, fractal(kBakeSeed + 8U, u, v, 128, 3));
      tex[kTexVessel].at(x, y) = static_cast<float>(std::max(v1, v2) * fade);
      tex[kTexWet].at(x, y) = static_cast<float>(smoothstep(0.15, 0.45, fractal(kBakeSeed + 6U, u, v, 128, 3)));
      // Fine wet relief (its height goes into scratch texture kTexDetailDu for now).
      tex[kTexDetailDu].at(x, y) = static_cast<float>(fractal(kBakeSeed + 7U, u, v, 16, 2));
    }
  }
  // Derivatives by central differences (wrapping): height, then detail.
  for (int y = 0; y < kTexSize; ++y) {
    for (int x = 0; x < kTexSize; ++x) {
      const int xp = (x + 1) & kTexMask;
      const int xm = (x - 1) & kTexMask;
      const int yp = (y + 1) & kTexMask;
      const int ym = (y - 1) & kTexMask;
      tex[kTexHeightDu].at(x, y) = 0.5F * (tex[kTexHeight].at(xp, y) - tex[kTexHeight].at(xm, y));
      tex[kTexHeightDv].at(x, y) = 0.5F * (tex[kTexHeight].at(x, yp) - tex[kTexHeight].at(x, ym));
      tex[kTexDetailDv].at(x, y) = 0.5F * (tex[kTexDetailDu].at(x, yp) - tex[kTexDetailDu].at(x, ym));
    }
  }
  // kTexDetailDu still holds the detail height: turn it into its u-derivative
  // row by row (a copy of the row keeps the original values).
  float row[kTexSize];
  for (int y = 0; y < kTexSize; ++y) {
    for (int x = 0; x < kTexSize; ++x) {
      row[x] = tex[kTexDetailDu].at(x, y);
    }
    for (int x = 0; x < kTexSize; ++x) {
      tex[kTexDetailDu].at(x, y) = 0.5F * (row[(x + 1) & kTexMask] - row[(x - 1) & kTexMask]);
    }
  }
  // Interleave, then release the scratch.
  for (int y = 0; y < kTexSize; ++y) {
    for (int x = 0; x < kTexSize; ++x) {
      TissueTexel& t = tissue[static_cast<std::size_t>(y) * kTexSize + static_cast<std::size_t>(x)];
      t.height = tex[kTexHeight].at(x, y);
      t.height_du = tex[kTexHeightDu].at(x, y);
      t.height_dv = tex[kTexHeightDv].at(x, y);
      t.colour = tex[kTexColour].at(x, y);
      t.fat = tex[kTexFat].at(x, y);
      t.vessel = tex[kTexVessel].at(x, y);
      t.wet = tex[kTexWet].at(x, y);
      t.wet_du = tex[kTexDetailDu].at(x, y);
      t.wet_dv = tex[kTexDetailDv].at(x, y);
      t.pad = 0.0F;
    }
  }
  for (auto& t : tex) {
    t.data.reset();
  }
  // Gaussian table for sensor noise (a fixed stream; the scene seed picks entries).
  Random rng(kBakeSeed, 99U);
  for (float& g : gauss) {
    g = static_cast<float>(rng.normal());
  }
  // Tone curve: soft shoulder (1 - exp(-x)), then display gamma 1/2.2, to
  // 8-bit levels. Index = linear * kToneLutSize / kToneMax.
  for (int i = 0; i <= kToneLutSize; ++i) {
    const double x = 4.0 * static_cast<double>(i) / kToneLutSize;
    const double shoulder = 1.0 - dmath::exp(-1.6 * x);
    tone[i] = static_cast<float>(255.0 * dmath::pow_positive(shoulder, 1.0 / 2.2));
  }
}

void Renderer::Impl::set_materials(const Appearance& a) noexcept {
  materials.albedo[kPartShaft] = Rgb{a.shaft_albedo[0], a.shaft_albedo[1], a.shaft_albedo[2]};
  materials.specular[kPartShaft] = a.shaft_gloss;
  materials.albedo[kPartGrasper] = Rgb{a.grasper_albedo[0], a.grasper_albedo[1], a.grasper_albedo[2]};
  materials.specular[kPartGrasper] = a.grasper_gloss;
  const auto& g = model.geometry();
  const Rgb blue{a.blue_albedo[0], a.blue_albedo[1], a.blue_albedo[2]};
  const Rgb yellow{a.yellow_albedo[0], a.yellow_albedo[1], a.yellow_albedo[2]};
  for (int m = 0; m < kNumMarkers; ++m) {
    const bool is_blue = g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue;
    materials.albedo[kPartStripe0 + m] = is_blue ? blue : yellow;
    materials.specular[kPartStripe0 + m] = a.stripe_gloss;
  }
}

void Renderer::Impl::build_instrument(const PoseVector& r, std::uint8_t index) noexcept {
  const auto& g = model.geometry();
  const solver::PoseFrames f = model.frames(r);
  inst_first[index] = prim_count;
  const Vec3 axis = f.channel_rotation.col(2);
  auto add = [this, index](const Vec3& p0, const Vec3& p1, const Vec3& n0, const Vec3& n1, double radius,
                           std::uint8_t part, double s0, double s1, bool cap0, bool cap1) {
    if (prim_count >= kMaxPrims) {
      return;
    }
    Primitive& p = prims[prim_count];
    const Vec3 span = p1 - p0;
    const double length = span.norm();
    if (!(length > 1e-9)) {
      return;
    }
    p.p0 = p0;
    p.p1 = p1;
    p.axis = span / length;
    p.n0 = n0;
    p.n1 = n1;
    p.radius = radius;
    p.part = part;
    p.instrument = index;
    p.s0 = s0;
    p.s1 = s1;
    p.cap0 = cap0;
    p.cap1 = cap1;
    p.centre = 0.5 * (p0 + p1);
    const double reach = 1.05 * radius;  // the mitre cuts reach slightly past R
    p.bound_radius = 0.5 * length + reach;
    set_image_bound(p, p0, p1, reach);
    ++prim_count;
  };

  // Shaft: channel exit to the base, in pieces.
  const double lambda = r[solver::kLambda];
  if (lambda > 1e-6) {
    // Clamped in floating point first: an absurd lambda must not overflow the cast.
    const double wanted = std::min(static_cast<double>(kMaxShaftPieces), std::max(1.0, std::ceil(lambda / kShaftPieceMm)));
    const int pieces = static_cast<int>(wanted);
    for (int i = 0; i < pieces; ++i) {
      const Vec3 a = f.channel_origin + (lambda * i / pieces) * axis;
      const Vec3 b = f.channel_origin + (lambda * (i + 1) / pieces) * axis;
      add(a, b, axis, axis, shaft_radius_mm, kPartShaft, 0.0, 0.0, false, i == pieces - 1);
    }
  }
  // Bending section: chords, every marker boundary a chord end.
  const int per_stripe = settings.segments_per_stripe;
  for (int m = 0; m < kNumMarkers; ++m) {
    const double sa = g.boundaries_mm[static_cast<std::size_t>(m)];
    const double sb = g.boundaries_mm[static_cast<std::size_t>(m) + 1U];
    for (int i = 0; i < per_stripe; ++i) {
      const double s0 = sa + (sb - sa) * i / per_stripe;
      const double s1 = (i + 1 == per_stripe) ? sb : sa + (sb - sa) * (i + 1) / per_stripe;
      const solver::CentrelineFrame c0 = model.centreline(f, s0);
      const solver::CentrelineFrame c1 = model.centreline(f, s1);
      const bool first = (m == 0 && i == 0);
      const bool last = (m == kNumMarkers - 1 && i + 1 == per_stripe);
      add(c0.position, c1.position, c0.tangent, c1.tangent, g.radius_mm,
          static_cast<std::uint8_t>(kPartStripe0 + m), s0, s1, first, last);
    }
  }
  // Grasper: from the end of the bending section to the TCP.
  const solver::CentrelineFrame end = model.centreline(f, g.bend_length_mm);
  const Vec3 tcp = end.position + g.tcp_offset_mm * end.tangent;
  add(end.position, tcp, end.tangent, end.tangent, grasper_radius_mm, kPartGrasper, g.bend_length_mm,
      g.bend_length_mm + g.tcp_offset_mm, false, true);
  grasper_binormal[index] = end.binormal;
  inst_count[index] = prim_count - inst_first[index];
  // Bounding sphere of the whole instrument (for secondary rays).
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -lo;
  for (int i = inst_first[index]; i < prim_count; ++i) {
    lo = lo.cwiseMin(prims[i].centre - Vec3::Constant(prims[i].bound_radius));
    hi = hi.cwiseMax(prims[i].centre + Vec3::Constant(prims[i].bound_radius));
  }
  inst_centre[index] = 0.5 * (lo + hi);
  inst_radius[index] = (inst_count[index] > 0) ? 0.5 * (hi - lo).norm() : 0.0;
}

void Renderer::Impl::bin_tiles() noexcept {
  const int tiles = tiles_x * tiles_y;
  for (int t = 0; t < tiles; ++t) {
    const double* rect = &tile_rect[4U * static_cast<std::size_t>(t)];
    std::uint16_t* list = &tile_prims[static_cast<std::size_t>(t) * static_cast<std::size_t>(kMaxPrims)];
    int count = 0;
    for (int i = 0; i < prim_count; ++i) {
      const Primitive& p = prims[i];
      if (p.xmax < rect[0] || p.xmin > rect[1] || p.ymax < rect[2] || p.ymin > rect[3]) {
        continue;
      }
      list[count++] = static_cast<std::uint16_t>(i);
    }
    tile_count[static_cast<std::size_t>(t)] = static_cast<std::uint16_t>(count);
  }
}

bool Renderer::Impl::nearest_instrument_hit(const Vec3& origin, const Vec3& d, double tmax, Hit& hit,
                                            const std::uint16_t* candidates, int candidate_count) const noexcept {
  bool found = false;
  hit.t = tmax;
  for (int c = 0; c < candidate_count; ++c) {
    const int i = candidates[c];
    const Primitive& p = prims[i];
    if (d.x() < p.xmin || d.x() > p.xmax || d.y() < p.ymin || d.y() > p.ymax) {
      continue;  // primary rays only (origin at the camera, d.z = 1)
    }
    if (intersect(p, origin, d, 1e-6, hit.t, hit)) {
      hit.prim = i;
      found = true;
    }
  }
  return found;
}

TissueSample Renderer::Impl::sample_tissue(double u, double v) const noexcept {
  const double fu = std::floor(u);
  const double fv = std::floor(v);
  const double tu = u - fu;
  const double tv = v - fv;
  const auto iu = static_cast<std::size_t>(static_cast<long>(fu) & kTexMask);
  const auto iv = static_cast<std::size_t>(static_cast<long>(fv) & kTexMask);
  const std::size_t iu1 = (iu + 1U) & static_cast<std::size_t>(kTexMask);
  const std::size_t iv1 = (iv + 1U) & static_cast<std::size_t>(kTexMask);
  const TissueTexel& a = tissue[iv * kTexSize + iu];
  const TissueTexel& b = tissue[iv * kTexSize + iu1];
  const TissueTexel& c = tissue[iv1 * kTexSize + iu];
  const TissueTexel& d = tissue[iv1 * kTexSize + iu1];
  const auto wa = static_cast<float>((1.0 - tu) * (1.0 - tv));
  const auto wb = static_cast<float>(tu * (1.0 - tv));
  const auto wc = static_cast<float>((1.0 - tu) * tv);
  const auto wd = static_cast<float>(tu * tv);
  auto mixf = [wa, wb, wc, wd](float pa, float pb, float pc, float pd) {
    return static_cast<double>(wa * pa + wb * pb + wc * pc + wd * pd);
  };
  TissueSample t{};
  t.height = mixf(a.height, b.height, c.height, d.height);
  t.height_du = mixf(a.height_du, b.height_du, c.height_du, d.height_du);
  t.height_dv = mixf(a.height_dv, b.height_dv, c.height_dv, d.height_dv);
  t.colour = mixf(a.colour, b.colour, c.colour, d.colour);
  t.fat = mixf(a.fat, b.fat, c.fat, d.fat);
  t.vessel = mixf(a.vessel, b.vessel, c.vessel, d.vessel);
  t.wet = mixf(a.wet, b.wet, c.wet, d.wet);
  t.wet_du = mixf(a.wet_du, b.wet_du, c.wet_du, d.wet_du);
  t.wet_dv = mixf(a.wet_dv, b.wet_dv, c.wet_dv, d.wet_dv);
  return t;
}

double Renderer::Impl::tissue_depth(double x, double y) const noexcept {
  const SceneLayout& s = layout;
  const double plane = s.depth_mm * (1.0 + s.tilt_x * x + s.tilt_y * y);
  const double sx = x * plane;
  const double sy = y * plane;
  const double u = (s.tex_cos * sx - s.tex_sin * sy) / kTexelMm + s.tex_u0;
  const double v = (s.tex_sin * sx + s.tex_cos * sy) / kTexelMm + s.tex_v0;
  return plane + s.bump_mm * sample_tissue(u, v).height;
}

bool Renderer::Impl::in_occluder(double x, double y) const noexcept {
  const SceneLayout& s = layout;
  if (!s.occluder) {
    return false;
  }
  const double dx = x - s.occ_x;
  const double dy = y - s.occ_y;
  const double r2 = dx * dx + dy * dy;
  const double outer = 1.25 * s.occ_radius;
  if (r2 > outer * outer) {
    return false;
  }
  const double a = dmath::atan2(dy, dx);
  const double rim = s.occ_radius * (1.0 + 0.14 * dmath::sin(2.0 * a + s.occ_p1) + 0.07 * dmath::sin(3.0 * a + s.occ_p2));
  return r2 < rim * rim;
}

Rgb Renderer::Impl::shade_instrument(const Hit& hit) const noexcept {
  const Primitive& p = prims[hit.prim];
  const double dist2 = hit.point.squaredNorm();
  const Vec3 view = -hit.point / std::sqrt(dist2);
  const LampView lamp = lamp_view(hit.point, view, dist2);
  const double cosine = std::max(0.0, dot3(hit.normal, lamp.to_lamp));
  const double crest = std::max(0.0, dot3(hit.normal, lamp.half));
  Rgb albedo = materials.albedo[p.part];
  double ks = materials.specular[p.part];
  if (p.part == kPartGrasper) {
    // The jaws' slit: a dark groove along the grasper in the binormal plane.
    const double across = std::fabs(dot3(hit.normal, grasper_binormal[p.instrument]));
    const double groove = smoothstep(0.05, 0.16, across);
    albedo = albedo * (0.15 + 0.85 * groove);
    ks *= groove;
    // Brushed metal: a slightly darker tint towards the tip.
    const double along = dot3(hit.point - p.p0, p.axis) / std::max(1e-9, (p.p1 - p.p0).norm());
    albedo = albedo * (1.0 - 0.2 * clamp01(along));
  }
  // Glossy sleeve: a broad lobe plus a sharp one; along the tube's crest
  // (normal towards the camera and the light) it saturates to white.
  const double c2 = crest * crest;
  const double c8 = c2 * c2 * c2 * c2;
  const double spec = ks * (0.35 * c8 + pow32(crest));
  const double light = layout.light * falloff(lamp.dist2);
  return Rgb{light * (albedo.r * cosine + spec), light * (albedo.g * cosine + spec), light * (albedo.b * cosine + spec)};
}

Rgb Renderer::Impl::tissue_albedo(double sx, double sy, const TissueSample& t, std::uint8_t& label) const noexcept {
  const SceneLayout& s = layout;
  // Reddish mucosa, colour variation, fat patches, vessels.
  const double cv = t.colour;
  Rgb albedo{0.64 * (1.0 + 0.2 * cv), 0.17 * (1.0 + 0.35 * cv), 0.12 * (1.0 + 0.3 * cv)};
  albedo = mix(albedo, Rgb{0.70, 0.42, 0.24}, 0.55 * t.fat);
  const double vessel = t.vessel;
  albedo = per_channel(mix(albedo, Rgb{0.30, 0.025, 0.04}, 0.75 * vessel), s.tissue_tint);
  label = kLabelTissue;
  if (s.decoy) {
    const double dx = sx - s.decoy_x;
    const double dy = sy - s.decoy_y;
    const double d = std::sqrt(dx * dx + dy * dy);
    if (d < 1.3 * s.decoy_radius) {
      const double a = dmath::atan2(dy, dx);
      const double rim = s.decoy_radius * (1.0 + 0.15 * dmath::sin(2.0 * a + 1.0) + 0.08 * dmath::sin(5.0 * a));
      if (d < rim) {
        albedo = mix(albedo, s.decoy_albedo, 0.9);
        label = kLabelDecoy;
      }
    }
  }
  return albedo;
}

Rgb Renderer::Impl::shade_tissue(double x, double y, double plane, const TissueSample& t,
                                 std::uint8_t& label) const noexcept {
  const SceneLayout& s = layout;
  const double sx = x * plane;
  const double sy = y * plane;
  const double z = plane + s.bump_mm * t.height;
  const Vec3 point(x * z, y * z, z);
  // Height gradient on the surface (mm/mm): texture derivative rotated back.
  const double hu = s.bump_mm * t.height_du / kTexelMm;
  const double hv = s.bump_mm * t.height_dv / kTexelMm;
  const double gx = s.depth_mm * s.tilt_x / plane + s.tex_cos * hu + s.tex_sin * hv;
  const double gy = s.depth_mm * s.tilt_y / plane - s.tex_sin * hu + s.tex_cos * hv;
  Vec3 normal = Vec3(gx, gy, -1.0).normalized();
  const double dist2 = point.squaredNorm();
  const Vec3 view = -point / std::sqrt(dist2);

  const Rgb albedo = tissue_albedo(sx, sy, t, label);
  const LampView lamp = lamp_view(point, view, dist2);
  const double cosine = std::max(0.0, dot3(normal, lamp.to_lamp));
  const double crest = std::max(0.0, dot3(normal, lamp.half));
  Rgb c = albedo * cosine;
  double spec = 0.0;
  if (!s.clean) {
    // Wet spots: fine relief and a sharp lobe, only where the tissue is wet.
    const double wet = t.wet;
    if (wet > 0.0) {
      // Glints where the wet film's relief mirrors the lamp into the camera.
      const Vec3 wet_normal = Vec3(gx + 2.2 * t.wet_du, gy + 2.2 * t.wet_dv, -1.0).normalized();
      const double cw = std::max(0.0, dot3(wet_normal, lamp.half));
      const double c32 = pow32(cw);
      spec = 3.0 * wet * c32 * c32;
    }
    spec += 0.06 * pow32(crest);  // broad sheen of the mucosa
  }
  c = c + Rgb{spec, spec, spec};
  // A lamp beside the lens: the instrument's shadow on the tissue shows
  // beside it (lit then only by the scene's scattered light).
  const double shadow = !s.lamp_at_lens && shadowed(point, lamp) ? kShadowLight : 1.0;
  const double light = s.light * falloff(lamp.dist2) * shadow;
  c = c * light;
  if (s.reflection && s.reflection_strength > 0.0) {
    // Mirror image on the wet film: reflect the view ray about the smooth normal.
    const Vec3 d = -view;
    // The film smooths the relief: reflect about a gentler normal.
    const Vec3 film = Vec3(0.5 * (gx + s.depth_mm * s.tilt_x / plane), 0.5 * (gy + s.depth_mm * s.tilt_y / plane), -1.0).normalized();
    const Vec3 reflected = d - 2.0 * dot3(d, film) * film;
    const double wet = 0.4 + 0.6 * t.wet;
    {
      for (int k = 0; k < 2; ++k) {
        if (inst_count[k] == 0 || misses_sphere(point, reflected, inst_centre[k], inst_radius[k])) {
          continue;
        }
        Hit hit;
        hit.t = std::numeric_limits<double>::infinity();
        bool found = false;
        for (int i = inst_first[k]; i < inst_first[k] + inst_count[k]; ++i) {
          const Primitive& p = prims[i];
          if (misses_sphere(point, reflected, p.centre, p.bound_radius)) {
            continue;
          }
          if (intersect(p, point, reflected, 1e-3, hit.t, hit)) {
            hit.prim = i;
            found = true;
          }
        }
        if (found) {
          // Lit from the camera, seen along the reflected ray; the wet film
          // reflects a fraction (Fresnel-like) of it over the tissue.
          const Primitive& p = prims[hit.prim];
          const double d2 = hit.point.squaredNorm();
          const Vec3 to_light = -hit.point / std::sqrt(d2);
          const Vec3 half = (to_light - reflected).normalized();
          // The side facing the tissue is lit by the tissue's own scattered light.
          const double diffuse = std::max(0.0, dot3(hit.normal, to_light)) + 0.6;
          const double glint = pow32(std::max(0.0, dot3(hit.normal, half)));
          const Rgb a = materials.albedo[p.part];
          const double gain = s.light * falloff(d2);
          const double sheen = materials.specular[p.part] * glint;
          const Rgb mirrored{gain * (a.r * diffuse + sheen), gain * (a.g * diffuse + sheen), gain * (a.b * diffuse + sheen)};
          const double w = s.reflection_strength * wet;
          c = c * (1.0 - w) + mirrored * w;
          label = kLabelReflection;
        }
      }
    }
  }
  return c;
}

Rgb Renderer::Impl::shade_occluder(double x, double y) const noexcept {
  const SceneLayout& s = layout;
  const double dx = (x - s.occ_x) / s.occ_radius;
  const double dy = (y - s.occ_y) / s.occ_radius;
  const double r2 = std::min(1.0, dx * dx + dy * dy);
  const Vec3 normal = Vec3(0.8 * dx, 0.8 * dy, -std::sqrt(1.0 - 0.64 * r2)).normalized();
  const Vec3 point(x * s.occ_depth, y * s.occ_depth, s.occ_depth);
  const double dist2 = point.squaredNorm();
  const Vec3 view = -point / std::sqrt(dist2);
  const LampView lamp = lamp_view(point, view, dist2);
  const double cosine = std::max(0.0, dot3(normal, lamp.to_lamp));
  const double crest = std::max(0.0, dot3(normal, lamp.half));
  Rgb albedo;
  double ks = 0.0;
  if (s.occ_blood) {
    albedo = Rgb{0.022, 0.0025, 0.003};
    ks = 0.6;
  } else {
    const double u = x * s.occ_depth / kTexelMm * 1.3 + 200.0;
    const double v = y * s.occ_depth / kTexelMm * 1.3 + 100.0;
    const TissueSample t = sample_tissue(u, v);
    const double cv = t.colour;
    albedo = Rgb{0.16 * (1.0 + 0.25 * cv), 0.035 * (1.0 + 0.4 * cv), 0.03};
    albedo = mix(albedo, Rgb{0.08, 0.008, 0.012}, 0.8 * t.vessel);
    ks = 0.3;
  }
  // Darker towards the rim (the flap curls away from the light).
  const double rim = 1.0 - 0.6 * r2 * r2;
  const double spec = ks * pow32(crest);
  const double light = s.light * falloff(lamp.dist2) * rim;
  return Rgb{light * (albedo.r * cosine + spec), light * (albedo.g * cosine + spec), light * (albedo.b * cosine + spec)};
}

Rgb Renderer::Impl::apply_haze(const Rgb& c, double depth, double x, double y) const noexcept {
  const SceneLayout& s = layout;
  const double u = x * 60.0 / kTexelMm + 301.0;
  const double v = y * 60.0 / kTexelMm + 17.0;
  // Patchy: smoke drifts in wisps.
  const double wisps = smoothstep(-0.4, 0.5, sample_tissue(u * 0.7, v * 0.7).height);
  const double density = s.haze_density * (0.2 + 1.6 * wisps);
  const double f = 1.0 - dmath::exp(-density * depth);
  return mix(c, s.haze_radiance, f);
}

Sample Renderer::Impl::shade(double x, double y, const std::uint16_t* candidates, int candidate_count) const noexcept {
  Sample out;
  const Vec3 d(x, y, 1.0);
  const SceneLayout& s = layout;
  const double plane = s.depth_mm * (1.0 + s.tilt_x * x + s.tilt_y * y);
  const double u = (s.tex_cos * x - s.tex_sin * y) * plane / kTexelMm + s.tex_u0;
  const double v = (s.tex_sin * x + s.tex_cos * y) * plane / kTexelMm + s.tex_v0;
  const TissueSample t = sample_tissue(u, v);
  const double tissue_z = plane + s.bump_mm * t.height;
  double occluder_z = std::numeric_limits<double>::infinity();
  if (in_occluder(x, y)) {
    occluder_z = layout.occ_depth;
  }
  Hit hit;
  const double limit = std::min(tissue_z, occluder_z);
  double depth = 0.0;
  if (candidate_count > 0 && nearest_instrument_hit(Vec3::Zero(), d, limit, hit, candidates, candidate_count)) {
    out.colour = shade_instrument(hit);
    const Primitive& p = prims[hit.prim];
    out.label = static_cast<std::uint8_t>(kLabelInstrument + 8 * p.instrument + p.part);
    out.instrument = true;
    depth = hit.t;
  } else if (occluder_z < tissue_z) {
    out.colour = shade_occluder(x, y);
    out.label = kLabelOccluder;
    depth = occluder_z;
  } else {
    out.colour = shade_tissue(x, y, plane, t, out.label);
    depth = tissue_z;
  }
  if (layout.haze) {
    out.colour = apply_haze(out.colour, depth * std::sqrt(1.0 + x * x + y * y), x, y);
  }
  return out;
}

void Renderer::Impl::make_layout(const SceneSpec& scene, const GroundTruth& truth) noexcept {
  SceneLayout& s = layout;
  s = SceneLayout{};
  const std::uint64_t world = (scene.world_seed != 0U) ? scene.world_seed : scene.seed;
  Random rng(world, 1U);
  // The instrument's farthest visible part: the tissue stays behind it.
  double far_z = 0.0;
  for (int k = 0; k < truth.instrument_count; ++k) {
    for (int i = inst_first[k]; i < inst_first[k] + inst_count[k]; ++i) {
      far_z = std::max(far_z, std::max(prims[i].p0.z(), prims[i].p1.z()));
    }
  }
  s.depth_mm = (scene.tissue_depth_mm > 0.0) ? scene.tissue_depth_mm : rng.uniform(40.0, 90.0);
  if (scene.tissue_depth_mm <= 0.0) {
    s.depth_mm = std::min(90.0, std::max(s.depth_mm, far_z + 12.0));
    if ((scene.hard_cases & kHardReflection) != 0U) {
      // A mirror image needs the wet surface close behind the instrument.
      s.depth_mm = std::min(90.0, std::max(40.0, far_z + 8.0));
    }
  }
  s.tilt_x = rng.uniform(-0.25, 0.25);
  s.tilt_y = rng.uniform(-0.25, 0.25);
  s.bump_mm = rng.uniform(2.0, 6.0);
  const double angle = rng.uniform(0.0, 6.283185307179586);
  s.tex_cos = dmath::cos(angle);
  s.tex_sin = dmath::sin(angle);
  s.tex_u0 = rng.uniform(0.0, kTexSize);
  s.tex_v0 = rng.uniform(0.0, kTexSize);
  s.clean = scene.clean;
  // Light: auto-exposure-like, tissue at its mean depth near mid grey.
  s.light = scene.exposure * 0.55 * s.depth_mm * s.depth_mm;
  s.noise_sigma = scene.clean ? 0.0 : scene.noise_sigma;
  s.blur_sigma = scene.clean ? 0.0 : scene.blur_sigma_px;
  s.vignetting = scene.clean ? 0.0 : scene.vignetting;
  s.tissue_tint = Rgb{scene.appearance.tissue_tint[0], scene.appearance.tissue_tint[1], scene.appearance.tissue_tint[2]};
  s.white_balance = scene.appearance.white_balance;
  s.lamp = Vec3(scene.appearance.lamp_offset_mm[0], scene.appearance.lamp_offset_mm[1], 0.0);
  s.lamp_at_lens = scene.appearance.lamp_offset_mm[0] == 0.0 && scene.appearance.lamp_offset_mm[1] == 0.0;
  set_materials(scene.appearance);

  const std::uint32_t hard = scene.hard_cases;
  Random hard_rng(world, 2U);
  // A point of the first instrument's bending section, for placing things.
  const auto& g = model.geometry();
  const solver::PoseFrames f = model.frames(scene.r);
  const double s_pick = hard_rng.uniform(0.25, 0.95) * g.bend_length_mm;
  const Vec3 anchor = model.centreline(f, s_pick).position;
  const bool anchor_ok = anchor.z() > 5.0;
  if ((hard & kHardReflection) != 0U) {
    s.reflection = true;
    s.reflection_strength = hard_rng.uniform(0.45, 0.7);
  }
  if ((hard & kHardOccluder) != 0U && anchor_ok) {
    s.occluder = true;
    s.occ_depth = std::max(3.0, anchor.z() - hard_rng.uniform(3.0, 8.0));
    const double offset = hard_rng.uniform(-1.5, 1.5) / anchor.z();
    s.occ_x = anchor.x() / anchor.z() + offset;
    s.occ_y = anchor.y() / anchor.z() + hard_rng.uniform(-1.5, 1.5) / anchor.z();
    s.occ_radius = hard_rng.uniform(2.5, 5.0) / anchor.z();  // 2.5-5 mm at the instrument's depth
    s.occ_p1 = hard_rng.uniform(0.0, 6.28);
    s.occ_p2 = hard_rng.uniform(0.0, 6.28);
    s.occ_blood = hard_rng.uniform() < 0.5;
  }
  if ((hard & kHardDecoy) != 0U) {
    s.decoy = true;
    const Vec3 tcp = model.tcp(scene.r);
    double cx = 0.0;
    double cy = 0.0;
    if (tcp.z() > 1.0) {
      cx = tcp.x() / tcp.z();
      cy = tcp.y() / tcp.z();
    }
    const double a = hard_rng.uniform(0.0, 6.283185307179586);
    const double dist = hard_rng.uniform(0.15, 0.35);
    const double nx = cx + dist * dmath::cos(a);
    const double ny = cy + dist * dmath::sin(a);
    const double plane = s.depth_mm * (1.0 + s.tilt_x * nx + s.tilt_y * ny);
    s.decoy_x = nx * plane;
    s.decoy_y = ny * plane;
    s.decoy_radius = hard_rng.uniform(2.0, 4.5);
    s.decoy_albedo = (hard_rng.uniform() < 0.5) ? Rgb{0.03, 0.12, 0.45} : Rgb{0.62, 0.52, 0.05};
  }
  if ((hard & kHardHaze) != 0U) {
    s.haze = true;
    s.haze_density = hard_rng.uniform(0.0025, 0.006);
    const double level = hard_rng.uniform(0.3, 0.5);
    s.haze_radiance = Rgb{level, level * 0.93, level * 0.9};
  }
  if ((hard & kHardNoise) != 0U && !scene.clean) {
    s.noise_sigma = 4.0 * std::max(scene.noise_sigma, 1.5);
  }
  if ((hard & kHardMotionBlur) != 0U) {
    s.motion_blur = true;
    const double a = hard_rng.uniform(0.0, 6.283185307179586);
    const double len = hard_rng.uniform(5.0, 14.0);
    s.blur_dx = len * dmath::cos(a);
    s.blur_dy = len * dmath::sin(a);
  }
}

void Renderer::Impl::compute_truth(const SceneSpec& scene, GroundTruth& truth) noexcept {
  truth.hard_cases = scene.hard_cases;
  truth.seed = scene.seed;
  truth.tissue_depth_mm = layout.depth_mm;
  for (int k = 0; k < truth.instrument_count; ++k) {
    InstrumentTruth& it = truth.instruments[static_cast<std::size_t>(k)];
    const PoseVector& r = (k == 0) ? scene.r : scene.r2;
    solver::CornerSet corners;
    model.corners(camera, r, corners);
    it.r = r;
    it.tcp = corners.tcp;
    it.corners = corners.pixel;
    it.corner_points = corners.point;
    it.present = corners.present;
    it.in_image = corners.in_image;
    it.corners_in_image = corners.count_in_image();
    it.corners_visible = 0;
    for (int c = 0; c < kNumCorners; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      it.visible[cu] = false;
      if (!it.in_image[cu]) {
        continue;
      }
      const Vec3& p = it.corner_points[cu];
      const Vec3 d(p.x() / p.z(), p.y() / p.z(), 1.0);
      bool hidden = tissue_depth(d.x(), d.y()) < p.z();
      hidden = hidden || (in_occluder(d.x(), d.y()) && layout.occ_depth < p.z());
      for (int i = 0; i < prim_count && !hidden; ++i) {
        Hit hit;
        if (intersect(prims[i], Vec3::Zero(), d, 1e-6, p.z(), hit) &&
            (hit.point - p).norm() > kVisibilityToleranceMm) {
          hidden = true;
        }
      }
      it.visible[cu] = !hidden;
      it.corners_visible += hidden ? 0 : 1;
    }
    // View status from the geometry: any part in front of the camera, any
    // centreline sample inside the image.
    const solver::PoseFrames f = model.frames(r);
    const auto& g = model.geometry();
    bool in_front = false;
    bool in_view = false;
    constexpr int kSamples = 24;
    for (int i = 0; i <= kSamples; ++i) {
      // Samples over shaft (first third), bending section, grasper.
      Vec3 point;
      const double t = static_cast<double>(i) / kSamples;
      if (t < 0.34) {
        point = f.channel_origin + (t / 0.34) * r[solver::kLambda] * f.channel_rotation.col(2);
      } else if (t < 0.8) {
        point = model.centreline(f, (t - 0.34) / 0.46 * g.bend_length_mm).position;
      } else {
        const solver::CentrelineFrame end = model.centreline(f, g.bend_length_mm);
        point = end.position + (t - 0.8) / 0.2 * g.tcp_offset_mm * end.tangent;
      }
      if (point.z() > 0.5) {
        in_front = true;
        Vec2 px;
        if (camera.project(point, px) && px.x() > -20.0 && px.y() > -20.0 && px.x() < camera.width() + 19.0 &&
            px.y() < camera.height() + 19.0) {
          in_view = true;
        }
      }
    }
    it.view = in_view ? InstrumentView::Visible : (in_front ? InstrumentView::OutOfView : InstrumentView::BehindCamera);
  }
}

// Motion blur: a symmetric streak of the linear image `src` into `dst`.
void Renderer::Impl::apply_motion_blur(const float* src, float* dst) const noexcept {
  const SceneLayout& s = layout;
  const int w = width;
  const int h = height;
  constexpr int kMaxSteps = 32;
  const int steps = std::min(kMaxSteps, std::max(2, static_cast<int>(std::ceil(dmath::hypot(s.blur_dx, s.blur_dy)))));
  int off_x[kMaxSteps + 1];
  int off_y[kMaxSteps + 1];
  int reach_x = 0;
  int reach_y = 0;
  for (int i = 0; i <= steps; ++i) {
    const double f = static_cast<double>(i) / steps - 0.5;
    off_x[i] = static_cast<int>(std::lround(f * s.blur_dx));
    off_y[i] = static_cast<int>(std::lround(f * s.blur_dy));
    reach_x = std::max(reach_x, std::abs(off_x[i]));
    reach_y = std::max(reach_y, std::abs(off_y[i]));
  }
  const float inv = 1.0F / static_cast<float>(steps + 1);
  for (int y = 0; y < h; ++y) {
    const bool inner_row = y >= reach_y && y < h - reach_y;
    for (int x = 0; x < w; ++x) {
      const bool inner = inner_row && x >= reach_x && x < w - reach_x;
      float acc0 = 0.0F;
      float acc1 = 0.0F;
      float acc2 = 0.0F;
      for (int i = 0; i <= steps; ++i) {
        int sx = x + off_x[i];
        int sy = y + off_y[i];
        if (!inner) {  // clamp at the borders only
          sx = std::min(w - 1, std::max(0, sx));
          sy = std::min(h - 1, std::max(0, sy));
        }
        const float* p = &src[3U * (static_cast<std::size_t>(sy) * static_cast<std::size_t>(w) + static_cast<std::size_t>(sx))];
        acc0 += p[0];
        acc1 += p[1];
        acc2 += p[2];
      }
      float* q = &dst[3U * (static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x))];
      q[0] = acc0 * inv;
      q[1] = acc1 * inv;
      q[2] = acc2 * inv;
    }
  }
}

// Slight optical blur of the linear image in place: separable 3-tap Gaussian
// (rows into `tmp`, then columns back).
void Renderer::Impl::apply_optical_blur(float* image, float* tmp) const noexcept {
  const int w = width;
  const int h = height;
  const auto side = static_cast<float>(dmath::exp(-1.0 / (2.0 * layout.blur_sigma * layout.blur_sigma)));
  const float norm = 1.0F / (1.0F + 2.0F * side);
  const float wc = norm;
  const float ws = side * norm;
  for (int y = 0; y < h; ++y) {
    const float* row = &image[3U * static_cast<std::size_t>(y) * static_cast<std::size_t>(w)];
    float* dst = &tmp[3U * static_cast<std::size_t>(y) * static_cast<std::size_t>(w)];
    for (int x = 0; x < w; ++x) {
      const int xl = std::max(0, x - 1);
      const int xr = std::min(w - 1, x + 1);
      for (int c = 0; c < 3; ++c) {
        dst[3 * x + c] = wc * row[3 * x + c] + ws * (row[3 * xl + c] + row[3 * xr + c]);
      }
    }
  }
  for (int y = 0; y < h; ++y) {
    const int yu = std::max(0, y - 1);
    const int yd = std::min(h - 1, y + 1);
    const float* r0 = &tmp[3U * static_cast<std::size_t>(yu) * static_cast<std::size_t>(w)];
    const float* r1 = &tmp[3U * static_cast<std::size_t>(y) * static_cast<std::size_t>(w)];
    const float* r2 = &tmp[3U * static_cast<std::size_t>(yd) * static_cast<std::size_t>(w)];
    float* dst = &image[3U * static_cast<std::size_t>(y) * static_cast<std::size_t>(w)];
    for (int i = 0; i < 3 * w; ++i) {
      dst[i] = wc * r1[i] + ws * (r0[i] + r2[i]);
    }
  }
}

// Vignetting, tone curve and gamma, noise, 8-bit saturation: the linear
// image `src` to the output frame.
void Renderer::Impl::tone_map(const SceneSpec& scene, const float* src, const MutableImageView& out) const noexcept {
  const SceneLayout& s = layout;
  const int w = width;
  const int h = height;
  const auto& k = camera.intrinsics();
  const double lut_scale = kToneLutSize / 4.0;
  for (int y = 0; y < h; ++y) {
    Random rng(scene.seed, 1000U + static_cast<std::uint64_t>(y));
    std::uint8_t* dst = out.row(y);
    const float* row = &src[3U * static_cast<std::size_t>(y) * static_cast<std::size_t>(w)];
    const double dy = (y - k.cy);
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
      std::uint8_t* px = dst + 3U * static_cast<std::size_t>(x);
      if (labels[i] == kLabelNoRay) {
        px[0] = 0U;
        px[1] = 0U;
        px[2] = 0U;
        continue;
      }
      const double dx = (x - k.cx);
      const double rho2 = (dx * dx + dy * dy) / max_radius2;
      const double vig = 1.0 - s.vignetting * rho2 * (0.6 + 0.4 * rho2);
      const std::uint64_t bits = (s.noise_sigma > 0.0) ? rng.next() : 0U;
      for (int c = 0; c < 3; ++c) {
        const double lin =
            std::max(0.0, static_cast<double>(row[3 * x + c]) * vig * s.white_balance[static_cast<std::size_t>(c)]);
        const double pos = std::min(static_cast<double>(kToneLutSize), lin * lut_scale);
        const auto idx = static_cast<int>(pos);
        const double frac = pos - idx;
        const auto lo = static_cast<double>(tone[idx]);
        const auto hi = static_cast<double>(tone[std::min(idx + 1, kToneLutSize)]);
        double level = lo + (hi - lo) * frac;
        if (s.noise_sigma > 0.0) {
          const auto g = static_cast<std::size_t>((bits >> (16U * static_cast<unsigned>(c))) & (kGaussTableSize - 1U));
          level += s.noise_sigma * (0.6 + 0.4 * level / 128.0) * static_cast<double>(gauss[g]);
        }
        const double q = std::floor(level + 0.5);
        px[c] = static_cast<std::uint8_t>(q < 0.0 ? 0.0 : (q > 255.0 ? 255.0 : q));
      }
    }
  }
}

void Renderer::Impl::post_process(const SceneSpec& scene, const MutableImageView& out) noexcept {
  float* src = linear.get();
  float* tmp = scratch.get();
  // Motion blur: a symmetric streak (the ground truth is mid-exposure).
  if (layout.motion_blur) {
    apply_motion_blur(src, tmp);
    std::swap(src, tmp);
  }
  // Slight optical blur: separable 3-tap Gaussian.
  if (layout.blur_sigma > 0.0) {
    apply_optical_blur(src, tmp);
  }
  // Vignetting, tone curve and gamma, noise, 8-bit saturation.
  tone_map(scene, src, out);
}

Renderer::Renderer(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
Renderer::~Renderer() = default;

const solver::CameraModel& Renderer::camera() const noexcept { return impl_->camera; }
const solver::InstrumentModel& Renderer::instrument() const noexcept { return impl_->model; }
const std::uint8_t* Renderer::labels() const noexcept { return impl_->labels.get(); }

PoseVector Renderer::mirrored_nominal_pose(double lambda_mm, double phi_rad, double theta_rad) const noexcept {
  const auto& g = impl_->model.geometry();
  PoseVector r;
  r << -g.nominal_x_ch_mm, g.nominal_y_ch_mm, -g.nominal_psi_rad, g.nominal_mu_rad, lambda_mm, phi_rad, theta_rad;
  return r;
}

Result<std::unique_ptr<Renderer>, RenderError> Renderer::create(const solver::CameraModel& camera,
                                                                const solver::InstrumentModel& instrument,
                                                                const RenderSettings& settings) noexcept {
  using R = Result<std::unique_ptr<Renderer>, RenderError>;
  if (settings.supersample < 1 || settings.supersample > 8 || settings.segments_per_stripe < 2 ||
      settings.segments_per_stripe > kMaxSegmentsPerStripe) {
    return R::failure(RenderError::BadSettings);
  }
  if (camera.width() <= 0 || camera.height() <= 0) {
    return R::failure(RenderError::BadImage);
  }
  if (static_cast<long>(camera.width()) * camera.height() > kMaxPixels) {
    return R::failure(RenderError::ImageTooLarge);
  }
  std::unique_ptr<Impl> impl(new (std::nothrow) Impl());
  if (!impl) {
    return R::failure(RenderError::OutOfMemory);
  }
  impl->camera = camera;
  impl->model = instrument;
  impl->settings = settings;
  impl->width = camera.width();
  impl->height = camera.height();
  impl->pixels = static_cast<std::size_t>(impl->width) * static_cast<std::size_t>(impl->height);
  if (!impl->allocate()) {
    return R::failure(RenderError::OutOfMemory);
  }
  impl->build_rays();
  impl->bake_textures();
  std::unique_ptr<Renderer> renderer(new (std::nothrow) Renderer(std::move(impl)));
  if (!renderer) {
    return R::failure(RenderError::OutOfMemory);
  }
  return R::success(std::move(renderer));
}

bool valid_appearance(const Appearance& a) noexcept {
  const auto within = [](double v, double lo, double hi) noexcept { return std::isfinite(v) && v >= lo && v <= hi; };
  bool ok = within(a.stripe_gloss, 0.0, 4.0) && within(a.shaft_gloss, 0.0, 4.0) && within(a.grasper_gloss, 0.0, 4.0);
  for (std::size_t c = 0U; c < 3U; ++c) {
    ok = ok && within(a.blue_albedo[c], 0.0, 1.0) && within(a.yellow_albedo[c], 0.0, 1.0) &&
         within(a.shaft_albedo[c], 0.0, 1.0) && within(a.grasper_albedo[c], 0.0, 1.0) &&
         within(a.tissue_tint[c], 0.25, 4.0) && within(a.white_balance[c], 0.25, 4.0);
  }
  return ok && within(a.shaft_radius_scale, 0.5, 1.5) && within(a.grasper_radius_scale, 0.5, 1.5) &&
         within(a.lamp_offset_mm[0], -10.0, 10.0) && within(a.lamp_offset_mm[1], -10.0, 10.0);
}

namespace {
bool finite_scene(const SceneSpec& scene) noexcept {
  const double values[] = {scene.noise_sigma, scene.blur_sigma_px, scene.vignetting, scene.exposure,
                           scene.tissue_depth_mm};
  for (double v : values) {
    if (!std::isfinite(v)) {
      return false;
    }
  }
  return valid_appearance(scene.appearance) && scene.r.allFinite() &&
         (!scene.second_instrument || scene.r2.allFinite()) && scene.noise_sigma >= 0.0 &&
         scene.blur_sigma_px >= 0.0 && scene.blur_sigma_px <= 3.0 && scene.vignetting >= 0.0 &&
         scene.vignetting <= 1.0 && scene.exposure > 0.0 && scene.tissue_depth_mm >= 0.0 &&
         scene.tissue_depth_mm < 1000.0;
}
}  // namespace

Status<RenderError> Renderer::ground_truth(const SceneSpec& scene, GroundTruth& truth) noexcept {
  if (!finite_scene(scene)) {
    return Status<RenderError>::failure(RenderError::BadScene);
  }
  Impl& m = *impl_;
  m.prim_count = 0;
  m.inst_count[1] = 0;
  const auto& g = m.model.geometry();
  m.shaft_radius_mm = g.shaft_radius_mm * scene.appearance.shaft_radius_scale;
  m.grasper_radius_mm = g.grasper_radius_mm * scene.appearance.grasper_radius_scale;
  m.build_instrument(scene.r, 0U);
  truth.instrument_count = 1;
  if (scene.second_instrument) {
    m.build_instrument(scene.r2, 1U);
    truth.instrument_count = 2;
  }
  m.make_layout(scene, truth);
  m.compute_truth(scene, truth);
  truth.motion_blur_dx_px = m.layout.motion_blur ? m.layout.blur_dx : 0.0;
  truth.motion_blur_dy_px = m.layout.motion_blur ? m.layout.blur_dy : 0.0;
  return ok_status<RenderError>();
}

// Pass 1 of a render: one sample at every pixel centre, tile by tile; counts
// each instrument's pixels into instrument_pixels[2].
void Renderer::Impl::shade_pixel_centres(float* coverage, long* instrument_pixels) noexcept {
  const int w = width;
  const int h = height;
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const std::size_t tile = static_cast<std::size_t>(ty) * static_cast<std::size_t>(tiles_x) + static_cast<std::size_t>(tx);
      const std::uint16_t* list = &tile_prims[tile * kMaxPrims];
      const int count = tile_count[tile];
      const int y1 = std::min(h, (ty + 1) * kTileSize);
      const int x1 = std::min(w, (tx + 1) * kTileSize);
      for (int y = ty * kTileSize; y < y1; ++y) {
        for (int x = tx * kTileSize; x < x1; ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
          const auto rx = static_cast<double>(ray_x[i]);
          float* px = &linear[3U * i];
          if (std::isnan(rx)) {
            labels[i] = kLabelNoRay;
            px[0] = px[1] = px[2] = 0.0F;
            if (coverage != nullptr) {
              coverage[i] = 0.0F;
            }
            continue;
          }
          const Sample sample = shade(rx, static_cast<double>(ray_y[i]), list, count);
          labels[i] = sample.label;
          if (sample.instrument) {
            ++instrument_pixels[(sample.label - kLabelInstrument) / 8];
          }
          px[0] = static_cast<float>(sample.colour.r);
          px[1] = static_cast<float>(sample.colour.g);
          px[2] = static_cast<float>(sample.colour.b);
          if (coverage != nullptr) {
            coverage[i] = sample.instrument ? 1.0F : 0.0F;
          }
        }
      }
    }
  }
}

// Whether a pixel of `label` has a neighbour (8-connected) of another label.
bool Renderer::Impl::on_label_edge(int x, int y, std::uint8_t label) const noexcept {
  const int w = width;
  const int h = height;
  for (int dy = -1; dy <= 1; ++dy) {
    const int yy = y + dy;
    if (yy < 0 || yy >= h) {
      continue;
    }
    for (int dx = -1; dx <= 1; ++dx) {
      const int xx = x + dx;
      if (xx < 0 || xx >= w) {
        continue;
      }
      if (labels[static_cast<std::size_t>(yy) * static_cast<std::size_t>(w) + static_cast<std::size_t>(xx)] != label) {
        return true;
      }
    }
  }
  return false;
}

// The ray of pixel (x, y), which must have one, and how it changes from
// pixel to pixel in x and in y.
RayFootprint Renderer::Impl::ray_footprint(int x, int y) const noexcept {
  const int w = width;
  const int h = height;
  // Ray derivatives per pixel (central where possible).
  auto ray_at = [this, w](int xx, int yy, double& rx, double& ry) {
    const std::size_t j = static_cast<std::size_t>(yy) * static_cast<std::size_t>(w) + static_cast<std::size_t>(xx);
    rx = static_cast<double>(ray_x[j]);
    ry = static_cast<double>(ray_y[j]);
    return !std::isnan(rx);
  };
  RayFootprint f;
  static_cast<void>(ray_at(x, y, f.cx, f.cy));  // valid: only pixels whose label is not kLabelNoRay come here
  double ax = 0.0;
  double ay = 0.0;
  double bx = 0.0;
  double by = 0.0;
  const bool l = x > 0 && ray_at(x - 1, y, ax, ay);
  const bool r = x + 1 < w && ray_at(x + 1, y, bx, by);
  if (l && r) {
    f.gxx = 0.5 * (bx - ax);
    f.gxy = 0.5 * (by - ay);
  } else if (r) {
    f.gxx = bx - f.cx;
    f.gxy = by - f.cy;
  } else if (l) {
    f.gxx = f.cx - ax;
    f.gxy = f.cy - ay;
  }
  const bool u = y > 0 && ray_at(x, y - 1, ax, ay);
  const bool dn = y + 1 < h && ray_at(x, y + 1, bx, by);
  if (u && dn) {
    f.gyx = 0.5 * (bx - ax);
    f.gyy = 0.5 * (by - ay);
  } else if (dn) {
    f.gyx = bx - f.cx;
    f.gyy = by - f.cy;
  } else if (u) {
    f.gyx = f.cx - ax;
    f.gyy = f.cy - ay;
  }
  return f;
}

// Replaces pixel (x, y)'s colour (and coverage) by the mean of n x n samples
// over its footprint, n = settings.supersample.
void Renderer::Impl::supersample_pixel(int x, int y, float* coverage) noexcept {
  const int n = settings.supersample;
  const double inv_n = 1.0 / n;
  const RayFootprint f = ray_footprint(x, y);
  const std::size_t tile = static_cast<std::size_t>(y / kTileSize) * static_cast<std::size_t>(tiles_x) +
                           static_cast<std::size_t>(x / kTileSize);
  const std::uint16_t* list = &tile_prims[tile * kMaxPrims];
  const int count = tile_count[tile];
  Rgb acc;
  int covered = 0;
  for (int sy = 0; sy < n; ++sy) {
    const double oy = (sy + 0.5) * inv_n - 0.5;
    for (int sx = 0; sx < n; ++sx) {
      const double ox = (sx + 0.5) * inv_n - 0.5;
      const Sample sample = shade(f.cx + ox * f.gxx + oy * f.gyx, f.cy + ox * f.gxy + oy * f.gyy, list, count);
      acc = acc + sample.colour;
      covered += sample.instrument ? 1 : 0;
    }
  }
  const double inv = 1.0 / (n * n);
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  float* px = &linear[3U * i];
  px[0] = static_cast<float>(acc.r * inv);
  px[1] = static_cast<float>(acc.g * inv);
  px[2] = static_cast<float>(acc.b * inv);
  if (coverage != nullptr) {
    coverage[i] = static_cast<float>(covered * inv);
  }
}

// Pass 2 of a render: pixels whose neighbourhood changes label are supersampled.
void Renderer::Impl::supersample_edges(float* coverage) noexcept {
  const int w = width;
  const int h = height;
  const int n = settings.supersample;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
      const std::uint8_t label = labels[i];
      if (label == kLabelNoRay || n == 1) {
        continue;
      }
      if (!on_label_edge(x, y, label)) {
        continue;
      }
      supersample_pixel(x, y, coverage);
    }
  }
}

Status<RenderError> Renderer::render(const SceneSpec& scene, MutableImageView out, GroundTruth& truth,
                                     float* coverage) noexcept {
  Impl& m = *impl_;
  if (!out.valid() || out.width != m.width || out.height != m.height) {
    return Status<RenderError>::failure(RenderError::BadImage);
  }
  const auto status = ground_truth(scene, truth);
  if (!status.ok()) {
    return status;
  }
  m.bin_tiles();
  // Pass 1: one sample at every pixel centre.
  long instrument_pixels[2] = {0, 0};
  m.shade_pixel_centres(coverage, instrument_pixels);
  // Pass 2: pixels whose neighbourhood changes label are supersampled.
  m.supersample_edges(coverage);
  // An instrument the geometry placed in view but no pixel shows is out of view.
  for (int k = 0; k < truth.instrument_count; ++k) {
    InstrumentTruth& it = truth.instruments[static_cast<std::size_t>(k)];
    if (it.view == InstrumentView::Visible && instrument_pixels[k] == 0) {
      it.view = InstrumentView::OutOfView;
    }
  }
  m.post_process(scene, out);
  return ok_status<RenderError>();
}

}  // namespace render
}  // namespace tcpest
