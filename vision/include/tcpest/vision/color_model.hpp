// The colour model of the markers (paper section 2.3, preliminary step): two
// 2-D Gaussians, blue and yellow, in the a*b* plane of CIE L*a*b* (D65 white,
// sRGB input). A pixel belongs to a class when its Mahalanobis distance to
// that class is below the class's threshold (and is the smaller of the two).
// The thresholds come from training data (see ColorTrainer) and are stored
// with the model. This is the exact classifier; the loop uses the lookup table
// of classifier_lut.hpp built from it at start-up.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "tcpest/common/diagnostic.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace vision {

enum class PixelClass : std::uint8_t { Background = 0, Blue = 1, Yellow = 2 };

struct Lab {
  double l = 0.0;  // L*, 0..100
  double a = 0.0;  // a*
  double b = 0.0;  // b*
};

// sRGB (8 bit per channel, IEC 61966-2-1 transfer curve) to CIE L*a*b*, D65.
Lab srgb_to_lab(std::uint8_t red, std::uint8_t green, std::uint8_t blue) noexcept;
// An 8-bit sRGB code's linear light (0..1, IEC 61966-2-1).
double srgb_code_to_linear(std::uint8_t code) noexcept;
// Linear-light sRGB (0..1 nominal) to L*a*b* and back (D65): light mixes
// linearly, so a blur is modelled in linear light between the two.
Lab linear_to_lab(double red, double green, double blue) noexcept;
void lab_to_linear(const Lab& lab, double& red, double& green, double& blue) noexcept;

// Plausible ranges of a model file (docs/model.md, "Plausible ranges"). The
// a*b* of sRGB colours lie within about +-128; a variance above 1e5 (a
// standard deviation of 316) spans more than the whole plane; a trained
// threshold is at most ColorTrainer::kMaxThreshold (6), and beyond a
// Mahalanobis distance of 100 every colour would belong to the class.
constexpr double kMaxColorMeanAbs = 200.0;     // |mean a*|, |mean b*|
constexpr double kMaxColorVariance = 1.0e5;    // cov_aa, cov_bb; |cov_ab| follows from det > 0
constexpr double kMaxColorThreshold = 100.0;   // Mahalanobis distance, 0 < t <= 100

struct ColorGaussian {
  double mean_a = 0.0;     // |.| <= kMaxColorMeanAbs
  double mean_b = 0.0;     // |.| <= kMaxColorMeanAbs
  double cov_aa = 1.0;     // 0 < . <= kMaxColorVariance
  double cov_ab = 0.0;     // cov_aa cov_bb - cov_ab^2 > 0
  double cov_bb = 1.0;     // 0 < . <= kMaxColorVariance
  double threshold = 3.0;  // Mahalanobis distance (not squared) accepted as this class, 0 < t <= kMaxColorThreshold

  // Mahalanobis distance of (a, b); a large number for an invalid covariance.
  double distance(double a, double b) const noexcept;
  bool valid() const noexcept;
};

struct ColorModel {
  ColorGaussian blue{};
  ColorGaussian yellow{};
  // Pixels darker than this are background whatever their chroma: in the dark
  // the a*b* of an 8-bit pixel is dominated by quantisation noise.
  double min_lightness = 8.0;

  PixelClass classify(std::uint8_t red, std::uint8_t green, std::uint8_t blue) const noexcept;
  // The signed chroma score used along the borders (stage 4): the a*b*
  // position along the line from the blue mean (-1) to the yellow mean (+1),
  // clamped to +/- 10.
  double yellow_minus_blue(std::uint8_t red, std::uint8_t green, std::uint8_t blue) const noexcept;
  // Blue against neutral (shaft, grasper): the a*b* projected on the blue
  // mean's direction, as a fraction of the mean, minus 1/2 (> 0 on blue).
  double blue_margin(std::uint8_t red, std::uint8_t green, std::uint8_t blue) const noexcept;
  bool valid() const noexcept;
};

// The model shipped in config/colors.json, built in so that the loop works
// without any file. Trained on lab frames rendered by revision fe795fd; how to
// reproduce it, and why it was not retrained: docs/vision.md, "Colour model (offline)".
ColorModel default_color_model() noexcept;

// Reads a colour model file (JSON, format "tcpest-colors-1", see
// docs/vision.md). Errors name the field.
Result<ColorModel, Diagnostic> parse_color_model(const char* text, std::size_t length,
                                                 const char* file_name) noexcept;
// Writes the model as JSON; returns the number of characters written (without
// the terminating NUL), 0 if the buffer is too small.
std::size_t format_color_model(const ColorModel& model, char* out, std::size_t capacity) noexcept;

// Offline training from labelled pixels, in two passes over the data:
// pass 1 (add_sample for blue and yellow pixels) estimates the Gaussians,
// pass 2 (add_threshold_sample for blue, yellow and background pixels)
// collects the histograms of Mahalanobis distances from which the thresholds
// are chosen (rule in finish(), documented in docs/vision.md).
class ColorTrainer {
 public:
  void add_sample(PixelClass cls, std::uint8_t red, std::uint8_t green, std::uint8_t blue) noexcept;
  // Ends pass 1. False when a class has fewer than kMinSamples samples or a
  // degenerate covariance.
  bool finish_gaussians() noexcept;
  void add_threshold_sample(PixelClass cls, std::uint8_t red, std::uint8_t green, std::uint8_t blue) noexcept;
  ColorModel finish() const noexcept;

  std::uint64_t samples(PixelClass cls) const noexcept;
  static constexpr std::uint64_t kMinSamples = 200U;
  // Threshold rule parameters.
  static constexpr double kOwnQuantile = 0.995;        // keep 99.5 % of the class's own pixels ...
  static constexpr double kBackgroundQuantile = 0.001;  // ... unless 0.1 % of the background would get in
  static constexpr double kFloorQuantile = 0.95;        // ... but never below the class's 95 % quantile
  static constexpr double kMaxThreshold = 6.0;

 private:
  static constexpr int kBins = 600;  // Mahalanobis distance histogram, 0.02 wide bins, 0..12
  static constexpr double kBinWidth = 0.02;
  struct Moments {
    std::uint64_t n = 0U;
    double sa = 0.0, sb = 0.0, saa = 0.0, sab = 0.0, sbb = 0.0;
  };
  static double quantile(const std::array<std::uint32_t, kBins + 1>& histogram, std::uint64_t total,
                         double q) noexcept;
  Moments moments_[2]{};
  ColorModel model_{};
  // [class][0 = own pixels, 1 = background pixels]
  std::array<std::uint32_t, kBins + 1> histogram_[2][2]{};
  std::uint64_t histogram_total_[2][2]{};
};

}  // namespace vision
}  // namespace tcpest
