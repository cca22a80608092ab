// Stage 4's geometry on its own (src/boundary_arc.hpp): a boundary's visible
// arc is half of an ellipse tangent to both borders, and the corners are
// the two tangency points, found through the projective map that makes the
// borders parallel.
#include <gtest/gtest.h>

#include <cmath>

#include "../src/boundary_arc.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

constexpr double kPi = 3.14159265358979323846;

// An ellipse like a stripe boundary's circle seen obliquely.
struct Ellipse {
  Point centre{200.0, 150.0};
  double a = 25.0;  // semi-axis along x (along the tube)
  double b = 45.0;  // semi-axis along y (across it)
  Point at(double phi) const { return Point{centre.x + a * std::cos(phi), centre.y + b * std::sin(phi)}; }
  Point tangent(double phi) const {  // unit, x growing
    double tx = -a * std::sin(phi);
    double ty = b * std::cos(phi);
    const double n = std::hypot(tx, ty);
    if (tx < 0.0) {
      tx = -tx;
      ty = -ty;
    }
    return Point{tx / n, ty / n};
  }
};

// The straight border tangent to the ellipse at phi: a Bezier with its
// middle control point half way.
Border border_tangent_at(const Ellipse& e, double phi) {
  const Point p = e.at(phi);
  const Point t = e.tangent(phi);
  Border b;
  b.curve.p0 = Point{p.x - 80.0 * t.x, p.y - 80.0 * t.y};
  b.curve.p2 = Point{p.x + 60.0 * t.x, p.y + 60.0 * t.y};
  b.curve.p1 = Point{0.5 * (b.curve.p0.x + b.curve.p2.x), 0.5 * (b.curve.p0.y + b.curve.p2.y)};
  b.valid = true;
  return b;
}

double distance(const Point& p, const Point& q) { return std::hypot(p.x - q.x, p.y - q.y); }

// Borders converging as under perspective (tangent at -80 and 110 deg, not
// opposite), the arc read on the half facing +x: the corners found from
// starts 10 px off are the tangency points.
// Verifies: REQ-VISION-006
TEST(BoundaryArc, TheCornersAreTheTangencyPointsOfTheArcsEllipse) {
  const Ellipse e;
  const double phi0 = -80.0 * kPi / 180.0;
  const double phi1 = 110.0 * kPi / 180.0;
  const std::array<Border, 2> borders{{border_tangent_at(e, phi0), border_tangent_at(e, phi1)}};
  std::array<Point, 15> arc{};
  for (std::size_t i = 0U; i < arc.size(); ++i) {
    const double f = (static_cast<double>(i) + 1.0) / (static_cast<double>(arc.size()) + 1.0);
    arc[i] = e.at(phi0 + f * (phi1 - phi0));  // through phi = 0: the +x half
  }
  std::array<double, 2> t{};
  for (std::size_t side = 0U; side < 2U; ++side) {
    const Point truth = e.at(side == 0U ? phi0 : phi1);
    const Point tangent = e.tangent(side == 0U ? phi0 : phi1);
    const Point start{truth.x + 10.0 * tangent.x, truth.y + 10.0 * tangent.y};
    t[side] = nearest_t(borders[side].curve, start, 0.5);
    EXPECT_NEAR(distance(borders[side].curve.at(t[side]), start), 0.0, 1e-6);
  }
  ASSERT_TRUE(fit_boundary_arc(borders, arc.data(), arc.size(), t));
  EXPECT_LT(distance(borders[0].curve.at(t[0]), e.at(phi0)), 0.01);
  EXPECT_LT(distance(borders[1].curve.at(t[1]), e.at(phi1)), 0.01);
}

TEST(BoundaryArc, BordersOnOneLineAreRefused) {
  const Ellipse e;
  const Border one = border_tangent_at(e, -kPi / 2.0);
  const std::array<Border, 2> borders{{one, one}};
  std::array<Point, 5> arc{};
  for (std::size_t i = 0U; i < arc.size(); ++i) {
    arc[i] = e.at(-kPi / 2.0 + 0.5 * static_cast<double>(i));
  }
  std::array<double, 2> t{{0.5, 0.5}};
  EXPECT_FALSE(fit_boundary_arc(borders, arc.data(), arc.size(), t));
}

TEST(BoundaryArc, NearestParameterOnACurve) {
  const Bezier curve{Point{0.0, 0.0}, Point{50.0, 20.0}, Point{100.0, 0.0}};
  for (const double truth : {0.1, 0.35, 0.5, 0.8}) {
    const Point on = curve.at(truth);
    const Point d = curve.derivative(truth);
    const double n = std::hypot(d.x, d.y);
    const Point off{on.x - 3.0 * d.y / n, on.y + 3.0 * d.x / n};  // 3 px along the normal
    EXPECT_NEAR(nearest_t(curve, off, 0.5), truth, 1e-9) << truth;
  }
}

}  // namespace
}  // namespace detail
}  // namespace vision
}  // namespace tcpest
