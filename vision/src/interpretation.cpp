// Stage 2: the interpretation tree of the paper. Levels are the markers 1..5
// from the base. A hypothesis starts at a region of the colour of some level
// (levels below it are empty: out of the image or hidden) and grows towards
// the tip one level at a time. The children of a node are the regions of the
// next level's colour that are adjacent to it and keep the skeleton's turn
// below 60 deg, plus virtual nodes merging two of them (a marker split by a
// highlight or an occlusion). At each level the child of highest posterior
// p(S|M_i) p(d|M_i) is kept; after a merge the merged statistics are used for
// the next level. The hypothesis of highest total score wins.
#include <cmath>
#include <new>

#include "tcpest/common/dmath.hpp"
#include "tcpest/vision/interpretation.hpp"

namespace tcpest {
namespace vision {
namespace {

constexpr std::size_t kMaxChildren = 8U;
constexpr double kNegligible = -1e30;

double sq(double v) noexcept { return v * v; }

double gaussian_log(double value, double mean, double sd) noexcept {
  if (!(sd > 0.0)) {
    return 0.0;
  }
  return -0.5 * sq((value - mean) / sd);
}

// log p(S | M_i): the half axes against the marker's prior, plus (if known)
// the position.
double shape_log(const Region& r, const MarkerPrior& prior) noexcept {
  double s = gaussian_log(r.half_major, prior.half_major, prior.half_major_sd) +
             gaussian_log(r.half_minor, prior.half_minor, prior.half_minor_sd);
  if (prior.centroid_sd > 0.0) {
    const double d = dmath::hypot(r.centroid.x - prior.centroid.x, r.centroid.y - prior.centroid.y);
    s += gaussian_log(d, 0.0, prior.centroid_sd);
  }
  return s;
}

// log p(d | M_i): the distance to the parent against the prior, and relative
// to the two regions' extents along the link (adjacent stripes touch).
double distance_log(const Region& child, const Region& parent, const MarkerPrior& prior) noexcept {
  const double dx = child.centroid.x - parent.centroid.x;
  const double dy = child.centroid.y - parent.centroid.y;
  const double d = dmath::hypot(dx, dy);
  if (!(d > 0.0)) {
    return kNegligible;
  }
  const double touching = child.extent_along(dx / d, dy / d) + parent.extent_along(dx / d, dy / d);
  double s = gaussian_log(d, prior.parent_distance, prior.parent_distance_sd);
  if (touching > 0.0) {
    s += gaussian_log(d / touching, 1.0, 0.25);
  }
  // Neighbouring stripes have similar sizes (same tube, similar depth).
  const double area_ratio = dmath::log(static_cast<double>(child.area) / static_cast<double>(parent.area));
  s += gaussian_log(area_ratio, 0.0, 0.7);
  return s;
}

bool adjacent(const Region& a, const Region& b, const InterpretationConfig& config) noexcept {
  const double dx = b.centroid.x - a.centroid.x;
  const double dy = b.centroid.y - a.centroid.y;
  const double d = dmath::hypot(dx, dy);
  if (!(d > 0.0)) {
    return false;
  }
  const double reach = a.extent_along(dx / d, dy / d) + b.extent_along(dx / d, dy / d);
  return d <= config.adjacency_factor * reach + config.adjacency_slack_px;
}

PixelClass level_class(const InterpretationConfig& config, int level) noexcept {
  return config.marker_classes[static_cast<std::size_t>(level)];
}

struct Node {
  Region region{};
  std::array<std::int16_t, 2> index{{-1, -1}};
  double log_posterior = kNegligible;
};

using RegionList = StaticVector<Region, kMaxRegions>;
using Children = StaticVector<std::size_t, kMaxChildren>;

// The skeleton's direction at the last link of a hypothesis (unit vector in
// the image), once it has one.
struct Heading {
  bool known = false;
  double x = 0.0;
  double y = 0.0;
};

// The children of `parent` at the next level: the unused regions of colour
// `want` adjacent to it whose link keeps the skeleton's turn from `heading`
// below max_link_angle_rad (at most kMaxChildren).
void collect_children(const RegionList& regions, const InterpretationConfig& config, const Region& parent, PixelClass want,
                      std::uint64_t used, const Heading& heading, Children& children) noexcept {
  for (std::size_t c = 0U; c < regions.size() && !children.full(); ++c) {
    if (((used >> c) & 1ULL) != 0ULL) {
      continue;
    }
    const Region& cand = regions[c];
    if (cand.cls != want || !adjacent(parent, cand, config)) {
      continue;
    }
    if (heading.known) {
      const double dx = cand.centroid.x - parent.centroid.x;
      const double dy = cand.centroid.y - parent.centroid.y;
      const double d = dmath::hypot(dx, dy);
      if (!(d > 0.0) || (dx * heading.x + dy * heading.y) / d < dmath::cos(config.max_link_angle_rad)) {
        continue;
      }
    }
    static_cast<void>(children.push_back(c));  // bounded by the loop condition
  }
}

// The node of highest posterior p(S|M_i) p(d|M_i) under the level's prior:
// a child, or a virtual node merging two of them (none: index[0] < 0).
Node best_child(const RegionList& regions, const Children& children, const Region& parent,
                const MarkerPrior& prior) noexcept {
  Node chosen;
  for (std::size_t a = 0U; a < children.size(); ++a) {
    const Region& ra = regions[children[a]];
    const double lp = shape_log(ra, prior) + distance_log(ra, parent, prior);
    if (lp > chosen.log_posterior) {
      chosen.region = ra;
      chosen.index = {{static_cast<std::int16_t>(children[a]), -1}};
      chosen.log_posterior = lp;
    }
    // Virtual nodes: this child merged with another one of the level.
    for (std::size_t b = a + 1U; b < children.size(); ++b) {
      Region merged = ra;
      merged.merge(regions[children[b]]);
      const double lpm = shape_log(merged, prior) + distance_log(merged, parent, prior);
      if (lpm > chosen.log_posterior) {
        chosen.region = merged;
        chosen.index = {{static_cast<std::int16_t>(children[a]), static_cast<std::int16_t>(children[b])}};
        chosen.log_posterior = lpm;
      }
    }
  }
  return chosen;
}

// One hypothesis: from the root region (merged with `partner` when it is
// another region) at level `start`, grown towards the tip level by level
// while a chosen node's posterior and the level reward stay above zero.
// Returns its score (before the orientation cue).
double grow_hypothesis(const RegionList& regions, const InterpretationConfig& config, const MarkerPriors& priors,
                       std::size_t root, std::size_t partner, int start, Interpretation& hyp) noexcept {
  hyp = Interpretation{};
  std::uint64_t used = (1ULL << root) | (1ULL << partner);
  Node current;
  current.region = regions[root];
  current.index = {{static_cast<std::int16_t>(root), -1}};
  if (partner != root) {
    current.region.merge(regions[partner]);
    current.index[1] = static_cast<std::int16_t>(partner);
  }
  current.log_posterior = shape_log(current.region, priors.marker[static_cast<std::size_t>(start)]);
  double score = current.log_posterior + config.level_reward;
  hyp.markers[static_cast<std::size_t>(start)] =
      MarkerObservation{true, current.region, current.index, current.log_posterior};
  hyp.first_marker = start;
  hyp.last_marker = start;
  hyp.found_count = 1;
  Heading heading;
  for (int level = start + 1; level < kNumMarkers; ++level) {
    const MarkerPrior& prior = priors.marker[static_cast<std::size_t>(level)];
    // Children: adjacent, right colour, unused, turn below the limit.
    Children children;
    collect_children(regions, config, current.region, level_class(config, level), used, heading, children);
    const Node chosen = best_child(regions, children, current.region, prior);
    if (chosen.index[0] < 0 || chosen.log_posterior + config.level_reward < 0.0) {
      break;  // the remaining levels are empty
    }
    const double dx = chosen.region.centroid.x - current.region.centroid.x;
    const double dy = chosen.region.centroid.y - current.region.centroid.y;
    const double d = dmath::hypot(dx, dy);
    if (d > 0.0) {
      heading = Heading{true, dx / d, dy / d};
    }
    used |= 1ULL << static_cast<unsigned>(chosen.index[0]);
    if (chosen.index[1] >= 0) {
      used |= 1ULL << static_cast<unsigned>(chosen.index[1]);
    }
    score += chosen.log_posterior + config.level_reward;
    hyp.markers[static_cast<std::size_t>(level)] =
        MarkerObservation{true, chosen.region, chosen.index, chosen.log_posterior};
    hyp.last_marker = level;
    ++hyp.found_count;
    current = chosen;
  }
  return score;
}

// Mean luminance of a 5x5 patch, -1 outside the image.
double patch_luminance(const ImageView& image, double x, double y) noexcept {
  const int cx = static_cast<int>(std::lround(x));
  const int cy = static_cast<int>(std::lround(y));
  if (!image.valid() || cx < 2 || cy < 2 || cx + 2 >= image.width || cy + 2 >= image.height) {
    return -1.0;
  }
  double sum = 0.0;
  for (int dy = -2; dy <= 2; ++dy) {
    const std::uint8_t* p = image.row(cy + dy) + static_cast<std::ptrdiff_t>(3) * (cx - 2);
    for (int dx = 0; dx < 5; ++dx) {
      sum += 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
      p += 3;
    }
  }
  return sum / 25.0;
}

// Orientation cue of a chain (times `weight`): the shaft before marker 1
// is dark, the grasper after marker 5 is bright.
double orientation_log(const ImageView& image, double weight, const Interpretation& hyp) noexcept {
  if (hyp.found_count < 2) {
    return 0.0;
  }
  const Region& first = hyp.markers[static_cast<std::size_t>(hyp.first_marker)].region;
  const Region& second = hyp.markers[static_cast<std::size_t>(hyp.first_marker) + 1U].region;
  const Region& last = hyp.markers[static_cast<std::size_t>(hyp.last_marker)].region;
  const Region& before_last = hyp.markers[static_cast<std::size_t>(hyp.last_marker) - 1U].region;
  // Points well beyond each end of the chain, along the chain.
  const auto beyond = [&image](const Region& end, const Region& inner) noexcept {
    const double dx = end.centroid.x - inner.centroid.x;
    const double dy = end.centroid.y - inner.centroid.y;
    const double d = dmath::hypot(dx, dy);
    if (!(d > 0.0)) {
      return -1.0;
    }
    const double reach = 1.8 * end.extent_along(dx / d, dy / d) + 2.0;
    return patch_luminance(image, end.centroid.x + dx / d * reach, end.centroid.y + dy / d * reach);
  };
  const double base = hyp.first_marker == 0 ? beyond(first, second) : -1.0;
  const double tip = hyp.last_marker == kNumMarkers - 1 ? beyond(last, before_last) : -1.0;
  constexpr double kMidGrey = 90.0;
  double cue = 0.0;
  if (base >= 0.0 && tip >= 0.0) {
    cue = (tip - base) / 40.0;
  } else if (base >= 0.0) {
    cue = (kMidGrey - base) / 40.0;
  } else if (tip >= 0.0) {
    cue = (tip - kMidGrey) / 40.0;
  }
  cue = cue > 1.0 ? 1.0 : (cue < -1.0 ? -1.0 : cue);
  return weight * cue;
}

}  // namespace

Result<std::unique_ptr<Interpreter>, VisionError> Interpreter::create(const InterpretationConfig& config) noexcept {
  using R = Result<std::unique_ptr<Interpreter>, VisionError>;
  for (const PixelClass cls : config.marker_classes) {
    if (cls != PixelClass::Blue && cls != PixelClass::Yellow) {
      return R::failure(VisionError::BadParameter);
    }
  }
  if (!(config.max_link_angle_rad > 0.0) || !(config.adjacency_factor > 0.0) ||
      !(config.adjacency_slack_px >= 0.0) || !std::isfinite(config.level_reward) ||
      !std::isfinite(config.orientation_weight)) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<Interpreter> interpreter(new (std::nothrow) Interpreter());
  if (interpreter == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  interpreter->config_ = config;
  return R::success(std::move(interpreter));
}

Status<VisionError> Interpreter::interpret(const RegionSet& region_set, const ImageView& image,
                                           const MarkerPriors& priors, Interpretation& out) const noexcept {
  out = Interpretation{};
  const auto& regions = region_set.regions;
  const std::size_t n = regions.size();

  Interpretation best{};
  double best_score = kNegligible;
  // Roots: every region, and every region merged with one adjacent region of
  // its colour (a virtual node at the first level too: the base marker split
  // by a highlight along the tube is as common as any other).
  // One loop over the pairs (root, partner), partner >= root; partner ==
  // root is the region alone.
  for (std::size_t pair = 0U; pair < n * n; ++pair) {
    const std::size_t root = pair / n;
    const std::size_t partner = pair % n;
    if (partner < root || (partner != root && (regions[partner].cls != regions[root].cls ||
                                               !adjacent(regions[root], regions[partner], config_)))) {
      continue;
    }
    for (int start = 0; start < kNumMarkers; ++start) {
      if (regions[root].cls != level_class(config_, start)) {
        continue;
      }
      Interpretation hyp{};
      double score = grow_hypothesis(regions, config_, priors, root, partner, start, hyp);
      score += orientation_log(image, config_.orientation_weight, hyp);
      if (score > best_score) {
        best_score = score;
        hyp.score = score;
        best = hyp;
      }
    }
  }
  out = best;
  if (out.found_count == 0) {
    return Status<VisionError>::failure(VisionError::NoInstrument);
  }
  return ok_status<VisionError>();
}

// --- priors ----------------------------------------------------------------

namespace {

// Predicted appearance of each marker at configuration r.
MarkerPriors predict(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                     const solver::PoseVector& r, double relative_sd, double absolute_sd_px,
                     double centroid_sd_px) noexcept {
  MarkerPriors p;
  const solver::PoseFrames frames = model.frames(r);
  const auto& g = model.geometry();
  solver::Vec2 previous_centre(0.0, 0.0);
  bool previous_ok = false;
  for (int m = 0; m < kNumMarkers; ++m) {
    MarkerPrior& mp = p.marker[static_cast<std::size_t>(m)];
    const double s0 = g.boundaries_mm[static_cast<std::size_t>(m)];
    const double s1 = g.boundaries_mm[static_cast<std::size_t>(m) + 1U];
    const solver::CentrelineFrame c0 = model.centreline(frames, s0);
    const solver::CentrelineFrame c1 = model.centreline(frames, s1);
    const solver::CentrelineFrame cm = model.centreline(frames, 0.5 * (s0 + s1));
    solver::Vec2 p0, p1, pm;
    const bool ok = camera.project(c0.position, p0) && camera.project(c1.position, p1) &&
                    camera.project(cm.position, pm);
    if (!ok) {
      mp.in_image = false;
      mp.half_major = 10.0;
      mp.half_major_sd = 1e3;
      mp.half_minor = 10.0;
      mp.half_minor_sd = 1e3;
      mp.parent_distance = 20.0;
      mp.parent_distance_sd = 1e3;
      previous_ok = false;
      continue;
    }
    // Apparent width: the tube's radius seen at the marker's middle, across the
    // image direction of the axis.
    const double length_px = (p1 - p0).norm();
    solver::Vec2 axis = p1 - p0;
    if (axis.norm() > 1e-9) {
      axis.normalize();
    } else {
      axis = solver::Vec2(1.0, 0.0);
    }
    const double depth = cm.position.z();
    const double width_px = 2.0 * g.radius_mm * camera.intrinsics().fx / (depth > 1.0 ? depth : 1.0);
    // A uniform rectangle l x w has half axes l/sqrt(3), w/sqrt(3) in the
    // second-moment sense used by Region.
    const double along = length_px / std::sqrt(3.0);
    const double across = width_px / std::sqrt(3.0);
    mp.half_major = along > across ? along : across;
    mp.half_minor = along > across ? across : along;
    mp.half_major_sd = relative_sd * mp.half_major + absolute_sd_px;
    mp.half_minor_sd = relative_sd * mp.half_minor + absolute_sd_px;
    if (previous_ok) {
      mp.parent_distance = (pm - previous_centre).norm();
      mp.parent_distance_sd = relative_sd * mp.parent_distance + absolute_sd_px;
    } else {
      mp.parent_distance = length_px;
      mp.parent_distance_sd = 1e3;
    }
    mp.centroid = Point{pm.x(), pm.y()};
    mp.centroid_sd = centroid_sd_px;
    mp.in_image = camera.in_image(pm);
    previous_centre = pm;
    previous_ok = true;
  }
  return p;
}

}  // namespace

MarkerPriors generic_priors(const solver::CameraModel& camera, const solver::InstrumentModel& model) noexcept {
  // The nominal channel pose, the instrument half out (lambda = 25 mm),
  // straight and unrotated: sizes are judged loosely (sd 60 % of the value)
  // and the position only very weakly (sd 40 % of the image diagonal), which
  // tells the base from the tip when nothing else does.
  const solver::PoseVector r = model.geometry().nominal_pose(25.0, 0.0, 0.0);
  const double diagonal = dmath::hypot(static_cast<double>(camera.width()), static_cast<double>(camera.height()));
  MarkerPriors p = predict(camera, model, r, 0.6, 3.0, 0.4 * diagonal);
  for (auto& m : p.marker) {
    m.parent_distance_sd = 1e3;  // the relative distance term does the work
    m.in_image = true;
  }
  p.relative_only = true;
  return p;
}

MarkerPriors model_priors(const solver::CameraModel& camera, const solver::InstrumentModel& model,
                          const solver::PoseVector& r) noexcept {
  // The encoders' r is off by a few millimetres and degrees (the play): sizes
  // within 30 %, positions within ~ 12 % of the image diagonal.
  const double diagonal = dmath::hypot(static_cast<double>(camera.width()), static_cast<double>(camera.height()));
  MarkerPriors p = predict(camera, model, r, 0.3, 2.0, 0.12 * diagonal);
  p.relative_only = false;
  return p;
}

void TemporalPriors::add(const Interpretation& interpretation) noexcept {
  Entry& e = entries_[static_cast<std::size_t>(next_)];
  for (std::size_t m = 0U; m < static_cast<std::size_t>(kNumMarkers); ++m) {
    e.found[m] = interpretation.markers[m].found;
    e.region[m] = interpretation.markers[m].region;
  }
  next_ = (next_ + 1) % kHistory;
  if (count_ < kHistory) {
    ++count_;
  }
}

bool TemporalPriors::priors(MarkerPriors& out) const noexcept {
  if (count_ < kMinFrames) {
    return false;
  }
  MarkerPriors p;
  p.relative_only = false;
  for (std::size_t m = 0U; m < static_cast<std::size_t>(kNumMarkers); ++m) {
    double n = 0.0, s_major = 0.0, s_minor = 0.0, s_d = 0.0, s_x = 0.0, s_y = 0.0;
    double q_major = 0.0, q_minor = 0.0, q_d = 0.0, q_pos = 0.0;
    double n_d = 0.0;
    for (int i = 0; i < count_; ++i) {
      const Entry& e = entries_[static_cast<std::size_t>(i)];
      if (!e.found[m]) {
        continue;
      }
      const Region& r = e.region[m];
      n += 1.0;
      s_major += r.half_major;
      s_minor += r.half_minor;
      s_x += r.centroid.x;
      s_y += r.centroid.y;
      q_major += r.half_major * r.half_major;
      q_minor += r.half_minor * r.half_minor;
      if (m > 0U && e.found[m - 1U]) {
        const double d = dmath::hypot(r.centroid.x - e.region[m - 1U].centroid.x,
                                    r.centroid.y - e.region[m - 1U].centroid.y);
        n_d += 1.0;
        s_d += d;
        q_d += d * d;
      }
    }
    MarkerPrior& mp = p.marker[m];
    if (n < 1.0) {
      mp.half_major = 10.0;
      mp.half_major_sd = 1e3;
      mp.half_minor = 10.0;
      mp.half_minor_sd = 1e3;
      mp.parent_distance = 20.0;
      mp.parent_distance_sd = 1e3;
      mp.in_image = false;
      continue;
    }
    mp.half_major = s_major / n;
    mp.half_minor = s_minor / n;
    mp.centroid = Point{s_x / n, s_y / n};
    for (int i = 0; i < count_; ++i) {
      const Entry& e = entries_[static_cast<std::size_t>(i)];
      if (e.found[m]) {
        q_pos += sq(e.region[m].centroid.x - mp.centroid.x) + sq(e.region[m].centroid.y - mp.centroid.y);
      }
    }
    // Sample spread plus a floor: the instrument moves between frames.
    const auto sd = [n](double sum, double sum_sq, double floor) noexcept {
      const double mean = sum / n;
      const double var = sum_sq / n - mean * mean;
      return std::sqrt((var > 0.0 ? var : 0.0) + floor * floor);
    };
    mp.half_major_sd = sd(s_major, q_major, 0.15 * mp.half_major + 2.0);
    mp.half_minor_sd = sd(s_minor, q_minor, 0.15 * mp.half_minor + 2.0);
    if (n_d >= 1.0) {
      mp.parent_distance = s_d / n_d;
      const double mean = s_d / n_d;
      const double var = q_d / n_d - mean * mean;
      mp.parent_distance_sd = std::sqrt((var > 0.0 ? var : 0.0) + sq(0.15 * mean + 2.0));
    } else {
      mp.parent_distance = 20.0;
      mp.parent_distance_sd = 1e3;
    }
    mp.centroid_sd = std::sqrt(q_pos / n) + 25.0;
    mp.in_image = true;
  }
  out = p;
  return true;
}

}  // namespace vision
}  // namespace tcpest
