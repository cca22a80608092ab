// tcpest render: writes synthetic endoscopic images with their ground-truth
// sidecars (docs/dataset-format.md) through the simulated endoscope of
// hal/render. Sets: lab (model.md's 294-pose grid with play and prior),
// hard (the same poses with 1-3 hard cases each), seq (smooth motion),
// single (one image at --r).
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/setup.hpp"
#include "tcpest/render/dataset.hpp"
#include "tcpest/render/image_io.hpp"
#include "tcpest/render/renderer.hpp"
#include "tcpest/render/sidecar.hpp"

namespace tcpest {
namespace cli {

namespace {

using render::GroundTruth;
using render::SceneSpec;
using solver::PoseVector;

constexpr OptionSpec kOptions[] = {
    kCalibOption,
    kInstrumentConfigOption,
    {"set", "NAME", "lab | hard | seq | single"},
    {"n", "N", "number of images (lab/hard: first N of the 294 grid poses; seq: frames; default 294 / 100)"},
    {"start", "I", "first index (lab/hard: grid index; seq: frame), default 0"},
    {"seed", "S", "random seed (play, prior, scene, noise); default 1"},
    {"out", "DIR", "output directory (created if missing)"},
    {"r", "R", "single: x_ch,y_ch,psi,mu,lambda,phi,theta (mm and rad)"},
    {"r-deg", "R", "single: same with the four angles in degrees"},
    {"hard", "LIST", "single/seq: hard cases, comma list of reflection,occluder,haze,decoy,noise,motion_blur"},
    {"quality", "Q", "JPEG quality 1..100 (default 92)"},
    {"raw", nullptr, "write raw frames (binary PPM) instead of JPEG"},
    {"two-instruments", nullptr, "add the second instrument (right channel, nominal pose mirrored in x)"},
    {"clean", nullptr, "no noise, blur, vignetting or wet highlights (geometric checks)"},
    {"fps", "HZ", "seq: frame rate (default 25)"},
    {"supersample", "N", "samples per axis on edge pixels, 1..8 (default 4)"},
    {"contact-sheet", "FILE", "also write a contact sheet of the first 12 images (.jpg or .png)"},
    {"quiet", nullptr, "no progress line"},
};
constexpr std::size_t kOptionCount = sizeof kOptions / sizeof kOptions[0];

enum class SetKind { Lab, Hard, Seq, Single };

bool parse_hard_list(const char* text, std::uint32_t& mask) noexcept {
  mask = 0U;
  const char* p = text;
  while (*p != '\0') {
    const char* end = std::strchr(p, ',');
    const std::size_t len = (end != nullptr) ? static_cast<std::size_t>(end - p) : std::strlen(p);
    bool known = false;
    for (int b = 0; b < render::kNumHardCases; ++b) {
      const char* name = render::hard_case_name(b);
      if (std::strlen(name) == len && std::strncmp(name, p, len) == 0) {
        mask |= 1U << static_cast<unsigned>(b);
        known = true;
      }
    }
    if (!known) {
      return false;
    }
    p += len;
    if (*p == ',') {
      ++p;
    }
  }
  return true;
}

// Thumbnails of the first images tiled into one picture.
class ContactSheet {
 public:
  static constexpr int kColumns = 4;
  static constexpr int kRows = 3;
  static constexpr int kFactor = 3;  // thumbnail = frame / 3
  bool init(int frame_w, int frame_h) noexcept {
    thumb_w_ = frame_w / kFactor;
    thumb_h_ = frame_h / kFactor;
    width_ = kColumns * thumb_w_ + (kColumns + 1) * kGap;
    height_ = kRows * thumb_h_ + (kRows + 1) * kGap;
    pixels_.reset(new (std::nothrow) std::uint8_t[static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * 3U]);
    if (!pixels_) {
      return false;
    }
    std::memset(pixels_.get(), 24, static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * 3U);
    return true;
  }
  void add(const ImageView& frame) noexcept {
    if (count_ >= kColumns * kRows || !pixels_) {
      return;
    }
    const int ox = kGap + (count_ % kColumns) * (thumb_w_ + kGap);
    const int oy = kGap + (count_ / kColumns) * (thumb_h_ + kGap);
    for (int y = 0; y < thumb_h_; ++y) {
      std::uint8_t* dst = &pixels_[(static_cast<std::size_t>(oy + y) * static_cast<std::size_t>(width_) +
                                    static_cast<std::size_t>(ox)) * 3U];
      for (int x = 0; x < thumb_w_; ++x) {
        for (int c = 0; c < 3; ++c) {
          int sum = 0;
          for (int dy = 0; dy < kFactor; ++dy) {
            const std::uint8_t* src = frame.row(y * kFactor + dy);
            for (int dx = 0; dx < kFactor; ++dx) {
              sum += src[3 * (x * kFactor + dx) + c];
            }
          }
          dst[3 * x + c] = static_cast<std::uint8_t>(sum / (kFactor * kFactor));
        }
      }
    }
    ++count_;
  }
  bool write(const char* path) const noexcept {
    const ImageView view{pixels_.get(), width_, height_, static_cast<std::size_t>(width_) * 3U};
    const std::size_t len = std::strlen(path);
    if (len > 4U && std::strcmp(path + len - 4U, ".png") == 0) {
      return render::write_png_file(view, path).ok();
    }
    auto encoder = render::JpegEncoder::create(width_, height_);
    return encoder.ok() && encoder.value()->write_file(view, 90, path).ok();
  }

 private:
  static constexpr int kGap = 4;
  std::unique_ptr<std::uint8_t[]> pixels_;
  int thumb_w_ = 0, thumb_h_ = 0, width_ = 0, height_ = 0, count_ = 0;
};

}  // namespace

int cmd_render(int argc, char** argv) {
  Args args;
  char error[256];
  if (!args.parse(argc, argv, 1, kOptions, kOptionCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest render: %s (see --help)\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest render --set lab|hard|seq|single --out DIR [options]",
                "Render synthetic endoscopic images with exact ground truth: one image and one JSON sidecar\n"
                "(same stem) per frame; see docs/dataset-format.md and docs/rendering.md.",
                kOptions, kOptionCount);
    return kExitOk;
  }
  if (args.positional_count() > 0U) {
    std::fprintf(stderr, "tcpest render: unexpected argument '%s'\n", args.positional(0));
    return kExitUsage;
  }
  const char* set_name = args.value("set");
  const char* out_dir = args.value("out");
  if (set_name == nullptr || out_dir == nullptr) {
    std::fprintf(stderr, "tcpest render: --set and --out are required (see --help)\n");
    return kExitUsage;
  }
  SetKind set = SetKind::Lab;
  if (std::strcmp(set_name, "lab") == 0) {
    set = SetKind::Lab;
  } else if (std::strcmp(set_name, "hard") == 0) {
    set = SetKind::Hard;
  } else if (std::strcmp(set_name, "seq") == 0) {
    set = SetKind::Seq;
  } else if (std::strcmp(set_name, "single") == 0) {
    set = SetKind::Single;
  } else {
    std::fprintf(stderr, "tcpest render: --set must be lab, hard, seq or single (got '%s')\n", set_name);
    return kExitUsage;
  }
  unsigned long long n = (set == SetKind::Seq) ? 100U : static_cast<unsigned long long>(render::kLabGridSize);
  unsigned long long start = 0U;
  unsigned long long seed = 1U;
  unsigned long long quality = 92U;
  unsigned long long supersample = 4U;
  double fps = 25.0;
  if ((args.value("n") != nullptr && !parse_unsigned(args.value("n"), n)) ||
      (args.value("start") != nullptr && !parse_unsigned(args.value("start"), start)) ||
      (args.value("seed") != nullptr && !parse_unsigned(args.value("seed"), seed)) ||
      (args.value("quality") != nullptr && !parse_unsigned(args.value("quality"), quality)) ||
      (args.value("supersample") != nullptr && !parse_unsigned(args.value("supersample"), supersample)) ||
      (args.value("fps") != nullptr && !parse_number(args.value("fps"), fps))) {
    std::fprintf(stderr, "tcpest render: --n, --start, --seed, --quality, --supersample take non-negative integers, "
                         "--fps a number\n");
    return kExitUsage;
  }
  if (quality < 1U || quality > 100U || supersample < 1U || supersample > 8U || !(fps > 0.0 && fps <= 1000.0) ||
      n > 1000000U || start > 1000000U) {
    std::fprintf(stderr, "tcpest render: out of range: --quality 1..100, --supersample 1..8, --fps (0, 1000], "
                         "--n and --start <= 1000000\n");
    return kExitUsage;
  }
  if ((set == SetKind::Lab || set == SetKind::Hard) && start + n > static_cast<unsigned long long>(render::kLabGridSize)) {
    n = (start >= static_cast<unsigned long long>(render::kLabGridSize))
            ? 0U
            : static_cast<unsigned long long>(render::kLabGridSize) - start;
  }
  std::uint32_t forced_hard = 0U;
  if (args.value("hard") != nullptr && !parse_hard_list(args.value("hard"), forced_hard)) {
    std::fprintf(stderr, "tcpest render: --hard: unknown name in '%s' (reflection, occluder, haze, decoy, noise, "
                         "motion_blur)\n", args.value("hard"));
    return kExitUsage;
  }
  PoseVector single_r = PoseVector::Zero();
  if (set == SetKind::Single) {
    double values[solver::kNumParams];
    if (args.value("r") != nullptr) {
      if (!parse_number_list(args.value("r"), values, solver::kNumParams)) {
        std::fprintf(stderr, "tcpest render: --r needs 7 finite numbers x_ch,y_ch,psi,mu,lambda,phi,theta\n");
        return kExitUsage;
      }
    } else if (args.value("r-deg") != nullptr) {
      if (!parse_number_list(args.value("r-deg"), values, solver::kNumParams)) {
        std::fprintf(stderr, "tcpest render: --r-deg needs 7 finite numbers x_ch,y_ch,psi,mu,lambda,phi,theta\n");
        return kExitUsage;
      }
      const int angles[] = {solver::kPsi, solver::kMu, solver::kPhi, solver::kTheta};
      for (int a : angles) {
        values[a] = solver::deg_to_rad(values[a]);
      }
    } else {
      std::fprintf(stderr, "tcpest render: --set single needs --r or --r-deg\n");
      return kExitUsage;
    }
    for (int q = 0; q < solver::kNumParams; ++q) {
      single_r[q] = values[q];
    }
    n = 1U;
  }

  ModelSetup setup;
  if (!load_model_setup("render", args.value("calib"), args.value("config"), setup)) {
    return kExitConfig;
  }
  render::RenderSettings settings;
  settings.supersample = static_cast<int>(supersample);
  auto created = render::Renderer::create(setup.camera, setup.instrument, settings);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest render: renderer: %s\n", render::to_string(created.error()));
    return kExitConfig;
  }
  render::Renderer& renderer = *created.value();
  const int width = setup.camera.width();
  const int height = setup.camera.height();
  const bool raw = args.flag("raw");
  std::unique_ptr<render::JpegEncoder> encoder;
  if (!raw) {
    auto made = render::JpegEncoder::create(width, height);
    if (!made.ok()) {
      std::fprintf(stderr, "tcpest render: JPEG encoder: %s\n", render::to_string(made.error()));
      return kExitFailure;
    }
    encoder = std::move(made.value());
  }
  const std::size_t frame_bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3U;
  std::unique_ptr<std::uint8_t[]> frame(new (std::nothrow) std::uint8_t[frame_bytes]);
  if (!frame) {
    std::fprintf(stderr, "tcpest render: out of memory for a %dx%d frame\n", width, height);
    return kExitFailure;
  }
  const MutableImageView view{frame.get(), width, height, static_cast<std::size_t>(width) * 3U};
  if (!make_directory(out_dir)) {
    std::fprintf(stderr, "tcpest render: cannot create the output directory '%s': %s\n", out_dir, std::strerror(errno));
    return kExitFailure;
  }
  const char* sheet_path = args.value("contact-sheet");
  ContactSheet sheet;
  if (sheet_path != nullptr && !sheet.init(width, height)) {
    std::fprintf(stderr, "tcpest render: out of memory for the contact sheet\n");
    return kExitFailure;
  }

  const auto& geometry = setup.instrument.geometry();
  const render::SequenceGenerator sequence(geometry, seed, fps);
  const render::SequenceGenerator sequence2(geometry, seed + 0x51DEULL, fps);
  const bool two = args.flag("two-instruments");
  const bool clean = args.flag("clean");
  const bool progress = !args.flag("quiet") && n > 1U;
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  const auto t_start = std::chrono::steady_clock::now();
  int not_visible = 0;
  render::InstrumentView last_view = render::InstrumentView::Visible;

  for (unsigned long long i = 0U; i < n; ++i) {
    const auto index = static_cast<int>(start + i);
    SceneSpec scene;
    scene.clean = clean;
    scene.seed = render::image_seed(seed, static_cast<std::uint64_t>(index));
    scene.hard_cases = forced_hard;
    render::Sidecar sidecar_extra;
    switch (set) {
      case SetKind::Lab:
      case SetKind::Hard: {
        const render::LabSample lab = render::lab_sample(geometry, index, seed);
        scene.r = lab.r;
        sidecar_extra.has_prior = true;
        sidecar_extra.prior = lab.prior.joints;
        if (set == SetKind::Hard) {
          scene.hard_cases = render::hard_cases_for(index, seed);
        }
        break;
      }
      case SetKind::Seq: {
        const render::SequenceSample s = sequence.sample(static_cast<std::uint32_t>(index));
        scene.r = s.r;
        scene.world_seed = sequence.world_seed();  // the same tissue in every frame
        scene.tissue_depth_mm = sequence.tissue_depth_mm();
        sidecar_extra.has_prior = true;
        sidecar_extra.prior = s.prior.joints;
        sidecar_extra.has_time = true;
        sidecar_extra.time_s = s.time_s;
        break;
      }
      case SetKind::Single:
        scene.r = single_r;
        break;
    }
    if (two) {
      // The second instrument: its own smooth joints (seq) or a draw from
      // the working range, about the mirrored nominal pose.
      const render::SequenceSample s2 = sequence2.sample(static_cast<std::uint32_t>(index));
      scene.second_instrument = true;
      scene.r2 = renderer.mirrored_nominal_pose(s2.r[solver::kLambda], s2.r[solver::kPhi], s2.r[solver::kTheta]);
    }
    GroundTruth truth;
    const auto rendered = renderer.render(scene, view, truth);
    if (!rendered.ok()) {
      std::fprintf(stderr, "\ntcpest render: image %d: %s\n", index, render::to_string(rendered.error()));
      return kExitFailure;
    }
    last_view = truth.instruments[0].view;
    if (last_view != render::InstrumentView::Visible) {
      ++not_visible;
    }
    char stem[4096];
    char path[4160];
    static_cast<void>(std::snprintf(stem, sizeof stem, "%s/%04d", out_dir, index));  // long paths are refused below
    if (std::strlen(stem) + 8U >= sizeof stem) {
      std::fprintf(stderr, "tcpest render: output path too long\n");
      return kExitUsage;
    }
    render::Sidecar sidecar = render::make_sidecar(truth, scene, settings, width, height);
    static_cast<void>(std::snprintf(sidecar.image, sizeof sidecar.image, "%04d.%s", index, raw ? "ppm" : "jpg"));
    static_cast<void>(std::snprintf(sidecar.set, sizeof sidecar.set, "%s", set_name));  // names are short
    sidecar.index = index;
    sidecar.has_dataset_seed = true;
    sidecar.dataset_seed = seed;
    sidecar.has_prior = sidecar_extra.has_prior;
    sidecar.prior = sidecar_extra.prior;
    sidecar.has_time = sidecar_extra.has_time;
    sidecar.time_s = sidecar_extra.time_s;
    sidecar.jpeg_quality = raw ? 0 : static_cast<int>(quality);
    static_cast<void>(std::snprintf(path, sizeof path, "%s.%s", stem, raw ? "ppm" : "jpg"));  // fits: checked above
    const auto written = raw ? render::write_ppm_file(view.view(), path)
                             : encoder->write_file(view.view(), static_cast<int>(quality), path);
    if (!written.ok()) {
      std::fprintf(stderr, "\ntcpest render: %s: %s\n", path, render::to_string(written.error()));
      return kExitFailure;
    }
    static_cast<void>(std::snprintf(path, sizeof path, "%s.json", stem));  // fits: checked above
    if (!render::write_sidecar_file(path, sidecar)) {
      std::fprintf(stderr, "\ntcpest render: %s: cannot write the sidecar\n", path);
      return kExitFailure;
    }
    if (sheet_path != nullptr) {
      sheet.add(view.view());
    }
    if (progress && (tty || (i + 1U) % 25U == 0U || i + 1U == n)) {
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
      std::fprintf(stderr, "%srender: %llu/%llu images, %.1f s%s", tty ? "\r" : "", i + 1U, n, elapsed,
                   tty ? "" : "\n");
    }
  }
  if (progress && tty) {
    std::fprintf(stderr, "\n");
  }
  if (sheet_path != nullptr && !sheet.write(sheet_path)) {
    std::fprintf(stderr, "tcpest render: cannot write the contact sheet '%s'\n", sheet_path);
    return kExitFailure;
  }
  if (set == SetKind::Single && not_visible > 0) {
    std::printf("instrument not visible (%s): image written without it\n", render::to_string(last_view));
  }
  std::printf("wrote %llu image(s) and sidecar(s) to %s%s\n", n, out_dir,
              not_visible > 0 ? " (some without a visible instrument: see instrument_view)" : "");
  return kExitOk;
}

}  // namespace cli
}  // namespace tcpest
