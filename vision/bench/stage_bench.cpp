// vision_bench: time of the extraction stages on rendered frames, and stage 1
// against OpenCV doing the same work (cvtColor to L*a*b*, a per-pixel
// Mahalanobis test for both colours, connectedComponentsWithStats per colour).
// Compare the rows of one run side by side; the machine's load matters.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include "tcpest/render/renderer.hpp"
#include "tcpest/vision/features.hpp"

#ifdef TCPEST_BENCH_OPENCV
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#endif

namespace {

using namespace tcpest;

struct Frame {
  solver::CameraModel camera;
  solver::InstrumentModel model;
  std::vector<std::uint8_t> pixels;
  solver::PoseVector r;
  ImageView view() const {
    return ImageView{pixels.data(), camera.width(), camera.height(), static_cast<std::size_t>(camera.width()) * 3U};
  }
};

// A rendered lab-like frame at the given size (the PAL camera's field of
// view scaled to the size).
Frame make_frame(int width, int height) {
  solver::CameraIntrinsics k = solver::default_pal_camera();
  const double scale = static_cast<double>(width) / static_cast<double>(k.width);
  k.width = width;
  k.height = height;
  k.fx *= scale;
  k.fy *= scale;
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  Frame f{solver::CameraModel::create(k).value(), solver::InstrumentModel::create(solver::InstrumentGeometry{}).value(),
          {}, solver::PoseVector::Zero()};
  f.pixels.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3U);
  auto created = render::Renderer::create(f.camera, f.model, render::RenderSettings{});
  auto renderer = std::move(created.value());
  render::SceneSpec spec;
  spec.r = f.model.geometry().nominal_pose(25.0, 0.5, 0.6);
  f.r = spec.r;
  render::GroundTruth truth;
  const MutableImageView out{f.pixels.data(), width, height, static_cast<std::size_t>(width) * 3U};
  static_cast<void>(renderer->render(spec, out, truth));  // a failed render leaves a black frame: still timed
  return f;
}

const Frame& pal_frame() {
  static const Frame f = make_frame(720, 576);
  return f;
}
const Frame& hd_frame() {
  static const Frame f = make_frame(1920, 1080);
  return f;
}

// classify_step: 0 = the auto rule (2 for 1920x1080), 1 = every pixel.
std::unique_ptr<vision::FeatureExtractor> make_extractor(int classify_step = 0) {
  vision::ExtractorConfig config;
  config.regions.classify_step = classify_step;
  auto created = vision::FeatureExtractor::create(config, vision::default_color_model());
  std::unique_ptr<vision::FeatureExtractor> extractor = std::move(created.value());
  return extractor;
}

void BM_Stage1_Ours_720x576(benchmark::State& state) {
  const Frame& f = pal_frame();
  auto fx = make_extractor();
  for (auto _ : state) {
    benchmark::DoNotOptimize(fx->find_regions(f.view()).ok());
  }
  state.counters["runs"] = fx->result().regions.run_count;
  state.counters["regions"] = static_cast<double>(fx->result().regions.regions.size());
  state.counters["ambiguous_cells"] = fx->lut().ambiguous_cells();
  // Share of the frame's pixels whose cell is ambiguous (the second-level read).
  std::size_t ambiguous = 0U;
  const std::uint8_t* table = fx->lut().table();
  for (std::size_t i = 0U; i + 2U < f.pixels.size(); i += 3U) {
    ambiguous += table[vision::ClassifierLut::index(f.pixels[i], f.pixels[i + 1U], f.pixels[i + 2U])] ==
                         vision::ClassifierLut::kAmbiguous
                     ? 1U
                     : 0U;
  }
  const std::size_t pixel_count = f.pixels.size() / 3U;
  state.counters["ambiguous_pixels_pct"] = 100.0 * static_cast<double>(ambiguous) / static_cast<double>(pixel_count);
}
BENCHMARK(BM_Stage1_Ours_720x576)->Unit(benchmark::kMicrosecond);

// Stage 1 at 1920x1080: every pixel (step 1) and the auto rule's 2x2 grid.
void BM_Stage1_Ours_1920x1080(benchmark::State& state) {
  const Frame& f = hd_frame();
  auto fx = make_extractor(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    benchmark::DoNotOptimize(fx->find_regions(f.view()).ok());
  }
  state.counters["step"] = fx->classify_step();
  state.counters["runs"] = fx->result().regions.run_count;
  state.counters["regions"] = static_cast<double>(fx->result().regions.regions.size());
}
BENCHMARK(BM_Stage1_Ours_1920x1080)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

void run_all_stages(benchmark::State& state, const Frame& f, int classify_step = 0) {
  auto fx = make_extractor(classify_step);
  const vision::MarkerPriors priors = vision::model_priors(f.camera, f.model, f.r);
  int failure = -1;
  for (auto _ : state) {
    const auto status = fx->extract(f.view(), priors);
    failure = status.ok() ? -1 : static_cast<int>(status.error());
    benchmark::DoNotOptimize(failure);
  }
  state.counters["corners"] = fx->result().corner_count;
  state.counters["markers"] = fx->result().interpretation.found_count;
  state.counters["error"] = failure;
}

void BM_Stages1to4_720x576(benchmark::State& state) { run_all_stages(state, pal_frame()); }
BENCHMARK(BM_Stages1to4_720x576)->Unit(benchmark::kMicrosecond);

void BM_Stages1to4_1920x1080(benchmark::State& state) { run_all_stages(state, hd_frame(), static_cast<int>(state.range(0))); }
BENCHMARK(BM_Stages1to4_1920x1080)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

#ifdef TCPEST_BENCH_OPENCV
// The same stage-1 work with OpenCV: RGB -> L*a*b* (float, exact), the
// Mahalanobis test of both Gaussians per pixel, then connected components
// with statistics for each colour's mask.
void BM_Stage1_OpenCV_720x576(benchmark::State& state) {
  const Frame& f = pal_frame();
  const vision::ColorModel m = vision::default_color_model();
  cv::Mat rgb(f.camera.height(), f.camera.width(), CV_8UC3, const_cast<std::uint8_t*>(f.pixels.data()));  // NOLINT(cppcoreguidelines-pro-type-const-cast): OpenCV's Mat takes a non-const pointer, read only here
  cv::Mat rgb_float, lab, blue_mask(rgb.size(), CV_8U), yellow_mask(rgb.size(), CV_8U), labels, stats, centroids;
  const auto inverse = [](const vision::ColorGaussian& g, double& ia, double& ib, double& ic) {
    const double det = g.cov_aa * g.cov_bb - g.cov_ab * g.cov_ab;
    ia = g.cov_bb / det;
    ib = -g.cov_ab / det;
    ic = g.cov_aa / det;
  };
  double b0 = 0.0, b1 = 0.0, b2 = 0.0, y0 = 0.0, y1 = 0.0, y2 = 0.0;
  inverse(m.blue, b0, b1, b2);
  inverse(m.yellow, y0, y1, y2);
  const float tb = static_cast<float>(m.blue.threshold * m.blue.threshold);
  const float ty = static_cast<float>(m.yellow.threshold * m.yellow.threshold);
  for (auto _ : state) {
    rgb.convertTo(rgb_float, CV_32F, 1.0 / 255.0);
    cv::cvtColor(rgb_float, lab, cv::COLOR_RGB2Lab);
    for (int y = 0; y < lab.rows; ++y) {
      const cv::Vec3f* row = lab.ptr<cv::Vec3f>(y);
      std::uint8_t* bm = blue_mask.ptr<std::uint8_t>(y);
      std::uint8_t* ym = yellow_mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < lab.cols; ++x) {
        const float l = row[x][0];
        const float da = row[x][1] - static_cast<float>(m.blue.mean_a);
        const float db = row[x][2] - static_cast<float>(m.blue.mean_b);
        const float ea = row[x][1] - static_cast<float>(m.yellow.mean_a);
        const float eb = row[x][2] - static_cast<float>(m.yellow.mean_b);
        const float d2b = static_cast<float>(b0) * da * da + 2.0F * static_cast<float>(b1) * da * db + static_cast<float>(b2) * db * db;
        const float d2y = static_cast<float>(y0) * ea * ea + 2.0F * static_cast<float>(y1) * ea * eb + static_cast<float>(y2) * eb * eb;
        const bool bright = l >= static_cast<float>(m.min_lightness);
        bm[x] = (bright && d2b < tb && d2b / tb <= d2y / ty) ? 255U : 0U;
        ym[x] = (bright && bm[x] == 0U && d2y < ty) ? 255U : 0U;
      }
    }
    const int nb = cv::connectedComponentsWithStats(blue_mask, labels, stats, centroids, 8, CV_32S);
    const int ny = cv::connectedComponentsWithStats(yellow_mask, labels, stats, centroids, 8, CV_32S);
    benchmark::DoNotOptimize(nb + ny);
  }
}
BENCHMARK(BM_Stage1_OpenCV_720x576)->Unit(benchmark::kMicrosecond);
#endif

}  // namespace

BENCHMARK_MAIN();
