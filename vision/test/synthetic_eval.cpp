// vision_synthetic_eval: scores the extraction on frames rendered in-process by
// the test scene (no dataset files needed), and trains the default colour model.
//   vision_synthetic_eval train            prints a colour model trained on rendered frames
//   vision_synthetic_eval eval [lab|hard] [--prior] [--every N] [--verbose]
// Measured numbers are reported in docs/vision.md.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

#include "synthetic_scene.hpp"
#include "tcpest/render/dataset.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/vision/features.hpp"
#include "tcpest/vision/overlay.hpp"

using namespace tcpest;
using namespace tcpest::vision;

namespace {

int train() {
  const auto camera = solver::CameraModel::create(solver::default_pal_camera()).value();
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
  test::Scene scene(camera, model);
  const auto grid = test::reference_grid(camera, model, 8);
  ColorTrainer trainer;
  std::vector<std::uint8_t> pixels;
  std::vector<PixelClass> classes;
  std::vector<std::vector<std::uint8_t>> frames;
  std::vector<std::vector<PixelClass>> labels;
  for (std::size_t i = 0U; i < grid.size(); i += 9U) {
    test::SceneStyle style;
    style.noise_sd = 2.0 + static_cast<double>(i % 4U);
    style.seed = static_cast<std::uint32_t>(i + 7U);
    test::Truth truth;
    scene.render(grid[i], style, pixels, truth, &classes);
    frames.push_back(pixels);
    labels.push_back(classes);
  }
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t f = 0U; f < frames.size(); ++f) {
      const auto& px = frames[f];
      const auto& cl = labels[f];
      const int w = camera.width();
      const int h = camera.height();
      for (int y = 1; y + 1 < h; ++y) {
        for (int x = 1; x + 1 < w; ++x) {
          const std::size_t i = static_cast<std::size_t>(y * w + x);
          // Pixels whose 3x3 neighbourhood is one class: mixed edge pixels are
          // neither training nor background samples.
          bool pure = true;
          for (int dy = -1; dy <= 1 && pure; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              if (cl[static_cast<std::size_t>((y + dy) * w + x + dx)] != cl[i]) {
                pure = false;
                break;
              }
            }
          }
          if (!pure) {
            continue;
          }
          if (pass == 0) {
            trainer.add_sample(cl[i], px[3 * i], px[3 * i + 1], px[3 * i + 2]);
          } else {
            trainer.add_threshold_sample(cl[i], px[3 * i], px[3 * i + 1], px[3 * i + 2]);
          }
        }
      }
    }
    if (pass == 0 && !trainer.finish_gaussians()) {
      std::fprintf(stderr, "training failed\n");
      return 1;
    }
  }
  char text[1024];
  const std::size_t n = format_color_model(trainer.finish(), text, sizeof text);
  std::fwrite(text, 1, n, stdout);
  return 0;
}

const char* g_dump = nullptr;
int g_dump_index = -1;

int eval(bool hard, bool use_prior, int every, bool verbose) {
  const auto camera = solver::CameraModel::create(solver::default_pal_camera()).value();
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{}).value();
  test::Scene scene(camera, model);
  auto grid = test::reference_grid(camera, model, 8);
  ExtractorConfig config;
  auto extractor = FeatureExtractor::create(config, default_color_model());
  if (!extractor.ok()) {
    std::fprintf(stderr, "create: %s\n", to_string(extractor.error()));
    return 1;
  }
  FeatureExtractor& fx = *extractor.value();
  std::mt19937 rng(42U);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::vector<std::uint8_t> pixels;
  long visible = 0, found_ok = 0, wrong = 0, found_total = 0;
  int frames = 0, successes = 0;
  std::vector<double> errors;
  std::vector<double> times_us;
  for (std::size_t i = 0U; i < grid.size(); i += static_cast<std::size_t>(every)) {
    solver::PoseVector r = grid[i];
    test::SceneStyle style;
    if (hard) {
      // Play of the mechanical parameters, noise, colour and light changes.
      r[solver::kXch] += 1.5 * unit(rng);
      r[solver::kYch] += 1.5 * unit(rng);
      r[solver::kPsi] += solver::deg_to_rad(3.0) * unit(rng);
      r[solver::kMu] += solver::deg_to_rad(3.0) * unit(rng);
      style.noise_sd = 6.0;
      style.ambient = 0.2 + 0.2 * std::fabs(unit(rng));
      style.tissue_texture = 30.0;
      style.seed = static_cast<std::uint32_t>(i + 1U);
    }
    test::Truth truth;
    scene.render(r, style, pixels, truth);
    if (truth.visible_count == 0) {
      continue;
    }
    solver::PoseVector prior_r = grid[i];
    prior_r[solver::kLambda] += 3.0 * unit(rng);
    prior_r[solver::kPhi] += 0.2 * unit(rng);
    prior_r[solver::kTheta] += 0.2 * unit(rng);
    const MarkerPriors priors = use_prior ? model_priors(camera, model, prior_r) : generic_priors(camera, model);
    const auto t0 = std::chrono::steady_clock::now();
    const auto status = fx.extract(scene.view(pixels), priors);
    const auto t1 = std::chrono::steady_clock::now();
    times_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    ++frames;
    const Extraction& e = fx.result();
    int frame_ok = 0;
    for (std::size_t k = 0U; k < 12U; ++k) {
      const Corner& c = e.corners[k];
      if (c.found) {
        ++found_total;
      }
      if (!truth.visible[k]) {
        continue;
      }
      ++visible;
      if (!c.found) {
        continue;
      }
      const double err = std::hypot(c.pixel.x - truth.corners.pixel[k].x(), c.pixel.y - truth.corners.pixel[k].y());
      if (err <= 1.5) {
        ++found_ok;
        ++frame_ok;
        errors.push_back(err);
      } else {
        ++wrong;
      }
    }
    if (frame_ok * 10 >= truth.visible_count * 8) {
      ++successes;
    }
    if (g_dump != nullptr) {
      std::vector<std::uint8_t> copy = pixels;
      const MutableImageView mv{copy.data(), camera.width(), camera.height(), static_cast<std::size_t>(camera.width()) * 3U};
      ReprojectedModel rm;
      rm.valid = true;
      for (std::size_t k = 0U; k < 12U; ++k) {
        rm.present[k] = truth.corners.in_image[k];
        rm.corners[k] = Point{truth.corners.pixel[k].x(), truth.corners.pixel[k].y()};
      }
      draw_extraction(mv, e, rm);
      for (int s = 0; s < e.skeleton_count; ++s) {
        draw_pixel(mv, static_cast<int>(e.skeleton[static_cast<std::size_t>(s)].x), static_cast<int>(e.skeleton[static_cast<std::size_t>(s)].y), 0, 0, 0);
      }
      char path[512];
      std::snprintf(path, sizeof path, "%s/frame_%03zu.ppm", g_dump, i);
      FILE* f = std::fopen(path, "wb");
      if (f != nullptr) {
        std::fprintf(f, "P6\n%d %d\n255\n", camera.width(), camera.height());
        std::fwrite(copy.data(), 1, copy.size(), f);
        std::fclose(f);
      }
    }
    if (verbose) {
      std::printf("edge points %zu %zu\n", e.borders[0].points.size(), e.borders[1].points.size());
      std::printf("frame %zu lambda %.1f phi %.0f theta %.0f: status %s, markers %d-%d, visible %d ok %d, found %d\n",
                  i, r[solver::kLambda], solver::rad_to_deg(r[solver::kPhi]), solver::rad_to_deg(r[solver::kTheta]),
                  status.ok() ? "ok" : to_string(status.error()), e.interpretation.first_marker + 1,
                  e.interpretation.last_marker + 1, truth.visible_count, frame_ok, e.corner_count);
      for (std::size_t k = 0U; k < 12U; ++k) {
        if (truth.visible[k] || e.corners[k].found) {
          std::printf("   k=%2zu vis %d truth (%.2f, %.2f) found %d (%.2f, %.2f)\n", k, truth.visible[k] ? 1 : 0,
                      truth.corners.pixel[k].x(), truth.corners.pixel[k].y(), e.corners[k].found ? 1 : 0,
                      e.corners[k].pixel.x, e.corners[k].pixel.y);
        }
      }
    }
  }
  std::sort(errors.begin(), errors.end());
  std::sort(times_us.begin(), times_us.end());
  const double median = errors.empty() ? 0.0 : errors[errors.size() / 2U];
  std::printf("frames %d, visible corners %ld: found and labelled within 1.5 px %.1f %%, median error %.3f px, "
              "wrong (found > 1.5 px off) %.2f %% of found, frame success (>= 80 %%) %.1f %%, extract median %.0f us\n",
              frames, visible, 100.0 * static_cast<double>(found_ok) / static_cast<double>(visible > 0 ? visible : 1),
              median, 100.0 * static_cast<double>(wrong) / static_cast<double>(found_total > 0 ? found_total : 1),
              100.0 * successes / (frames > 0 ? frames : 1), times_us.empty() ? 0.0 : times_us[times_us.size() / 2U]);
  return 0;
}

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
  if (argc >= 2 && std::strcmp(argv[1], "train") == 0) {
    return train();
  }
  if (argc >= 2 && std::strcmp(argv[1], "render") == 0) {
    ExtractorConfig config;
    int count = 294, every = 5;
    bool verbose = false;
    for (int i = 2; i < argc; ++i) {
      if (std::strcmp(argv[i], "--insets") == 0 && i + 2 < argc) {
        config.profile_min_inset_px = std::atof(argv[++i]);
        config.profile_max_inset = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--every") == 0 && i + 1 < argc) {
        every = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--extension") == 0 && i + 1 < argc) {
        config.skeleton_extension = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--samples") == 0 && i + 1 < argc) {
        config.skeleton_samples = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--tukey") == 0 && i + 1 < argc) {
        config.tukey_c = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--dump-index") == 0 && i + 1 < argc) {
        g_dump_index = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--min-confidence") == 0 && i + 1 < argc) {
        config.min_corner_confidence = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--end-margin") == 0 && i + 1 < argc) {
        config.end_margin_px = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--local") == 0 && i + 1 < argc) {
        config.local_border_window = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--edge-offset") == 0 && i + 1 < argc) {
        config.edge_offset_px = std::atof(argv[++i]);
      } else if (std::strcmp(argv[i], "--count") == 0 && i + 1 < argc) {
        count = std::atoi(argv[++i]);
      } else if (std::strcmp(argv[i], "--verbose") == 0) {
        verbose = true;
      } else if (std::strcmp(argv[i], "--orientation") == 0 && i + 1 < argc) {
        config.orientation_weight = std::atof(argv[++i]);
      }
    }
    return eval_render(count, every, verbose, config);
  }
  if (argc >= 2 && std::strcmp(argv[1], "eval") == 0) {
    bool hard = false, prior = false, verbose = false;
    int every = 1;
    for (int i = 2; i < argc; ++i) {
      if (std::strcmp(argv[i], "hard") == 0) {
        hard = true;
      } else if (std::strcmp(argv[i], "--prior") == 0) {
        prior = true;
      } else if (std::strcmp(argv[i], "--verbose") == 0) {
        verbose = true;
      } else if (std::strcmp(argv[i], "--dump") == 0 && i + 1 < argc) {
        g_dump = argv[++i];
      } else if (std::strcmp(argv[i], "--every") == 0 && i + 1 < argc) {
        every = std::atoi(argv[++i]);
      }
    }
    return eval(hard, prior, every < 1 ? 1 : every, verbose);
  }
  std::fprintf(stderr, "usage: vision_synthetic_eval train | eval [lab|hard] [--prior] [--every N] [--verbose]\n");
  return 2;
}
