// The IRLS fit of a quadratic Bezier curve with Tukey's biweight (stage 3
// of the paper, section 2.3; docs/vision.md "Stage 3: borders"), shared by
// stage 3's borders and stage 4's local borders. Pure: no image, no
// allocation.
#pragma once

#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace vision {
namespace detail {

// Tukey's biweight: (1 - u^2)^2 inside |u| < 1, 0 from there.
double tukey_weight(double u) noexcept;

// Solves the 3x3 system m x = rhs (two right-hand sides) by Gaussian
// elimination with partial pivoting; m and rhs are overwritten. False when
// singular (a pivot below 1e-12).
bool solve3(double m[3][3], double rhs[3][2], double x[3][2]) noexcept;

// Fits border.curve to border.points by iteratively reweighted least
// squares: chord-length parameters t_i in [0, 1], weights Tukey's biweight
// of residual / (c x scale), scale = 1.4826 x the median residual distance
// (floored at 0.15 px) updated during the first `scale_iterations`
// iterations only, at most `iterations` iterations (fewer once no control
// point moves by 1e-4 px). Writes each point's t and weight, the curve,
// scale_px and iterations; valid (and true) when the weights sum to 4 or
// more. False with fewer than 5 points, coincident points only, a singular
// system, or iterations, scale_iterations or c not positive.
bool fit_bezier(Border& border, double c, int iterations, int scale_iterations) noexcept;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
