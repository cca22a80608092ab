#include "tcpest/solver/config_io.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace tcpest {
namespace solver {

namespace {

using CameraResult = Result<CameraIntrinsics, Diagnostic>;
using GeometryResult = Result<InstrumentGeometry, Diagnostic>;

bool read_number(const yaml::Document& doc, const char* path, double& out, Diagnostic& error) noexcept {
  if (!doc.has(path)) {
    return true;  // optional: keep the default
  }
  const auto value = doc.number(path);
  if (!value.ok()) {
    error = value.error();
    return false;
  }
  out = value.value();
  return true;
}

// `value`, the element `what` of the field `path`, within lo..hi (`unit`);
// false with the field, the value and the range named.
bool check_range(const yaml::Document& doc, const char* path, const char* what, double value, double lo, double hi,
                 const char* unit, Diagnostic& error) noexcept {
  if (value >= lo && value <= hi) {
    return true;
  }
  char message[128] = {};
  static_cast<void>(std::snprintf(message, sizeof message, "%s = %g is outside its plausible range %g..%g %s", what,
                                  value, lo, hi, unit));  // truncation is fine
  error = doc.error_at(doc.find(path), path, message);
  return false;
}

// The top-level keys of a camera calibration, every spelling included;
// everything else in the file is skipped as it is parsed (yaml::KeySet).
// ROS camera_info and OpenCV's calibration sample write camera_matrix /
// distortion_coefficients; many OpenCV programs cameraMatrix / distCoeffs;
// OpenCV's camera calibration tutorial Camera_Matrix / Distortion_Coefficients.
constexpr const char* kCameraInfoKeys[] = {
    "image_width",  "image_height", "distortion_model",        "camera_matrix", "distortion_coefficients",
    "cameraMatrix", "distCoeffs",   "Camera_Matrix",           "Distortion_Coefficients",
    "rectification_matrix", "projection_matrix"};
constexpr std::size_t kFirstMatrixSpelling = 3U;  // then pairs: camera matrix, distortion
constexpr std::size_t kMatrixSpellings = 3U;

// The matrices' key in this file and the paths below it.
struct MatrixPaths {
  const char* key = "";
  char rows[yaml::kMaxPath] = {};
  char cols[yaml::kMaxPath] = {};
  char dt[yaml::kMaxPath] = {};
  char data[yaml::kMaxPath] = {};
};

void set_paths(MatrixPaths& m, const char* key) noexcept {
  m.key = key;
  // The keys are the short constants above: every path fits.
  static_cast<void>(std::snprintf(m.rows, sizeof m.rows, "%s.rows", key));
  static_cast<void>(std::snprintf(m.cols, sizeof m.cols, "%s.cols", key));
  static_cast<void>(std::snprintf(m.dt, sizeof m.dt, "%s.dt", key));
  static_cast<void>(std::snprintf(m.data, sizeof m.data, "%s.data", key));
}

struct CalibrationPaths {
  MatrixPaths camera;
  MatrixPaths distortion;
  bool opencv = false;  // OpenCV FileStorage matrices (rows, cols, dt, data), no distortion_model
};

// Which spelling the file uses for each matrix (the first one when it has
// none: the one a "missing" error names); false when it gives one matrix
// under two spellings.
bool find_matrix_keys(const yaml::Document& doc, CalibrationPaths& paths, Diagnostic& error) noexcept {
  for (std::size_t which = 0U; which < 2U; ++which) {
    MatrixPaths& m = (which == 0U) ? paths.camera : paths.distortion;
    const char* found = nullptr;
    for (std::size_t spelling = 0U; spelling < kMatrixSpellings; ++spelling) {
      const char* key = kCameraInfoKeys[kFirstMatrixSpelling + 2U * spelling + which];
      if (!doc.has(key)) {
        continue;
      }
      if (found != nullptr) {
        char message[128] = {};
        static_cast<void>(std::snprintf(message, sizeof message, "the same matrix is also given as '%s'",
                                        found));  // short constant names
        error = doc.error_at(doc.find(key), key, message);
        return false;
      }
      found = key;
    }
    set_paths(m, (found != nullptr) ? found : kCameraInfoKeys[kFirstMatrixSpelling + which]);
  }
  paths.opencv = !doc.has("distortion_model") && doc.has(paths.camera.dt);
  return true;
}

// The number of items of a sequence entry (stored one a line).
std::size_t item_count(const yaml::Entry& e) noexcept {
  if (e.value[0] == '\0') {
    return 0U;
  }
  std::size_t n = 1U;
  for (const char* c = e.value; *c != '\0'; ++c) {
    n += (*c == '\n') ? 1U : 0U;
  }
  return n;
}

// An OpenCV matrix: rows and cols (1..kMaxSide), dt d or f (double or
// float: the values are read as doubles either way), and rows x cols
// numbers in data. False with the field named.
bool check_opencv_matrix(const yaml::Document& doc, const MatrixPaths& m, Diagnostic& error) noexcept {
  constexpr long long kMaxSide = 14;  // the longest distortion vector OpenCV writes
  const auto rows = doc.integer(m.rows);
  const auto cols = doc.integer(m.cols);
  if (!rows.ok() || !cols.ok()) {
    error = rows.ok() ? cols.error() : rows.error();
    return false;
  }
  const long long sides[2] = {rows.value(), cols.value()};
  for (int i = 0; i < 2; ++i) {
    if (sides[i] < 1 || sides[i] > kMaxSide) {
      const char* path = (i == 0) ? m.rows : m.cols;
      error = doc.error_at(doc.find(path), path, "must be 1..14");
      return false;
    }
  }
  char dt[8] = {};
  const auto status = doc.text(m.dt, dt, sizeof dt);
  if (!status.ok() || (std::strcmp(dt, "d") != 0 && std::strcmp(dt, "f") != 0)) {
    error = doc.error_at(doc.find(m.dt), m.dt,
                         status.ok() ? "element type must be d (double) or f (float)" : status.error().message);
    return false;
  }
  const yaml::Entry* data = doc.find(m.data);
  if (data == nullptr || !data->is_sequence) {
    error = doc.error_at(data, m.data, (data == nullptr) ? "missing" : "expected a sequence of numbers");
    return false;
  }
  const std::size_t count = item_count(*data);
  if (static_cast<long long>(count) != sides[0] * sides[1]) {
    char message[128] = {};
    static_cast<void>(std::snprintf(message, sizeof message, "rows x cols = %lld x %lld, but data has %zu numbers",
                                    sides[0], sides[1], count));  // fits
    error = doc.error_at(data, m.data, message);
    return false;
  }
  return true;
}

// The intrinsics read from the file within their plausible ranges
// (camera.hpp, docs/model.md); false with the element named.
bool check_intrinsic_ranges(const yaml::Document& doc, const CalibrationPaths& paths, const CameraIntrinsics& k,
                            Diagnostic& error) noexcept {
  const char* matrix = paths.camera.data;
  const char* dist = paths.distortion.data;
  const double w = k.width;
  const double h = k.height;
  return check_range(doc, matrix, "fx", k.fx, kMinFocalPx, kMaxFocalPx, "px", error) &&
         check_range(doc, matrix, "fy", k.fy, kMinFocalPx, kMaxFocalPx, "px", error) &&
         check_range(doc, matrix, "cx", k.cx, -w, 2.0 * w, "px (within one image width of the image)", error) &&
         check_range(doc, matrix, "cy", k.cy, -h, 2.0 * h, "px (within one image height of the image)", error) &&
         check_range(doc, dist, "k1", k.k1, -kMaxRadialCoefficient, kMaxRadialCoefficient, "", error) &&
         check_range(doc, dist, "k2", k.k2, -kMaxRadialCoefficient, kMaxRadialCoefficient, "", error) &&
         check_range(doc, dist, "p1", k.p1, -kMaxTangentialCoefficient, kMaxTangentialCoefficient, "", error) &&
         check_range(doc, dist, "p2", k.p2, -kMaxTangentialCoefficient, kMaxTangentialCoefficient, "", error) &&
         check_range(doc, dist, "k3", k.k3, -kMaxRadialCoefficient, kMaxRadialCoefficient, "", error);
}

// A matrix's `rows`/`cols`, when given, must be the expected size; false
// with the field named.
bool check_size(const yaml::Document& doc, const char* matrix, long long rows, long long cols,
                Diagnostic& error) noexcept {
  const char* const keys[2] = {"rows", "cols"};
  const long long expected[2] = {rows, cols};
  for (int i = 0; i < 2; ++i) {
    char path[yaml::kMaxPath] = {};
    static_cast<void>(std::snprintf(path, sizeof path, "%s.%s", matrix, keys[i]));  // short constant names
    if (!doc.has(path)) {
      continue;
    }
    const auto value = doc.integer(path);
    if (!value.ok()) {
      error = value.error();
      return false;
    }
    if (value.value() != expected[i]) {
      char message[64] = {};
      static_cast<void>(std::snprintf(message, sizeof message, "must be %lld", expected[i]));  // fits
      error = doc.error_at(doc.find(path), path, message);
      return false;
    }
  }
  return true;
}

// The matrices a monocular camera_info carries but the raw image does not
// use (the rectified camera's rotation and projection): when given, they
// must still be well formed (their size, and finite numbers), so that a
// damaged file is refused rather than half read.
bool check_unused_matrices(const yaml::Document& doc, Diagnostic& error) noexcept {
  struct Unused {
    const char* matrix;
    const char* data;
    long long rows;
    long long cols;
  };
  const Unused unused[2] = {{"rectification_matrix", "rectification_matrix.data", 3, 3},
                            {"projection_matrix", "projection_matrix.data", 3, 4}};
  for (const Unused& u : unused) {
    if (!check_size(doc, u.matrix, u.rows, u.cols, error)) {
      return false;
    }
    if (!doc.has(u.data)) {
      continue;
    }
    double values[12] = {};
    const auto status = doc.numbers(u.data, values, static_cast<std::size_t>(u.rows * u.cols));
    if (!status.ok()) {
      error = status.error();
      return false;
    }
  }
  return true;
}

// distortion_model, when given, must be plumb_bob; an OpenCV file has none
// (its distortion is plumb_bob with 4 or 5 coefficients). False with the
// field named.
bool check_distortion_model(const yaml::Document& doc, const CalibrationPaths& paths, Diagnostic& error) noexcept {
  if (paths.opencv) {
    return true;
  }
  char model[32] = {};
  const auto status = doc.text("distortion_model", model, sizeof model);
  if (!status.ok()) {
    error = status.error();
    if (!doc.has("distortion_model")) {
      copy_text(error.message, sizeof error.message,
                "missing (a ROS camera_info names it; OpenCV's matrices have rows, cols, dt and data)");
    }
    return false;
  }
  if (std::strcmp(model, "plumb_bob") != 0) {
    error = doc.error_at(doc.find("distortion_model"), "distortion_model", "only plumb_bob is supported");
    return false;
  }
  return true;
}

// The distortion coefficients into `k`; false with the field named. rows x
// cols, when given, is the number of coefficients (1 x N, or N x 1 as OpenCV
// writes them). OpenCV's vectors have 4, 5, 8, 12 or 14 coefficients; those
// beyond k3 (its rational, thin-prism and tilted models) must be zero.
bool read_distortion(const yaml::Document& doc, const CalibrationPaths& paths, CameraIntrinsics& k,
                     Diagnostic& error) noexcept {
  const MatrixPaths& m = paths.distortion;
  if (!doc.has(m.data)) {
    error = doc.error_at(nullptr, m.data, "missing (also read as distCoeffs or Distortion_Coefficients)");
    return false;
  }
  double d[14] = {};
  std::size_t count = 0U;
  const auto status = doc.numbers_upto(m.data, d, 14U, count);
  if (!status.ok()) {
    error = status.error();
    return false;
  }
  const yaml::Entry* dist = doc.find(m.data);
  const bool opencv_count = count == 4U || count == 5U || count == 8U || count == 12U || count == 14U;
  if (count < 4U || (paths.opencv && !opencv_count)) {
    char message[128] = {};
    static_cast<void>(std::snprintf(message, sizeof message, "%zu coefficients: expected 5 (k1 k2 p1 p2 k3) or 4%s",
                                    count, paths.opencv ? " (OpenCV also writes 8, 12 or 14)" : ""));  // fits
    error = doc.error_at(dist, m.data, message);
    return false;
  }
  if (doc.has(m.rows) && doc.has(m.cols)) {
    const auto rows = doc.integer(m.rows);
    const auto cols = doc.integer(m.cols);
    if (!rows.ok() || !cols.ok()) {
      error = rows.ok() ? cols.error() : rows.error();
      return false;
    }
    const bool in_range = rows.value() >= 1 && rows.value() <= 14 && cols.value() >= 1 && cols.value() <= 14;
    if (!in_range || rows.value() * cols.value() != static_cast<long long>(count) ||
        (rows.value() != 1 && cols.value() != 1)) {
      error = doc.error_at(doc.find(m.cols), m.cols, "rows x cols is not the number of coefficients in data");
      return false;
    }
  }
  for (std::size_t i = 5U; i < count; ++i) {
    if (d[i] != 0.0) {
      char message[160] = {};
      static_cast<void>(std::snprintf(message, sizeof message,
                                      "%zu coefficients with k4.. not zero (rational, thin-prism or tilted model): "
                                      "only plumb_bob's k1 k2 p1 p2 k3 are supported",
                                      count));  // fits
      error = doc.error_at(dist, m.data, message);
      return false;
    }
  }
  k.k1 = d[0];
  k.k2 = d[1];
  k.p1 = d[2];
  k.p2 = d[3];
  k.k3 = (count >= 5U) ? d[4] : 0.0;
  return true;
}

// The image size into `k`; false with the field named.
bool read_image_size(const yaml::Document& doc, CameraIntrinsics& k, Diagnostic& error) noexcept {
  const char* const keys[2] = {"image_width", "image_height"};
  int* const sides[2] = {&k.width, &k.height};
  for (int i = 0; i < 2; ++i) {
    const auto value = doc.integer(keys[i]);
    if (!value.ok()) {
      error = value.error();
      return false;
    }
    if (value.value() <= 0 || value.value() > kMaxImageSide) {
      error = doc.error_at(doc.find(keys[i]), keys[i], "must be 1..16384 px");
      return false;
    }
    *sides[i] = static_cast<int>(value.value());
  }
  return true;
}

// The camera matrix [fx 0 cx; 0 fy cy; 0 0 1] (up to scale) into `k`;
// false with the field named.
bool read_camera_matrix(const yaml::Document& doc, const MatrixPaths& paths, CameraIntrinsics& k,
                        Diagnostic& error) noexcept {
  if (!doc.has(paths.data)) {
    error = doc.error_at(nullptr, paths.data, "missing (also read as cameraMatrix or Camera_Matrix)");
    return false;
  }
  double m[9] = {};
  const auto status = doc.numbers(paths.data, m, 9U);
  if (!status.ok()) {
    error = status.error();
    return false;
  }
  const yaml::Entry* matrix = doc.find(paths.data);
  if (m[1] != 0.0) {
    error = doc.error_at(matrix, paths.data, "skew is not supported (element 2 must be 0)");
    return false;
  }
  if (m[3] != 0.0 || m[6] != 0.0 || m[7] != 0.0 || m[8] == 0.0) {
    error = doc.error_at(matrix, paths.data, "not an upper-triangular camera matrix [fx 0 cx; 0 fy cy; 0 0 1]");
    return false;
  }
  // A matrix scaled by m[8] != 1 is the same camera.
  k.fx = m[0] / m[8];
  k.cx = m[2] / m[8];
  k.fy = m[4] / m[8];
  k.cy = m[5] / m[8];
  if (!(k.fx > 0.0) || !(k.fy > 0.0)) {
    error = doc.error_at(matrix, paths.data, "focal lengths must be positive (the matrix is singular)");
    return false;
  }
  return true;
}

}  // namespace

yaml::KeySet camera_info_keys() noexcept {
  return yaml::KeySet{kCameraInfoKeys, sizeof kCameraInfoKeys / sizeof kCameraInfoKeys[0]};
}

Result<CameraIntrinsics, Diagnostic> read_camera_info(const yaml::Document& doc) noexcept {
  CameraIntrinsics k;
  Diagnostic error;
  CalibrationPaths paths;
  if (!read_image_size(doc, k, error) || !find_matrix_keys(doc, paths, error)) {
    return CameraResult::failure(error);
  }
  // An OpenCV matrix (one with dt) is checked as such in a ROS file too.
  const bool camera_ok = !doc.has(paths.camera.dt) || check_opencv_matrix(doc, paths.camera, error);
  const bool distortion_ok = camera_ok && ((!paths.opencv && !doc.has(paths.distortion.dt)) ||
                                           check_opencv_matrix(doc, paths.distortion, error));
  const bool well_formed =
      distortion_ok && check_size(doc, paths.camera.key, 3, 3, error) && check_unused_matrices(doc, error);
  if (!well_formed || !read_camera_matrix(doc, paths.camera, k, error) ||
      !check_distortion_model(doc, paths, error) || !read_distortion(doc, paths, k, error) ||
      !check_intrinsic_ranges(doc, paths, k, error)) {
    return CameraResult::failure(error);
  }
  const auto model_check = CameraModel::create(k);
  if (!model_check.ok()) {
    const char* field = paths.camera.data;
    if (model_check.error() == CameraError::NoValidRegion) {
      field = paths.distortion.data;
    }
    return CameraResult::failure(doc.error_at(doc.find(field), field, to_string(model_check.error())));
  }
  return CameraResult::success(k);
}

Result<CameraIntrinsics, Diagnostic> load_camera_info(const char* path, yaml::Document& scratch) noexcept {
  const auto loaded = scratch.load(path, camera_info_keys());
  if (!loaded.ok()) {
    return CameraResult::failure(loaded.error());
  }
  return read_camera_info(scratch);
}

namespace {

// instrument.marker_colors, when given: a sequence of 5 'blue' or 'yellow'
// into g.marker_colors. False with the error's place in the file.
bool read_marker_colors(const yaml::Document& doc, InstrumentGeometry& g, Diagnostic& error) noexcept {
  if (!doc.has("instrument.marker_colors")) {
    return true;
  }
  const yaml::Entry* e = doc.find("instrument.marker_colors");
  e->used = true;
  const char* p = e->value;
  std::size_t i = 0U;
  while (*p != '\0') {
    std::size_t n = 0U;
    while (p[n] != '\0' && p[n] != '\n') {
      ++n;
    }
    if (i == g.marker_colors.size()) {
      error = doc.error_at(e, e->path, "expected 5 colours");
      return false;
    }
    if (n == 4U && std::strncmp(p, "blue", 4U) == 0) {
      g.marker_colors[i] = MarkerColor::Blue;
    } else if (n == 6U && std::strncmp(p, "yellow", 6U) == 0) {
      g.marker_colors[i] = MarkerColor::Yellow;
    } else {
      error = doc.error_at(e, e->path, "colours are 'blue' or 'yellow'");
      return false;
    }
    ++i;
    p += n;
    if (*p == '\n') {
      ++p;
    }
  }
  if (!e->is_sequence || i != g.marker_colors.size()) {
    error = doc.error_at(e, e->path, "expected a sequence of 5 colours");
    return false;
  }
  return true;
}

// A number of the instrument file with its plausible range: lo..hi, or
// lo excluded when `lo_open`.
struct RangedField {
  const char* path;
  double* target;
  double lo;
  double hi;
  bool lo_open;
  const char* unit;
};

// Reads an optional number and checks its range; false with the field and
// the range named.
bool read_ranged(const yaml::Document& doc, const RangedField& f, Diagnostic& error) noexcept {
  double value = *f.target;
  if (!read_number(doc, f.path, value, error)) {
    return false;
  }
  const bool above_lo = f.lo_open ? value > f.lo : value >= f.lo;
  if (!above_lo || !(value <= f.hi)) {
    char message[128] = {};
    static_cast<void>(std::snprintf(message, sizeof message, "%g is outside its plausible range %s%g, %g] %s", value,
                                    f.lo_open ? "(" : "[", f.lo, f.hi, f.unit));  // truncation is fine
    error = doc.error_at(doc.find(f.path), f.path, message);
    return false;
  }
  *f.target = value;
  return true;
}

// A geometry the file describes but validate() rejects, placed at the key
// that is wrong.
Diagnostic geometry_error_at(const yaml::Document& doc, GeometryError why) noexcept {
  const char* field = "instrument";
  switch (why) {
    case GeometryError::BadBoundaries: field = "instrument.boundaries_mm"; break;
    case GeometryError::RadiusTooLarge: field = "instrument.radius_mm"; break;
    case GeometryError::BadPenalty: field = "play_penalty"; break;
    case GeometryError::BadJointRange: field = "instrument.theta_max_deg"; break;
    case GeometryError::NonFiniteValue:
    case GeometryError::NonPositiveLength:
    case GeometryError::OutOfRange: break;  // the fields' own ranges are checked as they are read
  }
  return doc.error_at(doc.find(field), field, to_string(why));
}

}  // namespace

Result<InstrumentGeometry, Diagnostic> read_instrument_config(const yaml::Document& doc) noexcept {
  InstrumentGeometry g;
  Diagnostic error;
  double theta_max_deg = rad_to_deg(g.theta_max_rad);
  double psi_deg = rad_to_deg(g.nominal_psi_rad);
  double mu_deg = rad_to_deg(g.nominal_mu_rad);
  double angle_scale_deg = rad_to_deg(g.penalty.angle_scale_rad);
  // The plausible ranges of instrument.hpp in the file's units.
  constexpr double kLength = kMaxGeometryLengthMm;
  constexpr double kAngleDeg = rad_to_deg(kMaxGeometryAngleRad);
  constexpr double kStiffness = kMaxPenaltyStiffness;
  const RangedField fields[] = {
      {"instrument.bend_length_mm", &g.bend_length_mm, 0.0, kLength, true, "mm"},
      {"instrument.radius_mm", &g.radius_mm, 0.0, kLength, true, "mm"},
      {"instrument.tcp_offset_mm", &g.tcp_offset_mm, 0.0, kLength, true, "mm"},
      {"instrument.shaft_radius_mm", &g.shaft_radius_mm, 0.0, kLength, true, "mm"},
      {"instrument.grasper_radius_mm", &g.grasper_radius_mm, 0.0, kLength, true, "mm"},
      {"instrument.theta_max_deg", &theta_max_deg, 0.0, kAngleDeg, true, "deg"},
      {"instrument.lambda_min_mm", &g.lambda_min_mm, 0.0, kLength, false, "mm"},
      {"instrument.lambda_max_mm", &g.lambda_max_mm, 0.0, kLength, true, "mm"},
      {"channel_nominal.x_ch_mm", &g.nominal_x_ch_mm, -kLength, kLength, false, "mm"},
      {"channel_nominal.y_ch_mm", &g.nominal_y_ch_mm, -kLength, kLength, false, "mm"},
      {"channel_nominal.psi_deg", &psi_deg, -kAngleDeg, kAngleDeg, false, "deg"},
      {"channel_nominal.mu_deg", &mu_deg, -kAngleDeg, kAngleDeg, false, "deg"},
      {"play_penalty.position_k", &g.penalty.position_k, 0.0, kStiffness, false, ""},
      {"play_penalty.position_scale_mm", &g.penalty.position_scale_mm, 0.0, kLength, true, "mm"},
      {"play_penalty.angle_k", &g.penalty.angle_k, 0.0, kStiffness, false, ""},
      {"play_penalty.angle_scale_deg", &angle_scale_deg, 0.0, kAngleDeg, true, "deg"},
  };
  for (const RangedField& f : fields) {
    if (!read_ranged(doc, f, error)) {
      return GeometryResult::failure(error);
    }
  }
  g.theta_max_rad = deg_to_rad(theta_max_deg);
  g.nominal_psi_rad = deg_to_rad(psi_deg);
  g.nominal_mu_rad = deg_to_rad(mu_deg);
  g.penalty.angle_scale_rad = deg_to_rad(angle_scale_deg);
  const bool explicit_boundaries = doc.has("instrument.boundaries_mm");
  if (explicit_boundaries) {
    auto status = doc.numbers("instrument.boundaries_mm", g.boundaries_mm.data(), g.boundaries_mm.size());
    if (!status.ok()) {
      return GeometryResult::failure(status.error());
    }
  } else {
    // Five equal stripes over the (possibly configured) bend length.
    for (int j = 0; j < kNumBoundaries; ++j) {
      g.boundaries_mm[static_cast<std::size_t>(j)] = g.bend_length_mm * j / kNumMarkers;
    }
  }
  if (!read_marker_colors(doc, g, error)) {
    return GeometryResult::failure(error);
  }
  const char* sections[] = {"instrument", "channel_nominal", "play_penalty"};
  for (const char* section : sections) {
    const yaml::Entry* unknown = doc.first_unused(section);
    if (unknown != nullptr) {
      return GeometryResult::failure(doc.error_at(unknown, unknown->path, "unknown key"));
    }
  }
  const auto valid = validate(g);
  if (!valid.ok()) {
    return GeometryResult::failure(geometry_error_at(doc, valid.error()));
  }
  return GeometryResult::success(g);
}

Result<InstrumentGeometry, Diagnostic> load_instrument_config(const char* path, yaml::Document& scratch) noexcept {
  const auto loaded = scratch.load(path);
  if (!loaded.ok()) {
    return GeometryResult::failure(loaded.error());
  }
  return read_instrument_config(scratch);
}

}  // namespace solver
}  // namespace tcpest
