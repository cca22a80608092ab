#include "synthetic_scene.hpp"

#include <algorithm>
#include <cmath>

namespace tcpest {
namespace vision {
namespace test {
namespace {

using solver::Vec2;
using solver::Vec3;

enum Part : std::uint8_t { kNone = 0, kShaft, kBlue, kYellow, kGrasper };

struct Cylinder {
  Vec3 a;
  Vec3 axis;  // unit
  double length = 0.0;
  double radius = 0.0;
  double s0 = 0.0, s1 = 0.0;  // arc length range (bending section), else equal
  int kind = 0;               // 0 shaft, 1 bending, 2 grasper
};

struct Hit {
  double depth = 1e30;  // ray parameter (ray z = 1 component scaled)
  Part part = kNone;
  double shade = 1.0;
};

constexpr int kBendSegments = 64;

std::uint32_t hash(std::uint32_t x) noexcept {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

double noise(std::uint32_t seed, int x, int y, int c) noexcept {
  // Approximately Gaussian (sum of 4 uniforms), unit variance.
  double s = 0.0;
  for (std::uint32_t i = 0U; i < 4U; ++i) {
    const std::uint32_t h = hash(seed * 2654435761U ^ static_cast<std::uint32_t>(x) * 73856093U ^
                                 static_cast<std::uint32_t>(y) * 19349663U ^ static_cast<std::uint32_t>(c) * 83492791U ^
                                 i * 2246822519U);
    s += static_cast<double>(h) / 4294967295.0 - 0.5;
  }
  return s * std::sqrt(3.0);
}

}  // namespace

class Tracer {
 public:
  Tracer(const solver::InstrumentModel& model, const solver::PoseVector& r) {
    const auto& g = model.geometry();
    const solver::PoseFrames f = model.frames(r);
    const Vec3 ch = f.channel_origin;
    const Vec3 base = f.base_origin;
    const double shaft_len = (base - ch).norm();
    if (shaft_len > 1e-6) {
      add(ch, base, g.shaft_radius_mm, 0.0, 0.0, 0);
    }
    for (int i = 0; i < kBendSegments; ++i) {
      const double s0 = g.bend_length_mm * i / kBendSegments;
      const double s1 = g.bend_length_mm * (i + 1) / kBendSegments;
      add(model.centreline(f, s0).position, model.centreline(f, s1).position, g.radius_mm, s0, s1, 1);
    }
    add(model.centreline(f, g.bend_length_mm).position, model.tcp(r), g.grasper_radius_mm, 0.0, 0.0, 2);
    boundaries_ = g.boundaries_mm;
    colors_ = g.marker_colors;
  }

  Hit trace(const Vec3& dir) const noexcept {
    Hit best;
    for (const Cylinder& c : cylinders_) {
      // Ray o = 0, direction dir.
      const Vec3 w = -c.a;
      const Vec3 dp = dir - dir.dot(c.axis) * c.axis;
      const Vec3 wp = w - w.dot(c.axis) * c.axis;
      const double qa = dp.squaredNorm();
      const double qb = 2.0 * dp.dot(wp);
      const double qc = wp.squaredNorm() - c.radius * c.radius;
      const double disc = qb * qb - 4.0 * qa * qc;
      if (disc < 0.0 || qa < 1e-15) {
        continue;
      }
      const double t = (-qb - std::sqrt(disc)) / (2.0 * qa);
      if (t <= 0.0 || t >= best.depth) {
        continue;
      }
      const Vec3 p = t * dir;
      const double z = (p - c.a).dot(c.axis);
      if (z < 0.0 || z > c.length) {
        continue;
      }
      const Vec3 n = ((p - c.a) - z * c.axis) / c.radius;
      best.depth = t;
      best.shade = std::fabs(n.dot(dir.normalized()));
      if (c.kind == 0) {
        best.part = kShaft;
      } else if (c.kind == 2) {
        best.part = kGrasper;
      } else {
        const double s = c.s0 + (c.s1 - c.s0) * z / c.length;
        best.part = kShaft;
        for (std::size_t m = 0U; m < colors_.size(); ++m) {
          if (s >= boundaries_[m] && s < boundaries_[m + 1U] + 1e-12) {
            best.part = colors_[m] == solver::MarkerColor::Blue ? kBlue : kYellow;
            break;
          }
        }
      }
    }
    return best;
  }

 private:
  void add(const Vec3& a, const Vec3& b, double radius, double s0, double s1, int kind) {
    Cylinder c;
    c.a = a;
    c.length = (b - a).norm();
    c.axis = (b - a) / c.length;
    c.radius = radius;
    c.s0 = s0;
    c.s1 = s1;
    c.kind = kind;
    cylinders_.push_back(c);
  }
  std::vector<Cylinder> cylinders_;
  std::array<double, solver::kNumBoundaries> boundaries_{};
  std::array<solver::MarkerColor, solver::kNumMarkers> colors_{};
};

void Scene::render(const solver::PoseVector& r, const SceneStyle& style, std::vector<std::uint8_t>& pixels,
                   Truth& truth, std::vector<PixelClass>* classes) const {
  const int w = camera_.width();
  const int h = camera_.height();
  pixels.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3U, 0U);
  if (classes != nullptr) {
    classes->assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), PixelClass::Background);
  }
  const Tracer tracer(model_, r);
  const auto colour_of = [&style](const Hit& hit, int x, int y, double fx, double fy, double out[3]) {
    const std::array<std::uint8_t, 3>* base = nullptr;
    switch (hit.part) {
      case kShaft: base = &style.shaft; break;
      case kBlue: base = &style.blue; break;
      case kYellow: base = &style.yellow; break;
      case kGrasper: base = &style.grasper; break;
      case kNone: break;
    }
    if (base == nullptr) {
      const double px = x + fx;
      const double py = y + fy;
      const double t = style.tissue_texture *
                       (std::sin(px * 0.021 + 0.7 * std::cos(py * 0.013)) + 0.6 * std::sin(py * 0.034 - px * 0.011));
      out[0] = style.tissue[0] + t;
      out[1] = style.tissue[1] + 0.6 * t;
      out[2] = style.tissue[2] + 0.5 * t;
      return;
    }
    const double s = style.ambient + (1.0 - style.ambient) * hit.shade;
    for (int c = 0; c < 3; ++c) {
      out[c] = (*base)[static_cast<std::size_t>(c)] * s;
    }
  };
  // Coarse pass at pixel centres, then supersampling where neighbours differ.
  std::vector<Part> part(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), kNone);
  std::vector<Hit> hits(part.size());
  // Instrument bounding box in the image, to skip most background rays.
  int bx0 = 0, by0 = 0, bx1 = w - 1, by1 = h - 1;
  {
    const solver::PoseFrames f = model_.frames(r);
    bool all = true;
    double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
    const auto add = [&](const Vec3& p, double radius) {
      Vec2 px;
      if (p.z() <= radius + 0.5 || !camera_.project(p, px)) {
        all = false;
        return;
      }
      const double rp = 2.5 * radius * camera_.intrinsics().fx / (p.z() - radius) + 4.0;
      x0 = std::min(x0, px.x() - rp);
      x1 = std::max(x1, px.x() + rp);
      y0 = std::min(y0, px.y() - rp);
      y1 = std::max(y1, px.y() + rp);
    };
    const auto& g = model_.geometry();
    for (int i = 0; i <= 20; ++i) {
      add(f.channel_origin + (f.base_origin - f.channel_origin) * (i / 20.0), g.shaft_radius_mm);
      add(model_.centreline(f, g.bend_length_mm * i / 20.0).position, g.radius_mm);
      const Vec3 e = model_.centreline(f, g.bend_length_mm).position;
      add(e + (model_.tcp(r) - e) * (i / 20.0), g.grasper_radius_mm);
    }
    if (all) {
      bx0 = std::max(0, static_cast<int>(x0));
      by0 = std::max(0, static_cast<int>(y0));
      bx1 = std::min(w - 1, static_cast<int>(x1) + 1);
      by1 = std::min(h - 1, static_cast<int>(y1) + 1);
    }
  }
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      Vec2 ray;
      Hit hit;
      if (x >= bx0 && x <= bx1 && y >= by0 && y <= by1 && camera_.undistort(Vec2(x, y), ray)) {
        hit = tracer.trace(Vec3(ray.x(), ray.y(), 1.0));
      }
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
      part[i] = hit.part;
      hits[i] = hit;
    }
  }
  const int ss = std::max(1, style.supersampling);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
      bool edge = false;
      for (int dy = -1; dy <= 1 && !edge; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx;
          const int yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) {
            continue;
          }
          if (part[static_cast<std::size_t>(yy) * static_cast<std::size_t>(w) + static_cast<std::size_t>(xx)] !=
              part[i]) {
            edge = true;
            break;
          }
        }
      }
      double acc[3] = {0.0, 0.0, 0.0};
      if (!edge) {
        colour_of(hits[i], x, y, 0.0, 0.0, acc);
      } else {
        for (int sy = 0; sy < ss; ++sy) {
          for (int sx = 0; sx < ss; ++sx) {
            const double fx = (sx + 0.5) / ss - 0.5;
            const double fy = (sy + 0.5) / ss - 0.5;
            Vec2 ray;
            Hit hit;
            if (camera_.undistort(Vec2(x + fx, y + fy), ray)) {
              hit = tracer.trace(Vec3(ray.x(), ray.y(), 1.0));
            }
            double c[3];
            colour_of(hit, x, y, fx, fy, c);
            for (int k = 0; k < 3; ++k) {
              acc[k] += c[k] / (ss * ss);
            }
          }
        }
      }
      for (int c = 0; c < 3; ++c) {
        double v = acc[c];
        if (style.noise_sd > 0.0) {
          v += style.noise_sd * noise(style.seed, x, y, c);
        }
        v = v < 0.0 ? 0.0 : (v > 255.0 ? 255.0 : v);
        pixels[i * 3U + static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(std::lround(v));
      }
      if (classes != nullptr) {
        (*classes)[i] = part[i] == kBlue ? PixelClass::Blue : (part[i] == kYellow ? PixelClass::Yellow : PixelClass::Background);
      }
    }
  }
  // Truth.
  model_.corners(camera_, r, truth.corners);
  truth.visible_count = 0;
  for (std::size_t k = 0U; k < static_cast<std::size_t>(solver::kNumCorners); ++k) {
    truth.visible[k] = false;
    if (!truth.corners.in_image[k]) {
      continue;
    }
    const Vec3& p = truth.corners.point[k];
    const Hit hit = tracer.trace(p / p.z());
    // Hidden when something lies clearly in front of the limb point.
    truth.visible[k] = !(hit.part != kNone && hit.depth * 1.0 < p.z() - 0.5);
    if (truth.visible[k]) {
      ++truth.visible_count;
    }
  }
}

std::vector<solver::PoseVector> reference_grid(const solver::CameraModel& camera,
                                               const solver::InstrumentModel& model, int min_corners) {
  std::vector<solver::PoseVector> out;
  for (int li = 0; li < 7; ++li) {
    for (int pi = 0; pi < 7; ++pi) {
      for (int ti = 0; ti < 6; ++ti) {
        const double lambda = 10.0 + 30.0 * li / 6.0;
        const double phi = solver::deg_to_rad(-90.0 + 180.0 * pi / 6.0);
        const double theta = solver::deg_to_rad(-100.0 + 200.0 * ti / 5.0);
        const solver::PoseVector r = model.geometry().nominal_pose(lambda, phi, theta);
        solver::CornerSet cs;
        model.corners(camera, r, cs);
        if (cs.count_in_image() >= min_corners) {
          out.push_back(r);
        }
      }
    }
  }
  return out;
}

}  // namespace test
}  // namespace vision
}  // namespace tcpest
