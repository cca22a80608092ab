#include "tcpest/vision/color_model.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <cstdio>

#include "sampling.hpp"
#include "tcpest/common/json.hpp"

namespace tcpest {
namespace vision {
namespace {

// Cube root of t in (kDelta^3, ~1.1]: a first guess from the exponent bits
// (within ~4 %), then two Halley steps (cubic convergence: relative error
// < 1e-13 over the range; two divisions instead of libm's cbrt, which matters
// in stage 4 and in the model-guided corners).
double cube_root(double t) noexcept {
  std::uint64_t bits = 0U;
  std::memcpy(&bits, &t, sizeof bits);
  bits = bits / 3U + 0x2A9F7893782DA1CEULL;  // divides the exponent by 3
  double y = 0.0;
  std::memcpy(&y, &bits, sizeof y);
  for (int i = 0; i < 2; ++i) {
    const double y3 = y * y * y;
    y *= (y3 + 2.0 * t) / (2.0 * y3 + t);
  }
  return y;
}

double lab_f(double t) noexcept {
  constexpr double kDelta = 6.0 / 29.0;
  constexpr double kDelta3 = kDelta * kDelta * kDelta;
  return (t > kDelta3) ? cube_root(t) : t / (3.0 * kDelta * kDelta) + 4.0 / 29.0;
}

constexpr double kScoreClamp = 10.0;

double clamp_score(double v) noexcept {
  if (v > kScoreClamp) {
    return kScoreClamp;
  }
  if (v < -kScoreClamp) {
    return -kScoreClamp;
  }
  return v;
}

}  // namespace

Lab srgb_to_lab(std::uint8_t red, std::uint8_t green, std::uint8_t blue) noexcept {
  const detail::LinearLight& linear = detail::linear_light();
  return linear_to_lab(linear.of_code(red), linear.of_code(green), linear.of_code(blue));
}

double srgb_code_to_linear(std::uint8_t code) noexcept { return detail::linear_light().of_code(code); }

Lab linear_to_lab(double r, double g, double b) noexcept {
  // sRGB primaries, D65 white (IEC 61966-2-1).
  const double x = 0.4124564 * r + 0.3575761 * g + 0.1804375 * b;
  const double y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
  const double z = 0.0193339 * r + 0.1191920 * g + 0.9503041 * b;
  const double fx = lab_f(x / 0.95047);
  const double fy = lab_f(y);
  const double fz = lab_f(z / 1.08883);
  return Lab{116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

void lab_to_linear(const Lab& lab, double& red, double& green, double& blue) noexcept {
  constexpr double kDelta = 6.0 / 29.0;
  const auto finv = [](double f) {
    return f > kDelta ? f * f * f : 3.0 * kDelta * kDelta * (f - 4.0 / 29.0);
  };
  const double fy = (lab.l + 16.0) / 116.0;
  const double x = 0.95047 * finv(fy + lab.a / 500.0);
  const double y = finv(fy);
  const double z = 1.08883 * finv(fy - lab.b / 200.0);
  red = 3.2404542 * x - 1.5371385 * y - 0.4985314 * z;
  green = -0.9692660 * x + 1.8760108 * y + 0.0415560 * z;
  blue = 0.0556434 * x - 0.2040259 * y + 1.0572252 * z;
}

double ColorGaussian::distance(double a, double b) const noexcept {
  const double det = cov_aa * cov_bb - cov_ab * cov_ab;
  if (!(det > 0.0)) {
    return 1e9;
  }
  const double da = a - mean_a;
  const double db = b - mean_b;
  const double d2 = (cov_bb * da * da - 2.0 * cov_ab * da * db + cov_aa * db * db) / det;
  return std::sqrt(d2 > 0.0 ? d2 : 0.0);
}

bool ColorGaussian::valid() const noexcept {
  const double det = cov_aa * cov_bb - cov_ab * cov_ab;
  return std::fabs(mean_a) <= kMaxColorMeanAbs && std::fabs(mean_b) <= kMaxColorMeanAbs && std::isfinite(det) &&
         cov_aa > 0.0 && cov_aa <= kMaxColorVariance && cov_bb > 0.0 && cov_bb <= kMaxColorVariance && det > 0.0 &&
         threshold > 0.0 && threshold <= kMaxColorThreshold;
}

PixelClass ColorModel::classify(std::uint8_t red, std::uint8_t green, std::uint8_t blue_value) const noexcept {
  const Lab lab = srgb_to_lab(red, green, blue_value);
  if (lab.l < min_lightness) {
    return PixelClass::Background;
  }
  const double db = blue.distance(lab.a, lab.b) / blue.threshold;
  const double dy = yellow.distance(lab.a, lab.b) / yellow.threshold;
  if (db < 1.0 && db <= dy) {
    return PixelClass::Blue;
  }
  if (dy < 1.0) {
    return PixelClass::Yellow;
  }
  return PixelClass::Background;
}

double ColorModel::yellow_minus_blue(std::uint8_t red, std::uint8_t green, std::uint8_t blue_value) const noexcept {
  // Position along the line from the blue mean to the yellow mean, -1 at
  // blue, +1 at yellow: linear in the chroma, so a pixel mixed with the
  // background (at the silhouette) keeps its sign.
  const Lab lab = srgb_to_lab(red, green, blue_value);
  const double ua = yellow.mean_a - blue.mean_a;
  const double ub = yellow.mean_b - blue.mean_b;
  const double len2 = ua * ua + ub * ub;
  if (!(len2 > 0.0)) {
    return 0.0;
  }
  const double da = lab.a - 0.5 * (yellow.mean_a + blue.mean_a);
  const double db = lab.b - 0.5 * (yellow.mean_b + blue.mean_b);
  return clamp_score(2.0 * (da * ua + db * ub) / len2);
}

double ColorModel::blue_margin(std::uint8_t red, std::uint8_t green, std::uint8_t blue_value) const noexcept {
  // Blue chroma fraction: the a*b* projected on the blue mean's direction
  // from neutral grey, 1 at the blue mean, 0 on grey; minus one half. Linear
  // in the chroma, so a pixel half blue, half grey (or dark) is near 0.
  const Lab lab = srgb_to_lab(red, green, blue_value);
  const double len2 = blue.mean_a * blue.mean_a + blue.mean_b * blue.mean_b;
  if (!(len2 > 0.0)) {
    return 0.0;
  }
  return clamp_score((lab.a * blue.mean_a + lab.b * blue.mean_b) / len2 - 0.5);
}

bool ColorModel::valid() const noexcept {
  return blue.valid() && yellow.valid() && std::isfinite(min_lightness) && min_lightness >= 0.0 &&
         min_lightness < 100.0;
}

// --- file format -----------------------------------------------------------

namespace {

// `value` within lo..hi (lo excluded when `lo_open`); false with the range
// written into `message`.
bool in_range(double value, double lo, double hi, bool lo_open, char* message, std::size_t capacity) noexcept {
  const bool above_lo = lo_open ? value > lo : value >= lo;
  if (above_lo && value <= hi) {
    return true;
  }
  static_cast<void>(std::snprintf(message, capacity, "%g is outside its plausible range %s%g, %g]", value,
                                  lo_open ? "(" : "[", lo, hi));  // truncation is fine
  return false;
}

// One class's Gaussian; false with the field and why in `bad_field`, `message`.
bool read_gaussian(const json::Document& doc, std::size_t object, ColorGaussian& out, const char*& bad_field,
                   char* message, std::size_t capacity) noexcept {
  copy_text(message, capacity, "missing, not numbers, or not a valid Gaussian");
  const auto mean = doc.member(object, "mean_ab");
  double m[2] = {0.0, 0.0};
  bad_field = "mean_ab";
  if (!mean.ok() || !doc.numbers(mean.value(), m, 2U).ok()) {
    return false;
  }
  if (!in_range(m[0], -kMaxColorMeanAbs, kMaxColorMeanAbs, false, message, capacity) ||
      !in_range(m[1], -kMaxColorMeanAbs, kMaxColorMeanAbs, false, message, capacity)) {
    return false;
  }
  const auto cov = doc.member(object, "covariance_ab");
  double c[3] = {0.0, 0.0, 0.0};
  bad_field = "covariance_ab";
  if (!cov.ok() || !doc.numbers(cov.value(), c, 3U).ok()) {
    return false;
  }
  if (!in_range(c[0], 0.0, kMaxColorVariance, true, message, capacity) ||
      !in_range(c[2], 0.0, kMaxColorVariance, true, message, capacity)) {
    return false;
  }
  const auto threshold = doc.member(object, "threshold_mahalanobis");
  bad_field = "threshold_mahalanobis";
  if (!threshold.ok() || !doc.number(threshold.value()).ok()) {
    return false;
  }
  out.threshold = doc.number(threshold.value()).value();
  if (!in_range(out.threshold, 0.0, kMaxColorThreshold, true, message, capacity)) {
    return false;
  }
  out.mean_a = m[0];
  out.mean_b = m[1];
  out.cov_aa = c[0];
  out.cov_ab = c[1];
  out.cov_bb = c[2];
  bad_field = "covariance_ab";
  copy_text(message, capacity, "not positive definite (cov_aa cov_bb - cov_ab^2 must be > 0)");
  return out.valid();
}

}  // namespace

Result<ColorModel, Diagnostic> parse_color_model(const char* text, std::size_t length,
                                                 const char* file_name) noexcept {
  using R = Result<ColorModel, Diagnostic>;
  static json::Token tokens[256];  // init-time only; a colour file has ~40 tokens
  json::Document doc(tokens, sizeof tokens / sizeof tokens[0]);
  const auto parsed = doc.parse(text, length);
  if (!parsed.ok()) {
    return R::failure(Diagnostic::make(file_name, parsed.error().line, "", json::to_string(parsed.error().code)));
  }
  if (doc.type(doc.root()) != json::TokenType::Object) {
    return R::failure(Diagnostic::make(file_name, 1U, "", "expected a JSON object"));
  }
  const auto format = doc.member(doc.root(), "format");
  if (!format.ok() || !doc.string_equals(format.value(), "tcpest-colors-1")) {
    return R::failure(Diagnostic::make(file_name, 0U, "format", "expected \"tcpest-colors-1\""));
  }
  ColorModel model;
  const auto min_l = doc.member(doc.root(), "min_lightness");
  if (min_l.ok()) {
    const auto v = doc.number(min_l.value());
    if (!v.ok()) {
      return R::failure(Diagnostic::make(file_name, 0U, "min_lightness", "not a number"));
    }
    model.min_lightness = v.value();
  }
  const char* names[2] = {"blue", "yellow"};
  ColorGaussian* targets[2] = {&model.blue, &model.yellow};
  for (int i = 0; i < 2; ++i) {
    const auto object = doc.member(doc.root(), names[i]);
    if (!object.ok() || doc.type(object.value()) != json::TokenType::Object) {
      return R::failure(Diagnostic::make(file_name, 0U, names[i], "missing class object"));
    }
    const char* bad_field = "";
    char message[128] = {};
    if (!read_gaussian(doc, object.value(), *targets[i], bad_field, message, sizeof message)) {
      char field[96];
      static_cast<void>(std::snprintf(field, sizeof field, "%s.%s", names[i], bad_field));  // truncation is fine
      return R::failure(Diagnostic::make(file_name, 0U, field, message));
    }
  }
  if (!model.valid()) {
    return R::failure(Diagnostic::make(file_name, 0U, "min_lightness", "out of range 0..100"));
  }
  return R::success(model);
}

std::size_t format_color_model(const ColorModel& model, char* out, std::size_t capacity) noexcept {
  const int n = std::snprintf(
      out, capacity,
      "{\n"
      "  \"format\": \"tcpest-colors-1\",\n"
      "  \"space\": \"CIE L*a*b* a*b* plane, D65 white, sRGB input\",\n"
      "  \"min_lightness\": %.3f,\n"
      "  \"blue\": {\"mean_ab\": [%.6f, %.6f], \"covariance_ab\": [%.6f, %.6f, %.6f], "
      "\"threshold_mahalanobis\": %.4f},\n"
      "  \"yellow\": {\"mean_ab\": [%.6f, %.6f], \"covariance_ab\": [%.6f, %.6f, %.6f], "
      "\"threshold_mahalanobis\": %.4f}\n"
      "}\n",
      model.min_lightness, model.blue.mean_a, model.blue.mean_b, model.blue.cov_aa, model.blue.cov_ab,
      model.blue.cov_bb, model.blue.threshold, model.yellow.mean_a, model.yellow.mean_b, model.yellow.cov_aa,
      model.yellow.cov_ab, model.yellow.cov_bb, model.yellow.threshold);
  if (n < 0 || static_cast<std::size_t>(n) >= capacity) {
    return 0U;
  }
  return static_cast<std::size_t>(n);
}

// --- training --------------------------------------------------------------

void ColorTrainer::add_sample(PixelClass cls, std::uint8_t red, std::uint8_t green, std::uint8_t blue) noexcept {
  if (cls == PixelClass::Background) {
    return;
  }
  const Lab lab = srgb_to_lab(red, green, blue);
  if (lab.l < model_.min_lightness) {
    return;
  }
  Moments& m = moments_[cls == PixelClass::Blue ? 0 : 1];
  ++m.n;
  m.sa += lab.a;
  m.sb += lab.b;
  m.saa += lab.a * lab.a;
  m.sab += lab.a * lab.b;
  m.sbb += lab.b * lab.b;
}

bool ColorTrainer::finish_gaussians() noexcept {
  ColorGaussian* targets[2] = {&model_.blue, &model_.yellow};
  for (int i = 0; i < 2; ++i) {
    const Moments& m = moments_[i];
    if (m.n < kMinSamples) {
      return false;
    }
    const double n = static_cast<double>(m.n);
    ColorGaussian& g = *targets[i];
    g.mean_a = m.sa / n;
    g.mean_b = m.sb / n;
    // A floor of 0.25 (a*b* units squared) keeps a perfectly flat rendered
    // colour from giving a singular covariance.
    g.cov_aa = m.saa / n - g.mean_a * g.mean_a + 0.25;
    g.cov_ab = m.sab / n - g.mean_a * g.mean_b;
    g.cov_bb = m.sbb / n - g.mean_b * g.mean_b + 0.25;
    g.threshold = 3.0;
    if (!g.valid()) {
      return false;
    }
  }
  return true;
}

void ColorTrainer::add_threshold_sample(PixelClass cls, std::uint8_t red, std::uint8_t green,
                                        std::uint8_t blue) noexcept {
  const Lab lab = srgb_to_lab(red, green, blue);
  if (lab.l < model_.min_lightness) {
    return;
  }
  const ColorGaussian* g[2] = {&model_.blue, &model_.yellow};
  for (int i = 0; i < 2; ++i) {
    const bool own = (i == 0 && cls == PixelClass::Blue) || (i == 1 && cls == PixelClass::Yellow);
    const bool background = (cls == PixelClass::Background);
    if (!own && !background) {
      continue;
    }
    const double d = g[i]->distance(lab.a, lab.b);
    int bin = static_cast<int>(d / kBinWidth);
    if (!(d >= 0.0) || bin > kBins) {
      bin = kBins;
    }
    const int which = own ? 0 : 1;
    ++histogram_[i][which][static_cast<std::size_t>(bin)];
    ++histogram_total_[i][which];
  }
}

double ColorTrainer::quantile(const std::array<std::uint32_t, kBins + 1>& histogram, std::uint64_t total,
                              double q) noexcept {
  if (total == 0U) {
    return static_cast<double>(kBins) * kBinWidth;
  }
  const double target = q * static_cast<double>(total);
  double cumulative = 0.0;
  for (std::size_t i = 0U; i < histogram.size(); ++i) {
    cumulative += static_cast<double>(histogram[i]);
    if (cumulative >= target) {
      return static_cast<double>(i + 1U) * kBinWidth;
    }
  }
  return static_cast<double>(kBins) * kBinWidth;
}

ColorModel ColorTrainer::finish() const noexcept {
  ColorModel out = model_;
  ColorGaussian* g[2] = {&out.blue, &out.yellow};
  for (int i = 0; i < 2; ++i) {
    const double own = quantile(histogram_[i][0], histogram_total_[i][0], kOwnQuantile);
    const double floor = quantile(histogram_[i][0], histogram_total_[i][0], kFloorQuantile);
    const double background = quantile(histogram_[i][1], histogram_total_[i][1], kBackgroundQuantile);
    double t = own;
    if (histogram_total_[i][1] > 0U && background < t) {
      t = background;
    }
    if (t < floor) {
      t = floor;
    }
    if (t > kMaxThreshold) {
      t = kMaxThreshold;
    }
    g[i]->threshold = t;
  }
  return out;
}

std::uint64_t ColorTrainer::samples(PixelClass cls) const noexcept {
  if (cls == PixelClass::Background) {
    return histogram_total_[0][1];
  }
  return moments_[cls == PixelClass::Blue ? 0 : 1].n;
}

}  // namespace vision
}  // namespace tcpest
