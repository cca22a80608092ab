// Stage 4's geometry (the paper's section 2.3; docs/vision.md "Stage 4:
// corners"): a marker boundary's visible arc is half of an ellipse tangent
// to both borders, and the corners are the tangency points. Pure: no image,
// no allocation.
#pragma once

#include <array>
#include <cstddef>

#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {
namespace detail {

// Parameter of the point of `curve` nearest to p, from t (Newton, at most 8
// steps of at most 0.2 each).
double nearest_t(const Bezier& curve, const Point& p, double t) noexcept;

// The visible arc of a marker boundary is half of an ellipse (the projected
// circle) tangent to both borders at the two corners. A projective map H that
// sends the intersection of the two borders' tangent lines to infinity makes
// the lines parallel (v = v_mid -/+ w) and keeps the conic tangent to them;
// such an ellipse is u = u_c + alpha cos(phi) + beta sin(phi),
// v = v_mid + w sin(phi), which touches the lines at u = u_c -/+ beta. With
// sin(phi) from each arc point's v, u is linear in (u_c, alpha, beta): least
// squares, then the two tangency points mapped back. The tangent lines are
// taken at the current corner estimates, so the fit is repeated (bounded).
// t_corner: in, the corners' parameters on borders[0] and borders[1] to
// start from; out, the tangency points' parameters. False when the borders
// are (nearly) one line, the arc is degenerate or a point maps to infinity.
bool fit_boundary_arc(const std::array<Border, 2>& borders, const Point* arc, std::size_t count,
                      std::array<double, 2>& t_corner) noexcept;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
