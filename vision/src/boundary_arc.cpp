// Stage 4's geometry: the boundary arc's ellipse and its tangency points
// (boundary_arc.hpp).
#include "boundary_arc.hpp"

#include <cmath>

#include <Eigen/Dense>

#include "bezier_fit.hpp"
#include "tcpest/common/dmath.hpp"

namespace tcpest {
namespace vision {
namespace detail {
namespace {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;

}  // namespace

double nearest_t(const Bezier& curve, const Point& p, double t) noexcept {
  const double ddx = 2.0 * ((curve.p2.x - curve.p1.x) - (curve.p1.x - curve.p0.x));
  const double ddy = 2.0 * ((curve.p2.y - curve.p1.y) - (curve.p1.y - curve.p0.y));
  for (int it = 0; it < 8; ++it) {
    const Point q = curve.at(t);
    const Point d = curve.derivative(t);
    const double f = (q.x - p.x) * d.x + (q.y - p.y) * d.y;
    const double df = d.x * d.x + d.y * d.y + (q.x - p.x) * ddx + (q.y - p.y) * ddy;
    if (!(std::fabs(df) > 1e-12)) {
      break;
    }
    const double step = f / df;
    t -= step > 0.2 ? 0.2 : (step < -0.2 ? -0.2 : step);
  }
  return t;
}

bool fit_boundary_arc(const std::array<Border, 2>& borders, const Point* arc, std::size_t count,
                      std::array<double, 2>& t_corner) noexcept {
  constexpr int kRounds = 4;
  for (int round = 0; round < kRounds; ++round) {
    std::array<Vec3, 2> line{};
    std::array<Point, 2> c{};
    for (std::size_t side = 0U; side < 2U; ++side) {
      c[side] = borders[side].curve.at(t_corner[side]);
      const Point d = borders[side].curve.derivative(t_corner[side]);
      const Vec3 a(c[side].x, c[side].y, 1.0);
      const Vec3 b(c[side].x + d.x, c[side].y + d.y, 1.0);
      line[side] = a.cross(b);
    }
    const Point mid{0.5 * (c[0].x + c[1].x), 0.5 * (c[0].y + c[1].y)};
    Mat3 h = Mat3::Identity();
    const Vec3 x = line[0].cross(line[1]);
    if (std::fabs(x.z()) > 1e-12) {
      const double xx = x.x() / x.z();
      const double xy = x.y() / x.z();
      // Line through X perpendicular to (mid - X), scaled to 1 at mid.
      const double dx = mid.x - xx;
      const double dy = mid.y - xy;
      Vec3 h3(dx, dy, -(dx * xx + dy * xy));
      const double at_mid = h3.x() * mid.x + h3.y() * mid.y + h3.z();
      if (!(std::fabs(at_mid) > 1e-12)) {
        return false;
      }
      h3 /= at_mid;
      h.row(2) = h3.transpose();
    }
    const auto map = [&h](const Point& p) noexcept {
      const Vec3 q = h * Vec3(p.x, p.y, 1.0);
      return Point{q.x() / q.z(), q.y() / q.z()};
    };
    // Mapped tangent lines are parallel: a common unit normal n.
    const Mat3 h_inv_t = h.inverse().transpose();
    const Vec3 l0 = h_inv_t * line[0];
    const Vec3 l1 = h_inv_t * line[1];
    const double n0 = dmath::hypot(l0.x(), l0.y());
    const double n1 = dmath::hypot(l1.x(), l1.y());
    if (!(n0 > 1e-12) || !(n1 > 1e-12)) {
      return false;
    }
    double nx = l0.x() / n0;
    double ny = l0.y() / n0;
    const Point m0 = map(c[0]);
    const Point m1 = map(c[1]);
    double v0 = nx * m0.x + ny * m0.y;
    double v1 = nx * m1.x + ny * m1.y;
    if (v1 < v0) {  // orient v from side 0 to side 1
      nx = -nx;
      ny = -ny;
      v0 = -v0;
      v1 = -v1;
    }
    const double w = 0.5 * (v1 - v0);
    const double v_mid = 0.5 * (v1 + v0);
    if (!(w > 0.5)) {
      return false;
    }
    const double ux = -ny;
    const double uy = nx;
    double m[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    double rhs[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    for (std::size_t i = 0U; i < count; ++i) {
      const Point q = map(arc[i]);
      double sn = (nx * q.x + ny * q.y - v_mid) / w;
      sn = sn > 1.0 ? 1.0 : (sn < -1.0 ? -1.0 : sn);
      const double basis[3] = {1.0, std::sqrt(1.0 - sn * sn), sn};
      const double u = ux * q.x + uy * q.y;
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
          m[r][k] += basis[r] * basis[k];
        }
        rhs[r][0] += basis[r] * u;
      }
    }
    double sol[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    if (!solve3(m, rhs, sol)) {
      return false;
    }
    const Mat3 h_inv = h.inverse();
    for (std::size_t side = 0U; side < 2U; ++side) {
      const double sgn = side == 1U ? 1.0 : -1.0;
      const double u = sol[0][0] + sgn * sol[2][0];
      const double v = v_mid + sgn * w;
      const Vec3 q = h_inv * Vec3(u * ux + v * nx, u * uy + v * ny, 1.0);
      if (!(std::fabs(q.z()) > 1e-12)) {
        return false;
      }
      const Point p{q.x() / q.z(), q.y() / q.z()};
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
        return false;
      }
      t_corner[side] = nearest_t(borders[side].curve, p, t_corner[side]);
    }
  }
  return true;
}

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
