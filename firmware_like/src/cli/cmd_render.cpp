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
    {"start", "I", "first index (lab/hard: grid index 0..293; seq: frame 0..1000000), default 0"},
    {"seed", "S", "random seed (play, prior, scene, noise); default 1"},
    {"out", "DIR", "output directory (created if missing)"},
    {"r", "R", "single: x_ch,y_ch,psi,mu,lambda,phi,theta (mm and rad)"},
    {"r-deg", "R", "single: same with the four angles in degrees"},
    {"hard", "LIST", "single/seq: hard cases, comma list of reflection,occluder,haze,decoy,noise,motion_blur"},
    {"quality", "Q", "JPEG quality 1..100 (default 92)"},
    {"raw", nullptr, "write raw frames (binary PPM) instead of JPEG"},
    {"two-instruments", nullptr, "add the second instrument (right channel, nominal pose mirrored in x)"},
    {"clean", nullptr, "no noise, blur, vignetting or wet highlights (geometric checks)"},
    {"randomise", nullptr,
     "each image's look drawn from documented ranges: paint, gloss, tissue tint, white balance, exposure, "
     "noise, blur, vignetting, JPEG quality and chroma subsampling; per set the shaft's and grasper's radii "
     "and the lamp beside the lens, with its shadow (docs/rendering.md; seq: one look for the sequence; "
     "--quality is then ignored)"},
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

// The options of one render, parsed and checked.
struct RenderOptions {
  SetKind set = SetKind::Lab;
  const char* set_name = nullptr;
  const char* out_dir = nullptr;
  const char* sheet_path = nullptr;  // --contact-sheet, nullptr: none
  unsigned long long n = 0U;
  unsigned long long start = 0U;
  unsigned long long seed = 1U;
  unsigned long long quality = 92U;
  unsigned long long supersample = 4U;
  double fps = 25.0;
  std::uint32_t forced_hard = 0U;
  PoseVector single_r = PoseVector::Zero();
  bool raw = false;
  bool two_instruments = false;
  bool clean = false;
  bool randomise = false;
  bool quiet = false;
};

// The set named by --set; false if the name is unknown.
bool parse_set_kind(const char* name, SetKind& set) noexcept {
  if (std::strcmp(name, "lab") == 0) {
    set = SetKind::Lab;
  } else if (std::strcmp(name, "hard") == 0) {
    set = SetKind::Hard;
  } else if (std::strcmp(name, "seq") == 0) {
    set = SetKind::Seq;
  } else if (std::strcmp(name, "single") == 0) {
    set = SetKind::Single;
  } else {
    return false;
  }
  return true;
}

// --n, --start, --seed, --quality, --supersample and --fps with their
// defaults and ranges (lab/hard: --start inside the grid, n clipped to it).
// Returns kExitOk or kExitUsage (reported).
int parse_numeric_options(const Args& args, RenderOptions& o) noexcept {
  constexpr unsigned long long kMaxImages = 1000000U;
  o.n = (o.set == SetKind::Seq) ? 100U : static_cast<unsigned long long>(render::kLabGridSize);
  if (!unsigned_option(args, "render", "n", 1U, kMaxImages, o.n) ||
      !unsigned_option(args, "render", "start", 0U, kMaxImages, o.start) ||
      !unsigned_option(args, "render", "seed", 0U, ~0ULL, o.seed) ||
      !unsigned_option(args, "render", "quality", 1U, 100U, o.quality) ||
      !unsigned_option(args, "render", "supersample", 1U, 8U, o.supersample) ||
      !number_option(args, "render", "fps", 0.001, 1000.0, o.fps)) {
    return kExitUsage;
  }
  if (o.set == SetKind::Lab || o.set == SetKind::Hard) {
    const auto grid = static_cast<unsigned long long>(render::kLabGridSize);
    if (o.start >= grid) {
      std::fprintf(stderr, "tcpest render: --start: the %s set has %llu images, expected 0..%llu, got %llu\n",
                   o.set_name, grid, grid - 1U, o.start);
      return kExitUsage;
    }
    o.n = std::min(o.n, grid - o.start);
  }
  return kExitOk;
}

// --set single's configuration from --r or --r-deg (angles converted to
// radians). Returns kExitOk or kExitUsage (reported).
int parse_single_pose(const Args& args, PoseVector& single_r) noexcept {
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
  return kExitOk;
}

// Every option after --help. Returns kExitOk or kExitUsage (reported).
int parse_render_options(const Args& args, RenderOptions& o) noexcept {
  if (args.positional_count() > 0U) {
    std::fprintf(stderr, "tcpest render: unexpected argument '%s'\n", args.positional(0));
    return kExitUsage;
  }
  o.set_name = args.value("set");
  o.out_dir = args.value("out");
  if (o.set_name == nullptr || o.out_dir == nullptr) {
    std::fprintf(stderr, "tcpest render: --set and --out are required (see --help)\n");
    return kExitUsage;
  }
  if (!parse_set_kind(o.set_name, o.set)) {
    std::fprintf(stderr, "tcpest render: --set must be lab, hard, seq or single (got '%s')\n", o.set_name);
    return kExitUsage;
  }
  const int numbers = parse_numeric_options(args, o);
  if (numbers != kExitOk) {
    return numbers;
  }
  if (args.value("hard") != nullptr && !parse_hard_list(args.value("hard"), o.forced_hard)) {
    std::fprintf(stderr, "tcpest render: --hard: unknown name in '%s' (reflection, occluder, haze, decoy, noise, "
                         "motion_blur)\n", args.value("hard"));
    return kExitUsage;
  }
  if (o.set == SetKind::Single) {
    const int pose = parse_single_pose(args, o.single_r);
    if (pose != kExitOk) {
      return pose;
    }
    o.n = 1U;
  }
  o.sheet_path = args.value("contact-sheet");
  o.raw = args.flag("raw");
  o.two_instruments = args.flag("two-instruments");
  o.clean = args.flag("clean");
  o.randomise = args.flag("randomise");
  if (o.randomise && o.clean) {
    std::fprintf(stderr, "tcpest render: --randomise and --clean exclude each other (a clean render has no look to draw)\n");
    return kExitUsage;
  }
  o.quiet = args.flag("quiet");
  return kExitOk;
}

// What the images are made and written with: the renderer, the JPEG encoder
// (none with --raw), the frame and the optional contact sheet.
struct RenderTools {
  render::RenderSettings settings;
  std::unique_ptr<render::Renderer> renderer;
  std::unique_ptr<render::JpegEncoder> encoder;
  std::unique_ptr<std::uint8_t[]> frame;
  MutableImageView view;
  ContactSheet sheet;
  int width = 0;
  int height = 0;
};

// Creates the renderer, the encoder, the frame, the output directory and the
// contact sheet. Returns kExitOk, else the exit code (reported).
int make_render_tools(const RenderOptions& o, const ModelSetup& setup, RenderTools& t) noexcept {
  t.settings.supersample = static_cast<int>(o.supersample);
  auto created = render::Renderer::create(setup.camera, setup.instrument, t.settings);
  if (!created.ok()) {
    std::fprintf(stderr, "tcpest render: renderer: %s\n", render::to_string(created.error()));
    return kExitConfig;
  }
  t.renderer = std::move(created.value());
  t.width = setup.camera.width();
  t.height = setup.camera.height();
  if (!o.raw) {
    auto made = render::JpegEncoder::create(t.width, t.height);
    if (!made.ok()) {
      std::fprintf(stderr, "tcpest render: JPEG encoder: %s\n", render::to_string(made.error()));
      return kExitFailure;
    }
    t.encoder = std::move(made.value());
  }
  const std::size_t frame_bytes = static_cast<std::size_t>(t.width) * static_cast<std::size_t>(t.height) * 3U;
  t.frame.reset(new (std::nothrow) std::uint8_t[frame_bytes]);
  if (!t.frame) {
    std::fprintf(stderr, "tcpest render: out of memory for a %dx%d frame\n", t.width, t.height);
    return kExitFailure;
  }
  t.view = MutableImageView{t.frame.get(), t.width, t.height, static_cast<std::size_t>(t.width) * 3U};
  char failed[kMaxDirectoryPath + 1U] = {};
  if (!make_directories(o.out_dir, failed, sizeof failed)) {
    const int why = errno;
    std::fprintf(stderr, "tcpest render: cannot create the output directory '%s': '%s': %s\n", o.out_dir, failed,
                 std::strerror(why));
    return kExitFailure;
  }
  if (o.sheet_path != nullptr && !t.sheet.init(t.width, t.height)) {
    std::fprintf(stderr, "tcpest render: out of memory for the contact sheet\n");
    return kExitFailure;
  }
  return kExitOk;
}

// Where the scenes come from: the instrument's geometry, the smooth motions
// (seq, second instrument) and the renderer (the mirrored nominal pose).
struct SceneSources {
  const solver::InstrumentGeometry& geometry;
  const render::SequenceGenerator& sequence;
  const render::SequenceGenerator& sequence2;
  const render::Renderer& renderer;
};

// Image `index`'s scene, and the sidecar keys only the set knows (prior, time).
void describe_scene(const RenderOptions& o, const SceneSources& from, int index, SceneSpec& scene,
                    render::Sidecar& sidecar_extra) noexcept {
  scene.clean = o.clean;
  scene.seed = render::image_seed(o.seed, static_cast<std::uint64_t>(index));
  scene.hard_cases = o.forced_hard;
  switch (o.set) {
    case SetKind::Lab:
    case SetKind::Hard: {
      const render::LabSample lab = render::lab_sample(from.geometry, index, o.seed);
      scene.r = lab.r;
      sidecar_extra.has_prior = true;
      sidecar_extra.prior = lab.prior.joints;
      if (o.set == SetKind::Hard) {
        scene.hard_cases = render::hard_cases_for(index, o.seed);
      }
      break;
    }
    case SetKind::Seq: {
      const render::SequenceSample s = from.sequence.sample(static_cast<std::uint32_t>(index));
      scene.r = s.r;
      scene.world_seed = from.sequence.world_seed();  // the same tissue in every frame
      scene.tissue_depth_mm = from.sequence.tissue_depth_mm();
      sidecar_extra.has_prior = true;
      sidecar_extra.prior = s.prior.joints;
      sidecar_extra.has_time = true;
      sidecar_extra.time_s = s.time_s;
      break;
    }
    case SetKind::Single:
      scene.r = o.single_r;
      break;
  }
  if (o.randomise) {
    // One look per image, one per sequence (the same camera and scene throughout).
    const render::RandomLook look =
        render::random_look(o.set == SetKind::Seq ? from.sequence.world_seed() : scene.seed);
    scene.appearance = look.appearance;
    render::random_build(o.seed, scene.appearance);  // one instrument and endoscope per set
    scene.exposure = look.exposure;
    scene.noise_sigma = look.noise_sigma;
    scene.blur_sigma_px = look.blur_sigma_px;
    scene.vignetting = look.vignetting;
    sidecar_extra.has_appearance = true;
    sidecar_extra.jpeg_quality = look.jpeg_quality;
    sidecar_extra.chroma = look.chroma;
  }
  if (o.two_instruments) {
    // The second instrument: its own smooth joints (seq) or a draw from
    // the working range, about the mirrored nominal pose.
    const render::SequenceSample s2 = from.sequence2.sample(static_cast<std::uint32_t>(index));
    scene.second_instrument = true;
    scene.r2 = from.renderer.mirrored_nominal_pose(s2.r[solver::kLambda], s2.r[solver::kPhi], s2.r[solver::kTheta]);
  }
}

// Writes the rendered image `index` (JPEG, or PPM with --raw) and its sidecar.
// Returns kExitOk, else the exit code (reported).
int write_image(const RenderOptions& o, const RenderTools& t, int index, const SceneSpec& scene,
                const GroundTruth& truth, const render::Sidecar& sidecar_extra) noexcept {
  char stem[4096];
  char path[4160];
  static_cast<void>(std::snprintf(stem, sizeof stem, "%s/%04d", o.out_dir, index));  // long paths are refused below
  if (std::strlen(stem) + 8U >= sizeof stem) {
    std::fprintf(stderr, "tcpest render: output path too long\n");
    return kExitUsage;
  }
  render::Sidecar sidecar = render::make_sidecar(truth, scene, t.settings, t.width, t.height);
  static_cast<void>(std::snprintf(sidecar.image, sizeof sidecar.image, "%04d.%s", index, o.raw ? "ppm" : "jpg"));
  static_cast<void>(std::snprintf(sidecar.set, sizeof sidecar.set, "%s", o.set_name));  // names are short
  sidecar.index = index;
  sidecar.has_dataset_seed = true;
  sidecar.dataset_seed = o.seed;
  sidecar.has_prior = sidecar_extra.has_prior;
  sidecar.prior = sidecar_extra.prior;
  sidecar.has_time = sidecar_extra.has_time;
  sidecar.time_s = sidecar_extra.time_s;
  // A randomised look brings its own JPEG quality and chroma subsampling.
  const int quality = sidecar_extra.has_appearance ? sidecar_extra.jpeg_quality : static_cast<int>(o.quality);
  sidecar.has_appearance = sidecar_extra.has_appearance;
  sidecar.chroma = sidecar_extra.chroma;
  sidecar.jpeg_quality = o.raw ? 0 : quality;
  static_cast<void>(std::snprintf(path, sizeof path, "%s.%s", stem, o.raw ? "ppm" : "jpg"));  // fits: checked above
  const auto written = o.raw ? render::write_ppm_file(t.view.view(), path)
                             : t.encoder->write_file(t.view.view(), quality, path, sidecar.chroma);
  if (!written.ok()) {
    std::fprintf(stderr, "\ntcpest render: %s: %s\n", path, render::to_string(written.error()));
    return kExitFailure;
  }
  static_cast<void>(std::snprintf(path, sizeof path, "%s.json", stem));  // fits: checked above
  if (!render::write_sidecar_file(path, sidecar)) {
    std::fprintf(stderr, "\ntcpest render: %s: cannot write the sidecar\n", path);
    return kExitFailure;
  }
  return kExitOk;
}

// How many images showed no instrument, and the last image's view.
struct VisibilityCount {
  int not_visible = 0;
  render::InstrumentView last_view = render::InstrumentView::Visible;
};

// Renders and writes every image of the set, with a progress line on stderr.
// Returns kExitOk, else the exit code (reported).
int render_images(const RenderOptions& o, const ModelSetup& setup, RenderTools& t,
                  VisibilityCount& visibility) noexcept {
  const auto& geometry = setup.instrument.geometry();
  const render::SequenceGenerator sequence(geometry, o.seed, o.fps);
  const render::SequenceGenerator sequence2(geometry, o.seed + 0x51DEULL, o.fps);
  const SceneSources sources{geometry, sequence, sequence2, *t.renderer};
  const bool progress = !o.quiet && o.n > 1U;
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  const auto t_start = std::chrono::steady_clock::now();

  for (unsigned long long i = 0U; i < o.n; ++i) {
    const auto index = static_cast<int>(o.start + i);
    SceneSpec scene;
    render::Sidecar sidecar_extra;
    describe_scene(o, sources, index, scene, sidecar_extra);
    GroundTruth truth;
    const auto rendered = t.renderer->render(scene, t.view, truth);
    if (!rendered.ok()) {
      std::fprintf(stderr, "\ntcpest render: image %d: %s\n", index, render::to_string(rendered.error()));
      return kExitFailure;
    }
    visibility.last_view = truth.instruments[0].view;
    if (visibility.last_view != render::InstrumentView::Visible) {
      ++visibility.not_visible;
    }
    const int written = write_image(o, t, index, scene, truth, sidecar_extra);
    if (written != kExitOk) {
      return written;
    }
    if (o.sheet_path != nullptr) {
      t.sheet.add(t.view.view());
    }
    if (progress && (tty || (i + 1U) % 25U == 0U || i + 1U == o.n)) {
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
      std::fprintf(stderr, "%srender: %llu/%llu images, %.1f s%s", tty ? "\r" : "", i + 1U, o.n, elapsed,
                   tty ? "" : "\n");
    }
  }
  if (progress && tty) {
    std::fprintf(stderr, "\n");
  }
  return kExitOk;
}

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
  RenderOptions options;
  const int parsed = parse_render_options(args, options);
  if (parsed != kExitOk) {
    return parsed;
  }

  ModelSetup setup;
  if (!load_model_setup("render", args.value("calib"), args.value("config"), setup)) {
    return kExitConfig;
  }
  RenderTools tools;
  const int made = make_render_tools(options, setup, tools);
  if (made != kExitOk) {
    return made;
  }
  VisibilityCount visibility;
  const int rendered = render_images(options, setup, tools, visibility);
  if (rendered != kExitOk) {
    return rendered;
  }
  if (options.sheet_path != nullptr && !tools.sheet.write(options.sheet_path)) {
    std::fprintf(stderr, "tcpest render: cannot write the contact sheet '%s'\n", options.sheet_path);
    return kExitFailure;
  }
  if (options.set == SetKind::Single && visibility.not_visible > 0) {
    std::printf("instrument not visible (%s): image written without it\n", render::to_string(visibility.last_view));
  }
  std::printf("wrote %llu image(s) and sidecar(s) to %s%s\n", options.n, options.out_dir,
              visibility.not_visible > 0 ? " (some without a visible instrument: see instrument_view)" : "");
  return kExitOk;
}

}  // namespace cli
}  // namespace tcpest
