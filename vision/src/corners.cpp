// Stage 4: the apparent corners (corners.hpp; the paper's section 2.3).
#include <algorithm>
#include <cmath>
#include <new>

#include "bezier_fit.hpp"
#include "boundary_arc.hpp"
#include "profile_crossing.hpp"
#include "sampling.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/vision/corners.hpp"

namespace tcpest {
namespace vision {
namespace {

using detail::best_crossing;
using detail::fit_bezier;
using detail::fit_boundary_arc;
using detail::nearest_t;
using detail::Rgb;
using detail::sample;
using detail::to_byte;

// Stage 4's profiles run along each border over t in [kProfileT0,
// kProfileT1]: a little past both ends of the fitted curve.
constexpr double kProfileT0 = -0.08;
constexpr double kProfileT1 = 1.08;

using ProfileRows = std::array<std::array<double, kMaxProfileSamples>, kProfileInsets>;
using ProfileValid = std::array<std::array<bool, kMaxProfileSamples>, kProfileInsets>;

// The colour of marker m (0-based) of the interpretation: its region's.
PixelClass marker_class(const Interpretation& in, int m) noexcept {
  return in.markers[static_cast<std::size_t>(m)].region.cls;
}

// The markers' mean half width across the tube (px) at the insets' depth:
// 0.866 of the found regions' half minor axes (5 px without one).
double inset_half_width_px(const Interpretation& in) noexcept {
  double half_width = 0.0;
  int width_count = 0;
  for (int m = in.first_marker; m <= in.last_marker; ++m) {
    const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
    if (obs.found) {
      half_width += obs.region.half_minor * 0.866;
      ++width_count;
    }
  }
  return width_count > 0 ? half_width / width_count : 5.0;
}

// What stage 4 reads its boundaries' changes on: per side and inset (px
// inside the border) the yellow-minus-blue score and the blue margin at
// `samples` points dt apart, and each marker's parameter on each border.
struct CornerProfiles {
  const std::array<ProfileRows, 2>& score;
  const std::array<ProfileRows, 2>& margin;
  const std::array<ProfileValid, 2>& valid;
  std::array<double, kProfileInsets> insets{};
  std::array<std::array<double, kNumMarkers>, 2> marker_t{};
  int samples = 0;
  double dt = 0.0;
};

// The profiles along one border (CornerProfiles), each point `inset` px
// inside it along its normal; invalid where the image has no sample.
void sample_border_profiles(const ImageView& image, const ColorModel& colors, const Border& border, std::size_t side,
                            const std::array<double, kProfileInsets>& insets, int samples, double dt,
                            ProfileRows& score, ProfileRows& margin, ProfileValid& valid) noexcept {
  for (int i = 0; i < samples; ++i) {
    const double t = kProfileT0 + dt * static_cast<double>(i);
    const Point p = border.curve.at(t);
    const Point d = border.curve.derivative(t);
    const double dl = dmath::hypot(d.x, d.y);
    // Outward normal: side 1's is (-dy, dx), side 0's the opposite.
    const double sign = side == 1U ? 1.0 : -1.0;
    const double nx = dl > 0.0 ? sign * (-d.y / dl) : 0.0;
    const double ny = dl > 0.0 ? sign * (d.x / dl) : 0.0;
    for (std::size_t q = 0U; q < kProfileInsets; ++q) {
      const auto at = static_cast<std::size_t>(i);
      valid[q][at] = false;
      score[q][at] = 0.0;  // not a previous frame's value (no reader takes it: valid is false)
      margin[q][at] = 0.0;
      Rgb px;
      if (!(dl > 0.0) || !sample(image, p.x - insets[q] * nx, p.y - insets[q] * ny, px)) {
        continue;
      }
      const std::uint8_t r8 = to_byte(px.r), g8 = to_byte(px.g), b8 = to_byte(px.b);
      score[q][at] = colors.yellow_minus_blue(r8, g8, b8);
      margin[q][at] = colors.blue_margin(r8, g8, b8);
      valid[q][at] = true;
    }
  }
}

// Each marker's parameter on the border: the profile point nearest to its
// region's centroid.
void marker_params(const Interpretation& in, const Border& border, int samples, double dt,
                   std::array<double, kNumMarkers>& marker_t) noexcept {
  for (int m = in.first_marker; m <= in.last_marker; ++m) {
    const MarkerObservation& obs = in.markers[static_cast<std::size_t>(m)];
    double best = 1e30;
    for (int i = 0; i < samples; ++i) {
      const double t = kProfileT0 + dt * static_cast<double>(i);
      const Point p = border.curve.at(t);
      const double dd = dmath::hypot(p.x - obs.region.centroid.x, p.y - obs.region.centroid.y);
      if (dd < best) {
        best = dd;
        marker_t[static_cast<std::size_t>(m)] = t;
      }
    }
  }
}

// How boundary j (between markers j-1 and j, 0-based) shows along the
// borders: an internal one as the yellow-minus-blue score's change, an end
// one as its blue marker's margin's; want_sign: the change's sign from base
// to tip. False at an end marker that is not blue (no margin profile). The
// markers first_marker..last_marker are all found (stage 2 labels a chain).
bool boundary_change(const Interpretation& in, int j, bool& use_margin, double& want_sign) noexcept {
  const bool internal = j > in.first_marker && j <= in.last_marker;
  use_margin = false;
  if (internal) {
    want_sign = marker_class(in, j - 1) == PixelClass::Blue ? 1.0 : -1.0;
    return true;
  }
  const int m = (j == in.first_marker) ? j : j - 1;
  if (marker_class(in, m) != PixelClass::Blue) {
    return false;
  }
  use_margin = true;
  want_sign = (j == in.first_marker) ? 1.0 : -1.0;
  return true;
}

// The border parameters [t_lo, t_hi] where boundary j's change is looked
// for: between its two markers and a quarter of a marker's span beyond; at
// an end, 1.2 spans outwards from the end marker.
void crossing_window(const Interpretation& in, const std::array<double, kNumMarkers>& mt, int j, double& t_lo,
                     double& t_hi) noexcept {
  double span = 0.3;
  if (in.last_marker > in.first_marker) {
    span = std::fabs(mt[static_cast<std::size_t>(in.last_marker)] - mt[static_cast<std::size_t>(in.first_marker)]) /
           static_cast<double>(in.last_marker - in.first_marker);
  }
  const bool internal = j > in.first_marker && j <= in.last_marker;
  if (internal) {
    t_lo = mt[static_cast<std::size_t>(j - 1)] - 0.25 * span;
    t_hi = mt[static_cast<std::size_t>(j)] + 0.25 * span;
  } else if (j == in.first_marker) {
    t_lo = mt[static_cast<std::size_t>(j)] - 1.2 * span;
    t_hi = mt[static_cast<std::size_t>(j)] + 0.25 * span;
  } else {
    t_lo = mt[static_cast<std::size_t>(j - 1)] - 0.25 * span;
    t_hi = mt[static_cast<std::size_t>(j - 1)] + 1.2 * span;
  }
}

// Boundary j's crossings on both borders, per inset, and the points they
// put on its visible arc (each crossing moved its inset inside the border).
struct BoundaryCrossings {
  std::array<std::array<double, kProfileInsets>, 2> t{};
  std::array<std::array<bool, kProfileInsets>, 2> ok{};
  std::array<double, 2> strength{{0.0, 0.0}};  // per side: the crossings' slopes summed
  std::array<Point, 2U * kProfileInsets> arc{};
  std::size_t arc_count = 0U;
  std::array<int, 2> first_q{{-1, -1}};  // per side: the innermost inset with a crossing (-1: none)
};

BoundaryCrossings read_crossings(const std::array<Border, 2>& borders, const CornerProfiles& profiles,
                                 const Interpretation& in, int j, bool use_margin, double want_sign) noexcept {
  BoundaryCrossings out;
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Border& border = borders[side];
    if (!border.valid) {
      continue;
    }
    double t_lo = 0.0, t_hi = 0.0;
    crossing_window(in, profiles.marker_t[side], j, t_lo, t_hi);
    for (std::size_t q = 0U; q < kProfileInsets; ++q) {
      const double* profile = use_margin ? profiles.margin[side][q].data() : profiles.score[side][q].data();
      double best_slope = 0.0;
      out.ok[side][q] = best_crossing(profile, profiles.valid[side][q].data(), profiles.samples, kProfileT0,
                                      profiles.dt, t_lo, t_hi, want_sign, out.t[side][q], best_slope);
      if (out.ok[side][q]) {
        out.strength[side] += best_slope;
        const double tc = out.t[side][q];
        const Point p = border.curve.at(tc);
        const Point d = border.curve.derivative(tc);
        const double dl = dmath::hypot(d.x, d.y);
        const double sign = side == 1U ? 1.0 : -1.0;
        const double inset = profiles.insets[q];
        if (dl > 0.0) {
          out.arc[out.arc_count] = Point{p.x + inset * sign * (d.y / dl), p.y - inset * sign * (d.x / dl)};
          ++out.arc_count;
        }
      }
    }
    for (std::size_t q = 0U; q < kProfileInsets; ++q) {
      if (out.ok[side][q]) {
        out.first_q[side] = static_cast<int>(q);
        break;
      }
    }
  }
  return out;
}

// The border around a corner (parameter t on `global`) fitted again from
// the edge points within local_border_window x the tube's width (one
// quadratic over the whole tube is too coarse at a corner's scale); at an
// end boundary (end_sign +1 at the first, -1 at the last, 0 inside) only
// the marker's side: beyond it the shaft or the grasper has another radius.
// The global border where too few points or the fit fails; t: the corner's
// parameter on the border kept.
void refit_local_border(const Border& global, const CornersConfig& config, double end_sign, double half_width,
                        Border& local, double& t) noexcept {
  local = Border{};
  const Point approx = global.curve.at(t);
  const double window = config.local_border_window * 2.0 * half_width;
  const Point dir = global.curve.derivative(t);
  const double dir_len = dmath::hypot(dir.x, dir.y);
  for (const EdgePoint& ep : global.points) {
    const double along = dir_len > 0.0 ? ((ep.pixel.x - approx.x) * dir.x + (ep.pixel.y - approx.y) * dir.y) / dir_len : 0.0;
    if (end_sign * along < -config.end_margin_px) {
      continue;
    }
    if (dmath::hypot(ep.pixel.x - approx.x, ep.pixel.y - approx.y) <= window) {
      static_cast<void>(local.points.push_back(ep));  // same capacity as the global border
    }
  }
  if (local.points.size() < 6U ||
      !fit_bezier(local, config.tukey_c, config.irls_iterations, config.irls_scale_iterations)) {
    local = global;
    return;
  }
  double best = 1e30;
  double start = 0.5;
  for (int i = -4; i <= 24; ++i) {
    const Point q = local.curve.at(i / 20.0);
    const double d = dmath::hypot(q.x - approx.x, q.y - approx.y);
    if (d < best) {
      best = d;
      start = i / 20.0;
    }
  }
  t = nearest_t(local.curve, approx, start);
}

// The boundary's visible arc is half of an ellipse (a projected circle)
// tangent to both borders at the corners (fit_boundary_arc), on the local
// borders around them. A side's corner is kept (fitted[side]) within 3 half
// widths + 3 px of its innermost crossing.
void fit_arc_corners(const std::array<Border, 2>& borders, std::array<Border, 2>& local, const CornersConfig& config,
                     const BoundaryCrossings& cr, double end_sign, double half_width, std::array<Point, 2>& corner_px,
                     std::array<bool, 2>& fitted) noexcept {
  std::array<double, 2> t_corner{{cr.t[0][static_cast<std::size_t>(cr.first_q[0])],
                                  cr.t[1][static_cast<std::size_t>(cr.first_q[1])]}};
  bool local_ok = true;
  for (std::size_t side = 0U; side < 2U; ++side) {
    refit_local_border(borders[side], config, end_sign, half_width, local[side], t_corner[side]);
    local_ok = local_ok && local[side].valid;
  }
  if (!local_ok || !fit_boundary_arc(local, cr.arc.data(), cr.arc_count, t_corner)) {
    return;
  }
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Point p = local[side].curve.at(t_corner[side]);
    const Point near = borders[side].curve.at(cr.t[side][static_cast<std::size_t>(cr.first_q[side])]);
    if (dmath::hypot(p.x - near.x, p.y - near.y) < 3.0 * half_width + 3.0) {
      corner_px[side] = p;
      fitted[side] = true;
    }
  }
}

// A corner from one border only: its innermost crossing, extrapolated to
// the border with the tangency law t(d) ~ t0 + a sqrt(d) when the next
// inset has a crossing too.
Point extrapolated_corner(const Border& border, const BoundaryCrossings& cr,
                          const std::array<double, kProfileInsets>& insets, std::size_t side) noexcept {
  const auto fq = static_cast<std::size_t>(cr.first_q[side]);
  const double t_near = cr.t[side][fq];
  if (fq + 1U < kProfileInsets && cr.ok[side][fq + 1U]) {
    const double d0 = std::sqrt(insets[fq]);
    const double d1 = std::sqrt(insets[fq + 1U]);
    const double t1 = cr.t[side][fq + 1U];
    return border.curve.at(t_near - (t1 - t_near) * d0 / (d1 - d0));
  }
  return border.curve.at(t_near);
}

}  // namespace

Result<std::unique_ptr<CornerFinder>, VisionError> CornerFinder::create(const CornersConfig& config,
                                                                        const ColorModel& colors) noexcept {
  using R = Result<std::unique_ptr<CornerFinder>, VisionError>;
  if (config.profile_samples < 16 || config.profile_samples > static_cast<int>(kMaxProfileSamples) ||
      !colors.valid() || config.irls_iterations < 1 || config.irls_iterations > 50 ||
      config.irls_scale_iterations < 1 || config.irls_scale_iterations > config.irls_iterations ||
      !(config.tukey_c > 0.0)) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<CornerFinder> finder(new (std::nothrow) CornerFinder());
  if (finder == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  finder->config_ = config;
  finder->colors_ = colors;
  finder->scratch_.reset(new (std::nothrow) Scratch());
  if (finder->scratch_ == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  return R::success(std::move(finder));
}

Status<VisionError> CornerFinder::find(const ImageView& image, const Interpretation& in,
                                       const std::array<Border, 2>& borders, std::array<Corner, kNumCorners>& corners,
                                       int& corner_count) noexcept {
  for (auto& c : corners) {
    c = Corner{};
  }
  corner_count = 0;
  if (in.found_count < 2 || (!borders[0].valid && !borders[1].valid)) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  Scratch& scratch = *scratch_;
  CornerProfiles profiles{scratch.score, scratch.margin, scratch.valid};
  profiles.samples = config_.profile_samples;
  profiles.dt = (kProfileT1 - kProfileT0) / static_cast<double>(profiles.samples - 1);
  // Insets: from just inside the border to a little past the tube's middle,
  // so that the two sides together trace each boundary's visible arc.
  const double half_width = inset_half_width_px(in);
  const double first_inset = config_.profile_min_inset_px;
  const double last_inset = std::max(first_inset + 1.0, config_.profile_max_inset * half_width);
  for (std::size_t q = 0U; q < kProfileInsets; ++q) {
    profiles.insets[q] =
        first_inset + (last_inset - first_inset) * static_cast<double>(q) / static_cast<double>(kProfileInsets - 1U);
  }
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Border& border = borders[side];
    if (!border.valid) {
      continue;
    }
    sample_border_profiles(image, colors_, border, side, profiles.insets, profiles.samples, profiles.dt,
                           scratch.score[side], scratch.margin[side], scratch.valid[side]);
    marker_params(in, border, profiles.samples, profiles.dt, profiles.marker_t[side]);
  }
  // Boundary j lies between markers j-1 and j (0-based markers).
  for (int j = in.first_marker; j <= in.last_marker + 1; ++j) {
    bool use_margin = false;
    double want_sign = 0.0;
    if (!boundary_change(in, j, use_margin, want_sign)) {
      continue;
    }
    const BoundaryCrossings cr = read_crossings(borders, profiles, in, j, use_margin, want_sign);
    std::array<Point, 2> corner_px{};
    std::array<bool, 2> fitted{{false, false}};
    if (borders[0].valid && borders[1].valid && cr.first_q[0] >= 0 && cr.first_q[1] >= 0 && cr.arc_count >= 5U) {
      const bool internal = j > in.first_marker && j <= in.last_marker;
      const double end_sign = !internal ? (j == in.first_marker ? 1.0 : -1.0) : 0.0;
      fit_arc_corners(borders, scratch.local_borders, config_, cr, end_sign, half_width, corner_px, fitted);
    }
    for (std::size_t side = 0U; side < 2U; ++side) {
      const Border& border = borders[side];
      if (!border.valid || cr.first_q[side] < 0) {
        continue;
      }
      if (!fitted[side]) {
        corner_px[side] = extrapolated_corner(border, cr, profiles.insets, side);
      }
      const double conf = (cr.strength[side] / static_cast<double>(kProfileInsets)) / 2.0 * (fitted[side] ? 1.0 : 0.5);
      const double confidence = conf > 1.0 ? 1.0 : (conf < 0.0 ? 0.0 : conf);
      if (confidence < config_.min_corner_confidence) {
        continue;  // weak or unfitted: more often misplaced than not
      }
      const int k = 2 * j + static_cast<int>(side);
      Corner& c = corners[static_cast<std::size_t>(k)];
      c.found = true;
      c.pixel = corner_px[side];
      c.confidence = confidence;
      ++corner_count;
    }
  }
  return ok_status<VisionError>();
}

}  // namespace vision
}  // namespace tcpest
