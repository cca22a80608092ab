#include "tcpest/render/sidecar.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

#include "tcpest/common/json.hpp"
#include "tcpest/common/text_buffer.hpp"

namespace tcpest {
namespace render {

namespace {

using solver::kNumCorners;

using Writer = TextBuffer;

void add_numbers(Writer& w, const double* values, int count) noexcept {
  w.add("[");
  for (int i = 0; i < count; ++i) {
    w.add("%s%.12g", i > 0 ? ", " : "", values[i]);
  }
  w.add("]");
}

void add_bools(Writer& w, const std::array<bool, kNumCorners>& values) noexcept {
  w.add("[");
  for (int i = 0; i < kNumCorners; ++i) {
    w.add("%s%s", i > 0 ? ", " : "", values[static_cast<std::size_t>(i)] ? "true" : "false");
  }
  w.add("]");
}

// Escapes nothing: names we write are plain file names; quotes and
// backslashes are replaced so the JSON stays valid.
void add_string(Writer& w, const char* text) noexcept {
  char clean[160];
  std::size_t n = 0U;
  for (const char* p = text; *p != '\0' && n + 1U < sizeof clean; ++p) {
    const char c = *p;
    clean[n++] = (c == '"' || c == '\\' || static_cast<unsigned char>(c) < 0x20U) ? '_' : c;
  }
  clean[n] = '\0';
  w.add("\"%s\"", clean);
}

void add_instrument(Writer& w, const SidecarInstrument& s, const char* indent) noexcept {
  if (s.has_r) {
    w.add("%s\"r\": ", indent);
    add_numbers(w, s.r.data(), solver::kNumParams);
    w.add(",\n");
  }
  if (s.has_tcp) {
    w.add("%s\"tcp\": ", indent);
    add_numbers(w, s.tcp.data(), 3);
    w.add(",\n");
  }
  w.add("%s\"corners\": [", indent);
  for (int k = 0; k < kNumCorners; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    w.add("%s", k > 0 ? ", " : "");
    if (s.corner_present[ku]) {
      w.add("[%.12g, %.12g]", s.corners[ku].x(), s.corners[ku].y());
    } else {
      w.add("null");
    }
  }
  w.add("],\n%s\"corner_in_image\": ", indent);
  add_bools(w, s.corner_in_image);
  w.add(",\n%s\"corner_visible\": ", indent);
  add_bools(w, s.corner_visible);
  w.add(",\n%s\"instrument_view\": \"%s\"", indent, to_string(s.view));
}

SidecarInstrument from_truth(const InstrumentTruth& t) noexcept {
  SidecarInstrument s;
  s.has_r = true;
  s.r = t.r;
  s.has_tcp = true;
  s.tcp = t.tcp;
  s.corners = t.corners;
  s.corner_present = t.present;
  s.corner_in_image = t.in_image;
  s.corner_visible = t.visible;
  s.view = t.view;
  return s;
}

constexpr std::size_t kMaxTokens = 1024U;

class Reader {
 public:
  Reader(const json::Document& doc, const char* file) noexcept : doc_(doc), file_(file) {}
  Diagnostic error(const char* field, const char* message) const noexcept {
    return Diagnostic::make(file_, 0U, field, message);
  }
  // Optional member: kNone when absent.
  std::size_t find(std::size_t object, const char* key) const noexcept {
    const auto m = doc_.member(object, key);
    return m.ok() ? m.value() : json::kNone;
  }
  bool numbers(std::size_t index, double* out, std::size_t count) const noexcept {
    return doc_.numbers(index, out, count).ok();
  }
  bool bools(std::size_t index, std::array<bool, kNumCorners>& out) const noexcept {
    if (doc_.type(index) != json::TokenType::Array || doc_.array_size(index) != static_cast<std::size_t>(kNumCorners)) {
      return false;
    }
    for (std::size_t k = 0; k < static_cast<std::size_t>(kNumCorners); ++k) {
      const auto e = doc_.element(index, k);
      if (!e.ok()) {
        return false;
      }
      const json::TokenType type = doc_.type(e.value());
      if (type != json::TokenType::True && type != json::TokenType::False) {
        return false;
      }
      out[k] = type == json::TokenType::True;
    }
    return true;
  }
  const json::Document& doc() const noexcept { return doc_; }

 private:
  const json::Document& doc_;
  const char* file_;
};

bool parse_view(const json::Document& doc, std::size_t index, InstrumentView& view) noexcept {
  const InstrumentView all[] = {InstrumentView::Visible, InstrumentView::BehindCamera, InstrumentView::OutOfView};
  for (InstrumentView v : all) {
    if (doc.string_equals(index, to_string(v))) {
      view = v;
      return true;
    }
  }
  return false;
}

// Reads one instrument's keys from `object`. Returns nullptr on success,
// else the failing field name (message in `message`).
const char* parse_instrument(const Reader& rd, std::size_t object, SidecarInstrument& s, const char*& message) noexcept {
  const json::Document& doc = rd.doc();
  std::size_t i = rd.find(object, "r");
  if (i != json::kNone) {
    double r[solver::kNumParams];
    if (!rd.numbers(i, r, solver::kNumParams)) {
      message = "expected 7 numbers [x_ch, y_ch, psi, mu, lambda, phi, theta]";
      return "r";
    }
    for (int q = 0; q < solver::kNumParams; ++q) {
      s.r[q] = r[q];
    }
    s.has_r = true;
  }
  i = rd.find(object, "tcp");
  if (i != json::kNone) {
    double t[3];
    if (!rd.numbers(i, t, 3U)) {
      message = "expected 3 numbers [x, y, z] in mm";
      return "tcp";
    }
    s.tcp = solver::Vec3(t[0], t[1], t[2]);
    s.has_tcp = true;
  }
  i = rd.find(object, "corners");
  if (i == json::kNone) {
    message = "missing (12 entries, [u, v] or null, k = 2 j + side)";
    return "corners";
  }
  if (doc.type(i) != json::TokenType::Array || doc.array_size(i) != static_cast<std::size_t>(kNumCorners)) {
    message = "expected an array of 12 entries, each [u, v] or null";
    return "corners";
  }
  for (std::size_t k = 0; k < static_cast<std::size_t>(kNumCorners); ++k) {
    const auto e = doc.element(i, k);
    if (!e.ok()) {
      message = "expected an array of 12 entries";
      return "corners";
    }
    if (doc.is_null(e.value())) {
      s.corner_present[k] = false;
      continue;
    }
    double uv[2];
    if (!rd.numbers(e.value(), uv, 2U)) {
      message = "each corner must be [u, v] (finite pixels) or null";
      return "corners";
    }
    s.corners[k] = solver::Vec2(uv[0], uv[1]);
    s.corner_present[k] = true;
  }
  s.corner_in_image = s.corner_present;
  i = rd.find(object, "corner_in_image");
  if (i != json::kNone && !rd.bools(i, s.corner_in_image)) {
    message = "expected 12 booleans";
    return "corner_in_image";
  }
  s.corner_visible = s.corner_in_image;
  i = rd.find(object, "corner_visible");
  if (i != json::kNone && !rd.bools(i, s.corner_visible)) {
    message = "expected 12 booleans";
    return "corner_visible";
  }
  for (std::size_t k = 0; k < static_cast<std::size_t>(kNumCorners); ++k) {
    if (s.corner_visible[k] && !s.corner_present[k]) {
      message = "a corner marked visible has no coordinates (null)";
      return "corner_visible";
    }
  }
  i = rd.find(object, "instrument_view");
  if (i != json::kNone && !parse_view(doc, i, s.view)) {
    message = "expected \"visible\", \"behind_camera\" or \"out_of_view\"";
    return "instrument_view";
  }
  return nullptr;
}

// The image's name, set name and integer keys (width, height, index).
// Returns nullptr on success, else the failing field name (message in `message`).
const char* parse_image_keys(const Reader& rd, std::size_t root, Sidecar& s, const char*& message) noexcept {
  const json::Document& doc = rd.doc();
  std::size_t i = rd.find(root, "image");
  if (i != json::kNone && !doc.string(i, s.image, sizeof s.image).ok()) {
    message = "expected a file name (at most 127 characters)";
    return "image";
  }
  i = rd.find(root, "set");
  if (i != json::kNone && !doc.string(i, s.set, sizeof s.set).ok()) {
    message = "expected a short string";
    return "set";
  }
  const char* int_keys[] = {"width", "height", "index"};
  int* int_values[] = {&s.width, &s.height, &s.index};
  for (std::size_t k = 0; k < 3U; ++k) {
    i = rd.find(root, int_keys[k]);
    if (i == json::kNone) {
      continue;
    }
    const auto v = doc.number(i);
    if (!v.ok() || v.value() != std::floor(v.value()) || std::fabs(v.value()) > 1e9) {
      message = "expected an integer";
      return int_keys[k];
    }
    *int_values[k] = static_cast<int>(v.value());
  }
  if (s.width < 0 || s.height < 0) {
    message = "image size must not be negative";
    return "width";
  }
  return nullptr;
}

// The seeds (seed, dataset_seed, world_seed), read from their digits in `text`.
// Returns nullptr on success, else the failing field name (message in `message`).
const char* parse_seeds(const Reader& rd, std::size_t root, const char* text, Sidecar& s,
                        const char*& message) noexcept {
  const json::Document& doc = rd.doc();
  const char* seed_keys[] = {"seed", "dataset_seed", "world_seed"};
  std::uint64_t* seed_values[] = {&s.seed, &s.dataset_seed, &s.scene.world_seed};
  for (std::size_t k = 0; k < 3U; ++k) {
    const std::size_t i = rd.find(root, seed_keys[k]);
    if (i == json::kNone) {
      continue;
    }
    const auto v = doc.number(i);
    if (!v.ok() || v.value() < 0.0 || v.value() != std::floor(v.value()) || v.value() > 1.8446744073709552e19) {
      message = "expected a non-negative 64-bit integer";
      return seed_keys[k];
    }
    // Seeds above 2^53 do not survive a double: read the digits.
    const json::Token& t = doc.token(i);
    std::uint64_t seed = 0U;
    for (std::uint32_t c = t.start; c < t.end; ++c) {
      const char ch = text[c];
      if (ch < '0' || ch > '9') {
        break;
      }
      seed = seed * 10U + static_cast<std::uint64_t>(ch - '0');
    }
    *seed_values[k] = seed;
    s.has_dataset_seed = s.has_dataset_seed || k == 1U;
    s.scene.seed = s.seed;
  }
  return nullptr;
}

// The prior, the hard cases and the time of the frame.
// Returns nullptr on success, else the failing field name (message in `message`).
const char* parse_frame_keys(const Reader& rd, std::size_t root, Sidecar& s, const char*& message) noexcept {
  const json::Document& doc = rd.doc();
  std::size_t i = rd.find(root, "prior");
  if (i != json::kNone && !doc.is_null(i)) {
    if (!rd.numbers(i, s.prior.data(), 3U)) {
      message = "expected [lambda mm, phi rad, theta rad] or null";
      return "prior";
    }
    s.has_prior = true;
  }
  i = rd.find(root, "hard_cases");
  if (i != json::kNone) {
    if (doc.type(i) != json::TokenType::Array) {
      message = "expected an array of names";
      return "hard_cases";
    }
    for (std::size_t e = 0; e < doc.array_size(i); ++e) {
      const auto el = doc.element(i, e);
      bool known = false;
      for (int b = 0; b < kNumHardCases && el.ok(); ++b) {
        if (doc.string_equals(el.value(), hard_case_name(b))) {
          s.hard_cases |= 1U << static_cast<unsigned>(b);
          known = true;
        }
      }
      if (!known) {
        message = "unknown hard case name";
        return "hard_cases";
      }
    }
  }
  i = rd.find(root, "time_s");
  if (i != json::kNone) {
    const auto v = doc.number(i);
    if (!v.ok()) {
      message = "expected a number";
      return "time_s";
    }
    s.has_time = true;
    s.time_s = v.value();
  }
  return nullptr;
}

// render.appearance and render.chroma_subsampling (written by `tcpest
// render --randomise`); absent: the default look. Returns nullptr on
// success, else the failing field name.
const char* parse_appearance(const Reader& rd, std::size_t render, Sidecar& s, const char*& message) noexcept {
  const json::Document& doc = rd.doc();
  const std::size_t chroma = rd.find(render, "chroma_subsampling");
  if (chroma != json::kNone) {
    bool named = false;
    for (const ChromaSubsampling c : {ChromaSubsampling::k420, ChromaSubsampling::k422, ChromaSubsampling::k444}) {
      if (doc.string_equals(chroma, to_string(c))) {
        s.chroma = c;
        named = true;
      }
    }
    if (!named) {
      message = "expected \"420\", \"422\" or \"444\"";
      return "render.chroma_subsampling";
    }
  }
  const std::size_t a = rd.find(render, "appearance");
  if (a == json::kNone) {
    return nullptr;
  }
  Appearance& ap = s.scene.appearance;
  const std::size_t lamp = rd.find(a, "lamp_offset_mm");
  if (lamp != json::kNone && !rd.numbers(lamp, ap.lamp_offset_mm.data(), 2U)) {
    message = "expected [x, y]";
    return "lamp_offset_mm";
  }
  const char* triples[] = {"blue_albedo", "yellow_albedo", "shaft_albedo", "grasper_albedo", "tissue_tint",
                           "white_balance"};
  double* triple_values[] = {ap.blue_albedo.data(),    ap.yellow_albedo.data(), ap.shaft_albedo.data(),
                             ap.grasper_albedo.data(), ap.tissue_tint.data(),   ap.white_balance.data()};
  for (std::size_t k = 0; k < 6U; ++k) {
    const std::size_t m = rd.find(a, triples[k]);
    if (m != json::kNone && !rd.numbers(m, triple_values[k], 3U)) {
      message = "expected [r, g, b]";
      return triples[k];
    }
  }
  const char* singles[] = {"stripe_gloss", "shaft_gloss", "grasper_gloss", "shaft_radius_scale",
                           "grasper_radius_scale"};
  double* single_values[] = {&ap.stripe_gloss, &ap.shaft_gloss, &ap.grasper_gloss, &ap.shaft_radius_scale,
                             &ap.grasper_radius_scale};
  for (std::size_t k = 0; k < 5U; ++k) {
    const std::size_t m = rd.find(a, singles[k]);
    if (m != json::kNone) {
      const auto v = doc.number(m);
      if (!v.ok()) {
        message = "expected a number";
        return singles[k];
      }
      *single_values[k] = v.value();
    }
  }
  if (!valid_appearance(ap)) {
    message = "outside what a render can show (docs/dataset-format.md)";
    return "render.appearance";
  }
  s.has_appearance = true;
  return nullptr;
}

// The "render" object's keys (a missing or non-object "render" leaves them).
// Returns nullptr on success, else the failing field name (message in `message`).
const char* parse_render_keys(const Reader& rd, std::size_t root, Sidecar& s, const char*& message) noexcept {
  const json::Document& doc = rd.doc();
  const std::size_t i = rd.find(root, "render");
  if (i == json::kNone || doc.type(i) != json::TokenType::Object) {
    return nullptr;
  }
  s.has_render = true;
  const char* keys[] = {"noise_sigma", "blur_sigma_px", "vignetting", "exposure", "tissue_depth_mm"};
  double* values[] = {&s.scene.noise_sigma, &s.scene.blur_sigma_px, &s.scene.vignetting, &s.scene.exposure,
                      &s.tissue_depth_mm};
  for (std::size_t k = 0; k < 5U; ++k) {
    const std::size_t m = rd.find(i, keys[k]);
    if (m != json::kNone) {
      const auto v = doc.number(m);
      if (!v.ok()) {
        message = "expected a number";
        return keys[k];
      }
      *values[k] = v.value();
    }
  }
  const char* int_render_keys[] = {"supersample", "jpeg_quality"};
  int* int_render_values[] = {&s.supersample, &s.jpeg_quality};
  for (std::size_t k = 0; k < 2U; ++k) {
    const std::size_t m = rd.find(i, int_render_keys[k]);
    if (m != json::kNone) {
      const auto v = doc.number(m);
      if (!v.ok() || std::fabs(v.value()) > 1e6) {
        message = "expected an integer";
        return int_render_keys[k];
      }
      *int_render_values[k] = static_cast<int>(v.value());
    }
  }
  const std::size_t blur = rd.find(i, "motion_blur_px");
  if (blur != json::kNone) {
    if (!rd.numbers(blur, s.motion_blur_px.data(), 2U)) {
      message = "expected [dx, dy] (px)";
      return "render.motion_blur_px";
    }
    s.has_motion_blur = true;
  }
  const std::size_t c = rd.find(i, "clean");
  s.scene.clean = c != json::kNone && doc.type(c) == json::TokenType::True;
  return parse_appearance(rd, i, s, message);
}

}  // namespace

Sidecar make_sidecar(const GroundTruth& truth, const SceneSpec& scene, const RenderSettings& settings, int width,
                     int height) noexcept {
  Sidecar s;
  s.width = width;
  s.height = height;
  s.seed = truth.seed;
  s.instrument = from_truth(truth.instruments[0]);
  s.hard_cases = truth.hard_cases;
  s.has_render = true;
  s.scene = scene;
  s.tissue_depth_mm = truth.tissue_depth_mm;
  s.supersample = settings.supersample;
  s.has_motion_blur = (truth.hard_cases & kHardMotionBlur) != 0U;
  s.motion_blur_px = {truth.motion_blur_dx_px, truth.motion_blur_dy_px};
  s.has_second = truth.instrument_count > 1;
  if (s.has_second) {
    s.second = from_truth(truth.instruments[1]);
  }
  return s;
}

std::size_t format_sidecar(const Sidecar& s, char* out, std::size_t capacity) noexcept {
  Writer w(out, capacity);
  w.add("{\n  \"format\": \"%s\",\n  \"image\": ", kSidecarFormat);
  add_string(w, s.image);
  w.add(",\n  \"width\": %d,\n  \"height\": %d,\n  \"set\": ", s.width, s.height);
  add_string(w, s.set);
  w.add(",\n  \"index\": %d,\n  \"seed\": %llu,\n", s.index, static_cast<unsigned long long>(s.seed));
  if (s.has_dataset_seed) {
    w.add("  \"dataset_seed\": %llu,\n", static_cast<unsigned long long>(s.dataset_seed));
  }
  if (s.scene.world_seed != 0U) {
    w.add("  \"world_seed\": %llu,\n", static_cast<unsigned long long>(s.scene.world_seed));
  }
  add_instrument(w, s.instrument, "  ");
  w.add(",\n  \"prior\": ");
  if (s.has_prior) {
    add_numbers(w, s.prior.data(), 3);
  } else {
    w.add("null");
  }
  w.add(",\n  \"hard_cases\": [");
  int n = 0;
  for (int b = 0; b < kNumHardCases; ++b) {
    if ((s.hard_cases & (1U << static_cast<unsigned>(b))) != 0U) {
      w.add("%s\"%s\"", n > 0 ? ", " : "", hard_case_name(b));
      ++n;
    }
  }
  w.add("]");
  if (s.has_time) {
    w.add(",\n  \"time_s\": %.12g", s.time_s);
  }
  if (s.has_render) {
    w.add(",\n  \"render\": {\"clean\": %s, \"noise_sigma\": %.6g, \"blur_sigma_px\": %.6g, \"vignetting\": %.6g, "
          "\"exposure\": %.6g, \"tissue_depth_mm\": %.6g, \"supersample\": %d, \"jpeg_quality\": %d",
          s.scene.clean ? "true" : "false", s.scene.noise_sigma, s.scene.blur_sigma_px, s.scene.vignetting,
          s.scene.exposure, s.tissue_depth_mm, s.supersample, s.jpeg_quality);
    if (s.has_motion_blur) {
      w.add(", \"motion_blur_px\": ");
      add_numbers(w, s.motion_blur_px.data(), 2);
    }
    if (s.has_appearance) {
      const Appearance& a = s.scene.appearance;
      w.add(",\n    \"chroma_subsampling\": \"%s\", \"appearance\": {\"blue_albedo\": ", to_string(s.chroma));
      add_numbers(w, a.blue_albedo.data(), 3);
      w.add(", \"yellow_albedo\": ");
      add_numbers(w, a.yellow_albedo.data(), 3);
      w.add(", \"stripe_gloss\": %.6g, \"shaft_albedo\": ", a.stripe_gloss);
      add_numbers(w, a.shaft_albedo.data(), 3);
      w.add(", \"shaft_gloss\": %.6g, \"grasper_albedo\": ", a.shaft_gloss);
      add_numbers(w, a.grasper_albedo.data(), 3);
      w.add(", \"grasper_gloss\": %.6g, \"tissue_tint\": ", a.grasper_gloss);
      add_numbers(w, a.tissue_tint.data(), 3);
      w.add(", \"white_balance\": ");
      add_numbers(w, a.white_balance.data(), 3);
      w.add(", \"shaft_radius_scale\": %.6g, \"grasper_radius_scale\": %.6g, \"lamp_offset_mm\": ",
            a.shaft_radius_scale, a.grasper_radius_scale);
      add_numbers(w, a.lamp_offset_mm.data(), 2);
      w.add("}");
    }
    w.add("}");
  }
  if (s.has_second) {
    w.add(",\n  \"instrument2\": {\n");
    add_instrument(w, s.second, "    ");
    w.add("\n  }");
  }
  w.add("\n}\n");
  return w.length();
}

Result<Sidecar, Diagnostic> parse_sidecar(const char* text, std::size_t length, const char* file) noexcept {
  using R = Result<Sidecar, Diagnostic>;
  static_assert(kMaxTokens * sizeof(json::Token) <= 32768U, "token array lives on the stack");
  json::Token tokens[kMaxTokens];
  json::Document doc(tokens, kMaxTokens);
  const auto parsed = doc.parse(text, length);
  if (!parsed.ok()) {
    return R::failure(Diagnostic::make(file, parsed.error().line, "", json::to_string(parsed.error().code)));
  }
  if (doc.type(doc.root()) != json::TokenType::Object) {
    return R::failure(Diagnostic::make(file, 1U, "", "a sidecar is a JSON object"));
  }
  Reader rd(doc, file);
  Sidecar s;
  const std::size_t root = doc.root();
  const char* message = "";
  const char* field = parse_instrument(rd, root, s.instrument, message);
  if (field == nullptr) {
    field = parse_image_keys(rd, root, s, message);
  }
  if (field == nullptr) {
    field = parse_seeds(rd, root, text, s, message);
  }
  if (field == nullptr) {
    field = parse_frame_keys(rd, root, s, message);
  }
  if (field == nullptr) {
    field = parse_render_keys(rd, root, s, message);
  }
  if (field != nullptr) {
    return R::failure(rd.error(field, message));
  }
  const std::size_t i = rd.find(root, "instrument2");
  if (i != json::kNone && !doc.is_null(i)) {
    if (doc.type(i) != json::TokenType::Object) {
      return R::failure(rd.error("instrument2", "expected an object"));
    }
    field = parse_instrument(rd, i, s.second, message);
    if (field != nullptr) {
      char name[96];
      static_cast<void>(std::snprintf(name, sizeof name, "instrument2.%s", field));  // truncation is harmless
      return R::failure(rd.error(name, message));
    }
    s.has_second = true;
  }
  return R::success(s);
}

Result<Sidecar, Diagnostic> read_sidecar_file(const char* path) noexcept {
  using R = Result<Sidecar, Diagnostic>;
  static_assert(kSidecarMaxBytes <= 65536U, "read buffer lives on the stack");
  char text[kSidecarMaxBytes];
  std::FILE* file = std::fopen(path, "rb");
  if (file == nullptr) {
    return R::failure(Diagnostic::make(path, 0U, "", "cannot open the sidecar"));
  }
  const std::size_t n = std::fread(text, 1U, sizeof text, file);
  const bool error = std::ferror(file) != 0;
  const bool more = n == sizeof text && std::fgetc(file) != EOF;
  static_cast<void>(std::fclose(file));  // read-only: a close error loses nothing
  if (error) {
    return R::failure(Diagnostic::make(path, 0U, "", "read error"));
  }
  if (more) {
    return R::failure(Diagnostic::make(path, 0U, "", "sidecar larger than 16 KiB"));
  }
  return parse_sidecar(text, n, path);
}

bool write_sidecar_file(const char* path, const Sidecar& sidecar) noexcept {
  char text[kSidecarMaxBytes];
  const std::size_t n = format_sidecar(sidecar, text, sizeof text);
  if (n == 0U) {
    return false;
  }
  std::FILE* file = std::fopen(path, "wb");
  if (file == nullptr) {
    return false;
  }
  const bool ok = std::fwrite(text, 1U, n, file) == n;
  return (std::fclose(file) == 0) && ok;
}

}  // namespace render
}  // namespace tcpest
