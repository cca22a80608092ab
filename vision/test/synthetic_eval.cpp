// vision_synthetic_eval: scores the extraction on lab frames rendered
// in-process by hal/render (raw pixels, no files), with the encoder priors of
// the dataset, and splits each corner's error across / along its border.
//   vision_synthetic_eval render [--count N] [--every N] [--verbose] [--dump-index I]
//                                [--insets MIN MAX] [--edge-offset PX] [--local W] [--end-margin PX]
//                                [--extension F] [--samples N] [--tukey C] [--min-confidence C]
// --dump-index writes that frame's overlay with the true corners to /tmp/dump.png.
// Measured numbers are reported in docs/vision.md.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "tcpest/render/dataset.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/vision/features.hpp"
#include "tcpest/vision/overlay.hpp"

using namespace tcpest;
using namespace tcpest::vision;

namespace {

int g_dump_index = -1;

int eval_render(int count, int every, bool verbose, const ExtractorConfig& config) {
  const auto camera = solver::CameraModel::create(solver::default_pal_camera()).value();
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
  auto created = render::Renderer::create(camera, model, render::RenderSettings{});
  auto renderer = std::move(created.value());
  auto made = FeatureExtractor::create(config, default_color_model());
  FeatureExtractor& fx = *made.value();
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(camera.width() * camera.height() * 3));
  const MutableImageView out{pixels.data(), camera.width(), camera.height(), static_cast<std::size_t>(camera.width()) * 3U};
  long visible = 0, ok = 0, found = 0;
  std::vector<double> along, across, errs, signed_across, scales;
  for (int index = 0; index < count; index += every) {
    const render::LabSample ls = render::lab_sample(model.geometry(), index, 1U);
    render::SceneSpec spec;
    spec.r = ls.r;
    spec.seed = render::image_seed(1U, static_cast<std::uint64_t>(index));
    render::GroundTruth truth;
    if (!renderer->render(spec, out, truth).ok()) {
      continue;
    }
    const auto& t = truth.instruments[0];
    const solver::PoseVector prior_r = model.geometry().nominal_pose(ls.prior.joints[0], ls.prior.joints[1], ls.prior.joints[2]);
    const auto status = fx.extract(out.view(), model_priors(camera, model, prior_r));
    const Extraction& e = fx.result();
    if (index == g_dump_index) {
      std::vector<std::uint8_t> copy = pixels;
      const MutableImageView mv{copy.data(), camera.width(), camera.height(), static_cast<std::size_t>(camera.width()) * 3U};
      ReprojectedModel rm;
      rm.valid = true;
      for (std::size_t k = 0U; k < 12U; ++k) {
        rm.present[k] = t.in_image[k];
        rm.corners[k] = Point{t.corners[k].x(), t.corners[k].y()};
      }
      draw_extraction(mv, e, rm);
      static_cast<void>(render::write_png_file(mv.view(), "/tmp/dump.png"));
    }
    for (const Border& b : e.borders) {
      if (b.valid) {
        scales.push_back(b.scale_px);
      }
    }
    for (std::size_t k = 0U; k < 12U; ++k) {
      if (!t.visible[k]) {
        continue;
      }
      ++visible;
      if (!e.corners[k].found) {
        continue;
      }
      ++found;
      const double ex = e.corners[k].pixel.x - t.corners[k].x();
      const double ey = e.corners[k].pixel.y - t.corners[k].y();
      const double err = std::hypot(ex, ey);
      if (err <= 1.5) {
        ++ok;
      }
      errs.push_back(err);
      // Split the error along / across the border of that side.
      const Border& b = e.borders[k % 2U];
      // nearest t on the curve to the truth
      double best = 1e30, bt = 0.0;
      for (int i = -100; i <= 1100; ++i) {
        const Point p = b.curve.at(i / 1000.0);
        const double d = std::hypot(p.x - t.corners[k].x(), p.y - t.corners[k].y());
        if (d < best) {
          best = d;
          bt = i / 1000.0;
        }
      }
      {
        const Point dd = b.curve.derivative(bt);
        const double dl = std::hypot(dd.x, dd.y);
        const double sgn = (k % 2U) == 1U ? 1.0 : -1.0;
        const double onx = sgn * (-dd.y / dl), ony = sgn * (dd.x / dl);
        const Point pc = b.curve.at(bt);
        // > 0: the truth lies outside the fitted border.
        signed_across.push_back((t.corners[k].x() - pc.x) * onx + (t.corners[k].y() - pc.y) * ony);
      }
      across.push_back(best);
      const Point p = b.curve.at(bt);
      along.push_back(std::hypot(e.corners[k].pixel.x - p.x, e.corners[k].pixel.y - p.y));
      if (verbose) {
        std::printf("img %d k %zu err %.2f across %.2f along %.2f conf %.3f\n", index, k, err, best, along.back(), e.corners[k].confidence);
      }
    }
    if (verbose && !status.ok()) {
      std::printf("img %d: %s\n", index, to_string(status.error()));
    }
  }
  std::sort(along.begin(), along.end());
  std::sort(across.begin(), across.end());
  std::sort(errs.begin(), errs.end());
  const auto med = [](const std::vector<double>& v) { return v.empty() ? 0.0 : v[v.size() / 2U]; };
  std::sort(signed_across.begin(), signed_across.end());
  std::sort(scales.begin(), scales.end());
  std::printf("Bezier MAD scale median %.3f px\n", med(scales));
  std::printf("signed across (truth outside > 0): median %.3f, q25 %.3f, q75 %.3f\n", med(signed_across),
              signed_across.empty() ? 0.0 : signed_across[signed_across.size() / 4U],
              signed_across.empty() ? 0.0 : signed_across[3U * signed_across.size() / 4U]);
  std::printf("render lab: visible %ld, found %ld, within 1.5 px %.1f %%, median error %.2f, across-border median %.2f, along %.2f\n",
              visible, found, 100.0 * static_cast<double>(ok) / static_cast<double>(visible > 0 ? visible : 1), med(errs), med(across), med(along));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "render") == 0) {
    ExtractorConfig config;
    int count = 294, every = 5;
    bool verbose = false;
    for (int i = 2; i < argc; ++i) {
      if (std::strcmp(argv[i], "--insets") == 0 && i + 2 < argc) {
        config.corners.profile_min_inset_px = std::atof(argv[++i]);
        config.corners.profile_max_inset = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--every") == 0 && i + 1 < argc) {
        every = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--extension") == 0 && i + 1 < argc) {
        config.borders.skeleton_extension = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--samples") == 0 && i + 1 < argc) {
        config.borders.skeleton_samples = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--tukey") == 0 && i + 1 < argc) {
        config.borders.tukey_c = std::atof(argv[++i]);
        config.corners.tukey_c = config.borders.tukey_c;  // the local borders too
      } else if (std::strcmp(argv[i], "--dump-index") == 0 && i + 1 < argc) {
        g_dump_index = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--min-confidence") == 0 && i + 1 < argc) {
        config.corners.min_corner_confidence = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--end-margin") == 0 && i + 1 < argc) {
        config.corners.end_margin_px = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--local") == 0 && i + 1 < argc) {
        config.corners.local_border_window = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--edge-offset") == 0 && i + 1 < argc) {
        config.borders.edge_offset_px = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--count") == 0 && i + 1 < argc) {
        count = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--verbose") == 0) {
        verbose = true;
      } else if (std::strcmp(argv[i], "--orientation") == 0 && i + 1 < argc) {
        config.interpretation.orientation_weight = std::atof(argv[++i]);
      }
    }
    return eval_render(count, every, verbose, config);
  }
  std::fprintf(stderr, "usage: vision_synthetic_eval render [--count N] [--every N] [--verbose] [--dump-index I] [tuning options]\n");
  return 2;
}
