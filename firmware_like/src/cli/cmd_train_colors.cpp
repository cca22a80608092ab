// tcpest train-colors: trains the blue/yellow colour model (two Gaussians in
// the a*b* plane of CIE L*a*b*, D65, sRGB) from frames with hand-marked
// regions, and writes it with its thresholds (docs/vision.md).
// Marked regions come as polygons and/or mask images in a small JSON file:
//   {"frames": [{"image": "0001.jpg", "blue": [[[x, y], ...], ...], "yellow": [...],
//                "mask": "0001.mask.ppm"}, ...]}
// (paths relative to the JSON file; --masks requires "mask" in every frame),
// or from rendered datasets' sidecars (--sidecars DIR: the pixels where the
// middle markers' surface faces the camera, from the true configuration r).
// A mask is an 8-bit binary PPM (blue, yellow, black = background, anything
// else unused) or PGM (1 blue, 2 yellow, 3 background) the size of its image.
// Background samples are the mask's background pixels if it has any, else the
// pixels far from every marked region (outside their joint bounding box grown
// by half its size).
#include <dirent.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/setup.hpp"
#include "cli/vision_run.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/common/json.hpp"
#include "tcpest/render/sidecar.hpp"

namespace tcpest {
namespace cli {
namespace {

const OptionSpec kSpecs[] = {
    {"polygons", "FILE.json", "frames and their marked blue/yellow polygons (and optional masks)"},
    {"masks", "FILE.json", "frames and their mask images (PPM/PGM, see docs/vision.md)"},
    {"sidecars", "DIR", "a rendered dataset: marker polygons from the sidecars' true corners"},
    {"calib", "CAM.yaml", "with --sidecars: the dataset's camera (default: built-in PAL camera)"},
    {"config", "CFG.yaml", "with --sidecars: the instrument configuration (default: built-in geometry)"},
    {"out", "MODEL.json", "where to write the model (default: standard output)"},
    {"max", "N", "use at most N frames"},
};
constexpr std::size_t kSpecCount = sizeof kSpecs / sizeof kSpecs[0];

struct Polygon {
  vision::PixelClass cls = vision::PixelClass::Blue;
  std::vector<vision::Point> points;
};

struct MarkedPixel {
  int x = 0;
  int y = 0;
  vision::PixelClass cls = vision::PixelClass::Blue;
};

struct Frame {
  std::string image;
  std::string mask;  // empty: none
  std::vector<Polygon> polygons;
  std::vector<MarkedPixel> pixels;  // marked pixels (from sidecars)
  bool usable = true;               // false once its image or mask failed (pass 1)
};

// Per-pixel labels: the PixelClass values, and pixels that train nothing.
constexpr std::uint8_t kUnused = 3U;

// Mask coding (docs/vision.md). PPM: saturated blue / yellow, black for
// background; PGM: the small values 1, 2, 3. Everything else is unused, so
// that white paper, anti-aliased edges and the image itself train nothing.
std::uint8_t mask_label_rgb(std::uint8_t r, std::uint8_t g, std::uint8_t b) noexcept {
  if (b >= 160U && r <= 96U && g <= 96U) {
    return static_cast<std::uint8_t>(vision::PixelClass::Blue);
  }
  if (r >= 160U && g >= 160U && b <= 96U) {
    return static_cast<std::uint8_t>(vision::PixelClass::Yellow);
  }
  if (r <= 32U && g <= 32U && b <= 32U) {
    return static_cast<std::uint8_t>(vision::PixelClass::Background);
  }
  return kUnused;
}

std::uint8_t mask_label_grey(std::uint8_t v) noexcept {
  switch (v) {
    case 1U:
      return static_cast<std::uint8_t>(vision::PixelClass::Blue);
    case 2U:
      return static_cast<std::uint8_t>(vision::PixelClass::Yellow);
    case 3U:
      return static_cast<std::uint8_t>(vision::PixelClass::Background);
    default:
      return kUnused;
  }
}

// A decoded mask: one label per pixel, and what it marks.
struct DecodedMask {
  std::vector<std::uint8_t> labels;
  std::size_t marked = 0U;      // blue or yellow pixels
  std::size_t background = 0U;  // explicit background pixels
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // bounding box of the marked pixels
};

void decode_mask(const std::vector<std::uint8_t>& samples, const PnmInfo& info, DecodedMask& out) {
  const std::size_t n = static_cast<std::size_t>(info.width) * static_cast<std::size_t>(info.height);
  out.labels.resize(n);
  out.marked = 0U;
  out.background = 0U;
  out.x0 = info.width;
  out.y0 = info.height;
  out.x1 = -1;
  out.y1 = -1;
  for (std::size_t i = 0U; i < n; ++i) {
    const std::uint8_t* s = samples.data() + i * static_cast<std::size_t>(info.channels);
    const std::uint8_t label = info.channels == 1 ? mask_label_grey(s[0]) : mask_label_rgb(s[0], s[1], s[2]);
    out.labels[i] = label;
    if (label == static_cast<std::uint8_t>(vision::PixelClass::Background)) {
      ++out.background;
    } else if (label != kUnused) {
      ++out.marked;
      const int x = static_cast<int>(i % static_cast<std::size_t>(info.width));
      const int y = static_cast<int>(i / static_cast<std::size_t>(info.width));
      out.x0 = std::min(out.x0, x);
      out.y0 = std::min(out.y0, y);
      out.x1 = std::max(out.x1, x);
      out.y1 = std::max(out.y1, y);
    }
  }
}

bool inside(const std::vector<vision::Point>& poly, double x, double y) noexcept {
  bool in = false;
  const std::size_t n = poly.size();
  for (std::size_t i = 0U, j = n - 1U; i < n; j = i++) {
    const vision::Point& a = poly[i];
    const vision::Point& b = poly[j];
    if (((a.y > y) != (b.y > y)) && (x < (b.x - a.x) * (y - a.y) / (b.y - a.y) + a.x)) {
      in = !in;
    }
  }
  return in;
}

std::string directory_of(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0U, slash);
}

bool read_text(const char* path, std::string& out) {
  std::FILE* f = std::fopen(path, "rb");
  if (f == nullptr) {
    return false;
  }
  char buffer[65536];
  std::size_t n = 0U;
  while ((n = std::fread(buffer, 1U, sizeof buffer, f)) > 0U) {
    out.append(buffer, n);
  }
  static_cast<void>(std::fclose(f));  // read-only
  return true;
}

// --polygons (masks optional) or --masks (a mask in every frame).
bool load_marked_frames(const char* path, bool require_mask, std::vector<Frame>& frames) {
  std::string text;
  if (!read_text(path, text)) {
    std::fprintf(stderr, "tcpest train-colors: cannot read %s\n", path);
    return false;
  }
  std::vector<json::Token> tokens(text.size() / 2U + 64U);
  json::Document doc(tokens.data(), tokens.size());
  const auto parsed = doc.parse(text.c_str(), text.size());
  if (!parsed.ok()) {
    std::fprintf(stderr, "tcpest train-colors: %s:%u: %s\n", path, parsed.error().line,
                 json::to_string(parsed.error().code));
    return false;
  }
  const auto list = doc.member(doc.root(), "frames");
  if (!list.ok() || doc.type(list.value()) != json::TokenType::Array) {
    std::fprintf(stderr, "tcpest train-colors: %s: field 'frames': expected an array\n", path);
    return false;
  }
  const std::string base = directory_of(path);
  for (std::size_t f = 0U; f < doc.array_size(list.value()); ++f) {
    const std::size_t object = doc.element(list.value(), f).value();
    Frame frame;
    char name[512];
    const auto image = doc.member(object, "image");
    if (!image.ok() || !doc.string(image.value(), name, sizeof name).ok()) {
      std::fprintf(stderr, "tcpest train-colors: %s: frame %zu: field 'image': expected a string\n", path, f);
      return false;
    }
    frame.image = name[0] == '/' ? std::string(name) : base + "/" + name;
    const auto mask = doc.member(object, "mask");
    if (mask.ok()) {
      if (!doc.string(mask.value(), name, sizeof name).ok() || name[0] == '\0') {
        std::fprintf(stderr, "tcpest train-colors: %s: frame %zu: field 'mask': expected a file name\n", path, f);
        return false;
      }
      frame.mask = name[0] == '/' ? std::string(name) : base + "/" + name;
    } else if (require_mask) {
      std::fprintf(stderr, "tcpest train-colors: %s: frame %zu: field 'mask': missing\n", path, f);
      return false;
    }
    const char* classes[2] = {"blue", "yellow"};
    for (int c = 0; c < 2; ++c) {
      const auto polys = doc.member(object, classes[c]);
      if (!polys.ok()) {
        continue;
      }
      for (std::size_t p = 0U; p < doc.array_size(polys.value()); ++p) {
        const std::size_t poly = doc.element(polys.value(), p).value();
        Polygon polygon;
        polygon.cls = c == 0 ? vision::PixelClass::Blue : vision::PixelClass::Yellow;
        for (std::size_t v = 0U; v < doc.array_size(poly); ++v) {
          double xy[2] = {0.0, 0.0};
          if (!doc.numbers(doc.element(poly, v).value(), xy, 2U).ok()) {
            std::fprintf(stderr, "tcpest train-colors: %s: frame %zu: field '%s': points must be [x, y]\n", path, f,
                         classes[c]);
            return false;
          }
          polygon.points.push_back(vision::Point{xy[0], xy[1]});
        }
        if (polygon.points.size() >= 3U) {
          frame.polygons.push_back(polygon);
        }
      }
    }
    frames.push_back(frame);
  }
  return true;
}

// The marked pixels of a frame from its true configuration `r`: points of
// the middle markers' surface, away from the stripe ends, facing the camera,
// projected (the shaft or grasper may hide parts of the end markers). Each
// becomes a tiny polygon (a pixel square).
void mark_true_pixels(const ModelSetup& setup, const solver::PoseVector& r, Frame& frame) {
  const solver::PoseFrames pf = setup.instrument.frames(r);
  const auto& g = setup.instrument.geometry();
  for (int m = 1; m + 1 < solver::kNumMarkers; ++m) {
    const vision::PixelClass cls = g.marker_colors[static_cast<std::size_t>(m)] == solver::MarkerColor::Blue
                                       ? vision::PixelClass::Blue
                                       : vision::PixelClass::Yellow;
    const double s0 = g.boundaries_mm[static_cast<std::size_t>(m)];
    const double s1 = g.boundaries_mm[static_cast<std::size_t>(m) + 1U];
    for (int i = 0; i <= 24; ++i) {
      const double s_mm = s0 + (s1 - s0) * (0.25 + 0.5 * i / 24.0);
      const solver::CentrelineFrame c = setup.instrument.centreline(pf, s_mm);
      for (int a = 0; a < 120; ++a) {
        const double angle = 2.0 * solver::kPi * a / 120.0;
        const solver::Vec3 normal = dmath::cos(angle) * c.normal + dmath::sin(angle) * c.binormal;
        const solver::Vec3 x = c.position + g.radius_mm * normal;
        if (normal.dot(x.normalized()) > -0.35) {
          continue;  // grazing or turned away: near the silhouette
        }
        solver::Vec2 px;
        if (!setup.camera.project(x, px)) {
          continue;
        }
        frame.pixels.push_back(MarkedPixel{static_cast<int>(std::lround(px.x())), static_cast<int>(std::lround(px.y())), cls});
      }
    }
  }
}

// The frames of a rendered dataset, marked from their sidecars' true
// configurations. Unreadable sidecars and sidecars without a configuration
// are skipped, each named, and counted in a line at the end.
bool load_sidecars(const char* dir, const ModelSetup& setup, std::vector<Frame>& frames) {
  std::vector<std::string> names;
  DIR* d = opendir(dir);
  if (d == nullptr) {
    std::fprintf(stderr, "tcpest train-colors: cannot open %s\n", dir);
    return false;
  }
  for (const dirent* e = readdir(d); e != nullptr; e = readdir(d)) {
    const std::size_t n = std::strlen(e->d_name);
    if (n > 5U && std::strcmp(e->d_name + n - 5U, ".json") == 0) {
      names.emplace_back(e->d_name);
    }
  }
  static_cast<void>(closedir(d));  // read-only
  std::sort(names.begin(), names.end());
  std::size_t used = 0U;
  std::size_t unreadable = 0U;
  std::size_t without_pose = 0U;
  for (const std::string& name : names) {
    const std::string path = std::string(dir) + "/" + name;
    const auto s = render::read_sidecar_file(path.c_str());
    if (!s.ok()) {
      char message[768];
      s.error().format(message, sizeof message);
      std::fprintf(stderr, "tcpest train-colors: unreadable sidecar %s (skipped)\n", message);
      ++unreadable;
      continue;
    }
    const render::Sidecar& sc = s.value();
    if (!sc.instrument.has_r) {
      std::fprintf(stderr, "tcpest train-colors: sidecar %s has no true configuration (skipped)\n", path.c_str());
      ++without_pose;
      continue;
    }
    Frame frame;
    frame.image = std::string(dir) + "/" + sc.image;
    mark_true_pixels(setup, sc.instrument.r, frame);
    if (!frame.pixels.empty()) {
      frames.push_back(frame);
      ++used;
    }
  }
  std::fprintf(stderr, "tcpest train-colors: sidecars in %s: %zu used, %zu unreadable, %zu without a configuration\n",
               dir, used, unreadable, without_pose);
  return true;
}

// The marked frames of every --polygons, --masks and --sidecars option, at
// most --max of them. Returns kExitOk, else the exit code (reported).
int load_all_frames(const Args& args, std::vector<Frame>& frames) {
  if (args.value("polygons") != nullptr && !load_marked_frames(args.value("polygons"), false, frames)) {
    return kExitConfig;
  }
  if (args.value("masks") != nullptr && !load_marked_frames(args.value("masks"), true, frames)) {
    return kExitConfig;
  }
  ModelSetup setup;
  if (!load_model_setup("train-colors", args.value("calib"), args.value("config"), setup)) {
    return kExitConfig;
  }
  if (args.value("sidecars") != nullptr && !load_sidecars(args.value("sidecars"), setup, frames)) {
    return kExitConfig;
  }
  unsigned long long max_frames = ~0ULL;
  if (!unsigned_option(args, "train-colors", "max", 0U, ~0ULL, max_frames)) {
    return kExitUsage;
  }
  if (frames.size() > max_frames) {
    frames.resize(static_cast<std::size_t>(max_frames));
  }
  return kExitOk;
}

// Buffers reused from frame to frame: the image, its labels and its mask.
struct FrameBuffers {
  std::vector<std::uint8_t> pixels;
  std::vector<std::uint8_t> label;
  std::vector<std::uint8_t> mask_samples;
  DecodedMask mask;
};

// Reads a frame's image and mask (if any) into `buffers`. On failure reports
// it, marks the frame unusable and returns false.
bool read_frame(ImageReader& reader, Frame& frame, FrameBuffers& buffers, ImageView& view) {
  char error[512];
  if (!reader.read(frame.image.c_str(), buffers.pixels, view, error, sizeof error)) {
    std::fprintf(stderr, "tcpest train-colors: %s: %s (skipped)\n", frame.image.c_str(), error);
    frame.usable = false;
    return false;
  }
  if (frame.mask.empty()) {
    return true;
  }
  PnmInfo info;
  if (!reader.read_pnm(frame.mask.c_str(), buffers.mask_samples, info, error, sizeof error)) {
    std::fprintf(stderr, "tcpest train-colors: mask %s: %s (frame skipped)\n", frame.mask.c_str(), error);
    frame.usable = false;
    return false;
  }
  if (info.width != view.width || info.height != view.height) {
    std::fprintf(stderr, "tcpest train-colors: mask %s is %dx%d but image %s is %dx%d (frame skipped)\n",
                 frame.mask.c_str(), info.width, info.height, frame.image.c_str(), view.width, view.height);
    frame.usable = false;
    return false;
  }
  decode_mask(buffers.mask_samples, info, buffers.mask);
  if (buffers.mask.marked == 0U && buffers.mask.background == 0U) {
    std::fprintf(stderr, "tcpest train-colors: mask %s marks no pixel (frame skipped)\n", frame.mask.c_str());
    frame.usable = false;
    return false;
  }
  return true;
}

// Index of pixel (x, y) in a frame's labels.
std::size_t pixel_at(const ImageView& view, int x, int y) noexcept {
  return static_cast<std::size_t>(y) * static_cast<std::size_t>(view.width) + static_cast<std::size_t>(x);
}

// A coordinate (pixels) truncated and clamped to the frame's columns / rows.
int clamp_x(const ImageView& view, double v) noexcept {
  return std::max(0, std::min(view.width - 1, static_cast<int>(v)));
}
int clamp_y(const ImageView& view, double v) noexcept {
  return std::max(0, std::min(view.height - 1, static_cast<int>(v)));
}

// The automatic background rule: every pixel is background except those in
// the marks' joint bounding box grown by half its size (+10 px), unused.
// `mask` is the frame's decoded mask, nullptr if it has none.
void label_far_background(const Frame& frame, const DecodedMask* mask, const ImageView& view,
                          std::vector<std::uint8_t>& label) {
  const std::size_t pixel_count = static_cast<std::size_t>(view.width) * static_cast<std::size_t>(view.height);
  // Labels: 1 blue, 2 yellow, 0 background, 3 unused (near the marks).
  label.assign(pixel_count, 0U);
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  const auto grow = [&](double x, double y) {
    x0 = std::min(x0, x);
    y0 = std::min(y0, y);
    x1 = std::max(x1, x);
    y1 = std::max(y1, y);
  };
  for (const Polygon& p : frame.polygons) {
    for (const vision::Point& q : p.points) {
      grow(q.x, q.y);
    }
  }
  for (const MarkedPixel& m : frame.pixels) {
    grow(m.x, m.y);
  }
  if (mask != nullptr && mask->marked > 0U) {
    grow(mask->x0, mask->y0);
    grow(mask->x1 + 1, mask->y1 + 1);
  }
  const double gx = 0.5 * (x1 - x0) + 10.0;
  const double gy = 0.5 * (y1 - y0) + 10.0;
  for (int y = clamp_y(view, y0 - gy); y <= clamp_y(view, y1 + gy); ++y) {
    for (int x = clamp_x(view, x0 - gx); x <= clamp_x(view, x1 + gx); ++x) {
      label[pixel_at(view, x, y)] = kUnused;
    }
  }
}

// Labels the pixels inside the frame's polygons and its marked pixels with
// their class.
void label_marks(const Frame& frame, const ImageView& view, std::vector<std::uint8_t>& label) {
  for (const Polygon& p : frame.polygons) {
    double px0 = 1e30, py0 = 1e30, px1 = -1e30, py1 = -1e30;
    for (const vision::Point& q : p.points) {
      px0 = std::min(px0, q.x);
      py0 = std::min(py0, q.y);
      px1 = std::max(px1, q.x);
      py1 = std::max(py1, q.y);
    }
    for (int y = clamp_y(view, py0); y <= clamp_y(view, py1 + 1.0); ++y) {
      for (int x = clamp_x(view, px0); x <= clamp_x(view, px1 + 1.0); ++x) {
        if (inside(p.points, x, y)) {
          label[pixel_at(view, x, y)] = static_cast<std::uint8_t>(p.cls);
        }
      }
    }
  }
  for (const MarkedPixel& m : frame.pixels) {
    if (m.x >= 0 && m.y >= 0 && m.x < view.width && m.y < view.height) {
      label[pixel_at(view, m.x, m.y)] = static_cast<std::uint8_t>(m.cls);
    }
  }
}

// Every pixel's label for a frame read by read_frame: background, marks and
// mask; kUnused where nothing is known.
void label_frame(const Frame& frame, const ImageView& view, FrameBuffers& buffers) {
  const bool has_mask = !frame.mask.empty();
  const DecodedMask& mask = buffers.mask;
  std::vector<std::uint8_t>& label = buffers.label;
  const std::size_t pixel_count = static_cast<std::size_t>(view.width) * static_cast<std::size_t>(view.height);
  if (has_mask && mask.background > 0U) {
    // Explicit background samples replace the automatic rule.
    label.assign(pixel_count, kUnused);
  } else {
    label_far_background(frame, has_mask ? &mask : nullptr, view, label);
  }
  label_marks(frame, view, label);
  if (has_mask) {
    for (std::size_t i = 0U; i < pixel_count; ++i) {
      if (mask.labels[i] != kUnused) {
        label[i] = mask.labels[i];  // the mask wins where it overlaps a polygon
      }
    }
  }
}

// Adds the labelled pixels of a frame to the trainer: pass 0 trains the
// Gaussians, pass 1 the thresholds.
void add_samples(vision::ColorTrainer& trainer, const ImageView& view, const std::vector<std::uint8_t>& label,
                 int pass) noexcept {
  for (int y = 0; y < view.height; ++y) {
    const std::uint8_t* row = view.row(y);
    const std::uint8_t* lab_row = label.data() + pixel_at(view, 0, y);
    for (int x = 0; x < view.width; ++x) {
      if (lab_row[x] == kUnused) {
        continue;
      }
      const auto cls = static_cast<vision::PixelClass>(lab_row[x]);
      const std::uint8_t* c = row + static_cast<std::ptrdiff_t>(3) * x;
      if (pass == 0) {
        trainer.add_sample(cls, c[0], c[1], c[2]);
      } else {
        trainer.add_threshold_sample(cls, c[0], c[1], c[2]);
      }
    }
  }
}

// Trains the model in two passes over the usable frames (Gaussians, then
// thresholds). Returns kExitOk, else the exit code (reported).
int train(std::vector<Frame>& frames, vision::ColorTrainer& trainer) {
  ImageReader reader;
  if (!reader.init(3840, 2160)) {
    std::fprintf(stderr, "tcpest train-colors: JPEG decoder initialisation failed\n");
    return kExitFailure;
  }
  FrameBuffers buffers;
  for (int pass = 0; pass < 2; ++pass) {
    for (Frame& frame : frames) {
      if (!frame.usable) {
        continue;  // reported in pass 1
      }
      ImageView view;
      if (!read_frame(reader, frame, buffers, view)) {
        continue;
      }
      label_frame(frame, view, buffers);
      add_samples(trainer, view, buffers.label, pass);
    }
    if (pass == 0 && !trainer.finish_gaussians()) {
      std::fprintf(stderr, "tcpest train-colors: too few marked pixels (blue %llu, yellow %llu; need %llu each)\n",
                   static_cast<unsigned long long>(trainer.samples(vision::PixelClass::Blue)),
                   static_cast<unsigned long long>(trainer.samples(vision::PixelClass::Yellow)),
                   static_cast<unsigned long long>(vision::ColorTrainer::kMinSamples));
      return kExitFailure;
    }
  }
  return kExitOk;
}

// Reports what was trained on and writes the model to --out (default:
// standard output). Returns the command's exit code.
int write_model(const char* out_path, const std::vector<Frame>& frames, vision::ColorTrainer& trainer) {
  const vision::ColorModel model = trainer.finish();
  char text[2048];
  const std::size_t n = vision::format_color_model(model, text, sizeof text);
  const std::size_t used =
      static_cast<std::size_t>(std::count_if(frames.begin(), frames.end(), [](const Frame& f) { return f.usable; }));
  std::fprintf(stderr, "tcpest train-colors: %zu frames (%zu skipped), %llu blue, %llu yellow, %llu background pixels\n",
               used, frames.size() - used, static_cast<unsigned long long>(trainer.samples(vision::PixelClass::Blue)),
               static_cast<unsigned long long>(trainer.samples(vision::PixelClass::Yellow)),
               static_cast<unsigned long long>(trainer.samples(vision::PixelClass::Background)));
  if (out_path == nullptr) {
    std::fwrite(text, 1U, n, stdout);
    return kExitOk;
  }
  std::FILE* f = std::fopen(out_path, "wb");
  if (f == nullptr || std::fwrite(text, 1U, n, f) != n || std::fclose(f) != 0) {
    std::fprintf(stderr, "tcpest train-colors: cannot write %s\n", out_path);
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace

int cmd_train_colors(int argc, char** argv) {
  Args args;
  char error[512];
  if (!args.parse(argc, argv, 1, kSpecs, kSpecCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest train-colors: %s\n", error);
    return kExitUsage;
  }
  if (args.help_requested() ||
      (args.value("polygons") == nullptr && args.value("masks") == nullptr && args.value("sidecars") == nullptr)) {
    print_usage("tcpest train-colors (--polygons FILE.json | --masks FILE.json | --sidecars DIR)... "
                "[--out MODEL.json] [--max N]",
                "Trains the blue/yellow colour model (a*b* Gaussians, Mahalanobis thresholds) from marked frames.\n"
                "Masks: 8-bit binary PPM (blue, yellow, black = background, other = unused) or PGM\n"
                "(1 blue, 2 yellow, 3 background), the size of the image; see docs/vision.md.",
                kSpecs, kSpecCount);
    return args.help_requested() ? kExitOk : kExitUsage;
  }
  std::vector<Frame> frames;
  const int loaded = load_all_frames(args, frames);
  if (loaded != kExitOk) {
    return loaded;
  }
  vision::ColorTrainer trainer;
  const int trained = train(frames, trainer);
  if (trained != kExitOk) {
    return trained;
  }
  return write_model(args.value("out"), frames, trainer);
}

}  // namespace cli
}  // namespace tcpest
