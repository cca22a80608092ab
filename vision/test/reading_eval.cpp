// vision_reading_eval: the model-guided readings at the true pose of every
// annotated frame of one or more datasets (ours, randomised or independent:
// docs/dataset-format.md). At the sidecar's r the model's silhouettes and
// boundaries lie exactly on the image's, so what a reader reports there is
// its own error, with no fit, solve or track in between (one frame's change
// cannot move the pose of the next): the instrument for comparing readers
// on both sources (docs/vision.md, "Reading accuracy at the true pose").
//   vision_reading_eval [--calib CAM.yaml] DATASET_DIR...
// Per dataset:
// - the silhouette reader (Refiner::edge) at the image fit's sample points
//   on the striped tube and the shaft: the share read, the share within
//   1 px of the true silhouette, the median offset (px, outwards) and its MAD;
// - refine_corners at r, per boundary j: the share of visible corners it
//   measures (a boundary arc read and the silhouette beside it), and of
//   those the share more than 0.7 px off along the tube and across it, and
//   the median signed offset along (px, towards the tip).
// Not a test; a tool (allocates freely).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "../src/fit_scratch.hpp"
#include "../src/refiner.hpp"
#include "cli/vision_run.hpp"
#include "tcpest/render/sidecar.hpp"
#include "tcpest/solver/config_io.hpp"
#include "tcpest/vision/color_model.hpp"
#include "tcpest/vision/features.hpp"

using namespace tcpest;
using solver::kNumBoundaries;
using solver::kNumCorners;

namespace {

constexpr double kGoodReadingPx = 1.0;  // a silhouette reading this close to the truth is good
constexpr double kCornerPartPx = 0.7;   // a corner's along / across part beyond this is off
constexpr int kMaxWidth = 1920;         // the largest frame decoded
constexpr int kMaxHeight = 1080;

double median(std::vector<double> v) {
  if (v.empty()) {
    return 0.0;
  }
  std::sort(v.begin(), v.end());
  return v[v.size() / 2U];
}

double mad(const std::vector<double>& v) {
  const double m = median(v);
  std::vector<double> d;
  d.reserve(v.size());
  for (const double x : v) {
    d.push_back(std::fabs(x - m));
  }
  return median(d);
}

struct SilhouetteTally {
  int sampled = 0;
  std::vector<double> offsets_px;
  void report(const char* name) const {
    const auto read = static_cast<int>(offsets_px.size());
    int good = 0;
    for (const double e : offsets_px) {
      good += std::fabs(e) <= kGoodReadingPx ? 1 : 0;
    }
    const double share = 100.0 / std::max(sampled, 1);
    std::printf("  silhouette, %-6s %6d sampled: read %5.1f %%, within %.1f px %5.1f %%, beyond %5.1f %%; "
                "median offset %+.3f px, MAD %.3f px\n",
                name, sampled, share * read, kGoodReadingPx, share * good, share * (read - good), median(offsets_px),
                mad(offsets_px));
  }
};

// The tube's silhouette reader with the model beside the truth: the sample
// point moved by d px along its normal (a fit not yet converged), where a
// good reader reports -d. How far a reader still points back to the
// silhouette says how it steers a fit from a start a few pixels off, which
// its accuracy at the truth alone does not.
constexpr std::array<double, 6> kModelOffsetsPx = {{-3.0, -2.0, -1.0, 1.0, 2.0, 3.0}};
struct BasinTally {
  std::array<int, kModelOffsetsPx.size()> sampled{};
  std::array<int, kModelOffsetsPx.size()> good{};
  void report() const {
    std::printf("  silhouette, tube, model off by d px: within %.1f px of the truth (of sampled)", kGoodReadingPx);
    for (std::size_t i = 0U; i < kModelOffsetsPx.size(); ++i) {
      std::printf("%s d %+.0f: %5.1f %%", i == 0U ? " " : ", ", kModelOffsetsPx[i], 100.0 * good[i] / std::max(sampled[i], 1));
    }
    std::printf("\n");
  }
};

struct BoundaryTally {
  int visible = 0;
  int measured = 0;
  int off_along = 0;
  int off_across = 0;
  std::vector<double> along_px;  // signed, towards the tip
};

// The silhouette reader at the image fit's sample points (image_fit.cpp).
void read_silhouettes(const vision::detail::Refiner& refiner, const vision::ExtractorConfig& config,
                      const solver::CameraModel& camera, const solver::InstrumentModel& model,
                      const solver::PoseFrames& f, double lambda_mm, SilhouetteTally& tube, SilhouetteTally& shaft,
                      BasinTally& basin) {
  const double window_px = config.refiner.refine_edge_search_px;
  const double length_mm = model.geometry().bend_length_mm;
  for (std::size_t side = 0U; side < 2U; ++side) {
    for (int i = 0; i < vision::detail::kFitSilhouetteSamples; ++i) {
      const double s = vision::detail::fit_silhouette_s_mm(length_mm, i);
      solver::Vec2 p;
      solver::Vec2 n;
      double e = 0.0;
      if (!vision::detail::silhouette_at(camera, model, f, s, side, p, n) || !camera.in_image(p)) {
        continue;
      }
      ++tube.sampled;
      if (refiner.edge(p, n, window_px, e)) {
        tube.offsets_px.push_back(e);
      }
      for (std::size_t k = 0U; k < kModelOffsetsPx.size(); ++k) {
        const solver::Vec2 moved = p + kModelOffsetsPx[k] * n;
        if (!camera.in_image(moved)) {
          continue;
        }
        ++basin.sampled[k];
        if (refiner.edge(moved, n, window_px, e)) {
          basin.good[k] += std::fabs(e + kModelOffsetsPx[k]) <= kGoodReadingPx ? 1 : 0;
        }
      }
    }
    for (int i = 0; i < vision::detail::kFitShaftSamples; ++i) {
      const double back = vision::detail::fit_shaft_back_mm(i);
      solver::Vec2 p;
      solver::Vec2 n;
      double e = 0.0;
      if (back > lambda_mm - 1.0) {
        break;
      }
      if (!vision::detail::shaft_silhouette_at(camera, model, f, back, side, p, n) || !camera.in_image(p)) {
        continue;
      }
      ++shaft.sampled;
      if (refiner.edge(p, n, window_px, e)) {
        shaft.offsets_px.push_back(e);
      }
    }
  }
}

// refine_corners at the true pose, against the sidecar's corners.
void score_corners(const vision::Extraction& e, const render::SidecarInstrument& truth,
                   std::array<BoundaryTally, kNumBoundaries>& tally, double predicted_confidence) {
  for (std::size_t k = 0U; k < static_cast<std::size_t>(kNumCorners); ++k) {
    if (!truth.corner_visible[k]) {
      continue;
    }
    BoundaryTally& t = tally[k / 2U];
    ++t.visible;
    const vision::Corner& c = e.corners[k];
    if (!c.found || !(c.confidence > predicted_confidence)) {
      continue;
    }
    ++t.measured;
    // Along: towards the same side's corner of the next boundary, or from
    // the one before when the next is not given (a null corner's pixel is
    // not set: docs/dataset-format.md); neither given: no split.
    const bool next_given = k + 2U < static_cast<std::size_t>(kNumCorners) && truth.corner_present[k + 2U];
    const bool previous_given = k >= 2U && truth.corner_present[k - 2U];
    if (!next_given && !previous_given) {
      continue;
    }
    solver::Vec2 along = next_given ? solver::Vec2(truth.corners[k + 2U] - truth.corners[k])
                                    : solver::Vec2(truth.corners[k] - truth.corners[k - 2U]);
    if (!(along.norm() > 1e-9)) {
      continue;
    }
    along.normalize();
    const solver::Vec2 d(c.pixel.x - truth.corners[k].x(), c.pixel.y - truth.corners[k].y());
    const double a = d.dot(along);
    const double x = d.x() * along.y() - d.y() * along.x();
    t.off_along += std::fabs(a) > kCornerPartPx ? 1 : 0;
    t.off_across += std::fabs(x) > kCornerPartPx ? 1 : 0;
    t.along_px.push_back(a);
  }
}

int evaluate(const std::string& dir, const solver::CameraModel& camera, const solver::InstrumentModel& model,
             vision::FeatureExtractor& extractor, cli::ImageReader& reader) {
  const vision::ExtractorConfig& config = extractor.config();
  SilhouetteTally tube;
  SilhouetteTally shaft;
  BasinTally basin;
  std::array<BoundaryTally, kNumBoundaries> boundaries{};
  int frames = 0;
  std::vector<std::uint8_t> pixels;
  std::vector<std::string> sidecars;
  if (!cli::list_sidecars("vision_reading_eval", dir, sidecars)) {
    return 0;
  }
  for (const std::string& name : sidecars) {
    const std::string path = dir + "/" + name;
    const auto sidecar = render::read_sidecar_file(path.c_str());
    if (!sidecar.ok() || !sidecar.value().instrument.has_r) {
      continue;
    }
    const render::Sidecar& sc = sidecar.value();
    const std::string image_path = dir + "/" + sc.image;
    ImageView image{};
    char error[160] = {};
    if (!reader.read(image_path.c_str(), pixels, image, error, sizeof error)) {
      std::fprintf(stderr, "vision_reading_eval: %s: %s\n", image_path.c_str(), error);
      continue;
    }
    if (image.width != camera.width() || image.height != camera.height()) {
      std::fprintf(stderr, "vision_reading_eval: %s is %dx%d, the calibration's %dx%d (--calib)\n", image_path.c_str(),
                   image.width, image.height, camera.width(), camera.height());
      continue;
    }
    ++frames;
    const solver::PoseVector& r = sc.instrument.r;
    const solver::PoseFrames f = model.frames(r);
    const vision::detail::Refiner refiner(image, extractor.colors(), config, camera, model, f, nullptr);
    read_silhouettes(refiner, config, camera, model, f, r[solver::kLambda], tube, shaft, basin);
    if (extractor.refine_corners(image, camera, model, r).ok()) {
      score_corners(extractor.result(), sc.instrument, boundaries, config.refiner.refine_predicted_confidence);
    }
  }
  std::printf("%s: %d frames with a true pose\n", dir.c_str(), frames);
  if (frames == 0) {
    return 0;  // nothing to report
  }
  tube.report("tube");
  basin.report();
  shaft.report("shaft");
  // The colour boundaries together (the base's corners are never measured,
  // the tip's only when its arc shows a colour change), then each one.
  BoundaryTally colour;
  for (std::size_t j = 1U; j + 1U < static_cast<std::size_t>(kNumBoundaries); ++j) {
    colour.visible += boundaries[j].visible;
    colour.measured += boundaries[j].measured;
    colour.off_along += boundaries[j].off_along;
    colour.off_across += boundaries[j].off_across;
  }
  const double per_colour = 100.0 / std::max(colour.measured, 1);
  std::printf("  boundaries 1-4: %4d visible corners, measured %5.1f %%; of those off along %4.1f %%, across %4.1f %%\n",
              colour.visible, 100.0 * colour.measured / std::max(colour.visible, 1), per_colour * colour.off_along,
              per_colour * colour.off_across);
  for (std::size_t j = 1U; j < static_cast<std::size_t>(kNumBoundaries); ++j) {
    const BoundaryTally& t = boundaries[j];
    const double per_measured = 100.0 / std::max(t.measured, 1);
    std::printf("  boundary %zu: %4d visible corners, measured %5.1f %%; of those off along %4.1f %%, across %4.1f %%; "
                "along median %+.3f px\n",
                j, t.visible, 100.0 * t.measured / std::max(t.visible, 1), per_measured * t.off_along,
                per_measured * t.off_across, median(t.along_px));
  }
  return frames;
}

}  // namespace

int main(int argc, char** argv) {
  static yaml::Document calibration;  // large: static storage
  solver::CameraIntrinsics intrinsics = solver::default_pal_camera();
  int first = 1;
  if (argc >= 3 && std::strcmp(argv[1], "--calib") == 0) {
    const auto loaded = solver::load_camera_info(argv[2], calibration);
    if (!loaded.ok()) {
      std::fprintf(stderr, "vision_reading_eval: %s: %s\n", argv[2], loaded.error().message);
      return 2;
    }
    intrinsics = loaded.value();
    first = 3;
  }
  if (first >= argc) {
    std::fprintf(stderr, "usage: vision_reading_eval [--calib CAM.yaml] DATASET_DIR...\n");
    return 2;
  }
  const auto camera = solver::CameraModel::create(intrinsics);
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{});
  auto extractor = vision::FeatureExtractor::create(vision::ExtractorConfig{}, vision::default_color_model());
  cli::ImageReader reader;
  if (!camera.ok() || !model.ok() || !extractor.ok() || !reader.init(kMaxWidth, kMaxHeight)) {
    std::fprintf(stderr, "vision_reading_eval: set-up failed\n");
    return 1;
  }
  int frames = 0;
  for (int i = first; i < argc; ++i) {
    frames += evaluate(argv[i], camera.value(), model.value(), *extractor.value(), reader);
  }
  return frames > 0 ? 0 : 1;
}
