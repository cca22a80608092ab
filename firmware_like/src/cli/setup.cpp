#include "cli/setup.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "tcpest/common/yaml_lite.hpp"
#include "tcpest/solver/config_io.hpp"

namespace tcpest {
namespace cli {

bool load_model_setup(const char* command, const char* calib_path, const char* config_path,
                      ModelSetup& out) noexcept {
  static yaml::Document scratch;  // large parse buffer, start-up only
  char message[768];
  solver::CameraIntrinsics intrinsics = solver::default_pal_camera();
  if (calib_path != nullptr) {
    const auto loaded = solver::load_camera_info(calib_path, scratch);
    if (!loaded.ok()) {
      loaded.error().format(message, sizeof message);
      std::fprintf(stderr, "tcpest %s: camera calibration: %s\n", command, message);
      return false;
    }
    intrinsics = loaded.value();
  }
  const auto camera = solver::CameraModel::create(intrinsics);
  if (!camera.ok()) {
    std::fprintf(stderr, "tcpest %s: camera: %s\n", command, solver::to_string(camera.error()));
    return false;
  }
  solver::InstrumentGeometry geometry;
  if (config_path != nullptr) {
    const auto loaded = solver::load_instrument_config(config_path, scratch);
    if (!loaded.ok()) {
      loaded.error().format(message, sizeof message);
      std::fprintf(stderr, "tcpest %s: config: %s\n", command, message);
      return false;
    }
    geometry = loaded.value();
  }
  const auto instrument = solver::InstrumentModel::create(geometry);
  if (!instrument.ok()) {
    std::fprintf(stderr, "tcpest %s: instrument geometry: %s\n", command, solver::to_string(instrument.error()));
    return false;
  }
  out.camera = camera.value();
  out.instrument = instrument.value();
  return true;
}

bool make_directory(const char* path) noexcept {
  if (::mkdir(path, 0755) == 0 || errno == EEXIST) {
    struct stat st {};
    if (::stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
      return true;
    }
    errno = ENOTDIR;
  }
  return false;
}

bool make_directories(const char* path, char* failed, std::size_t failed_capacity) noexcept {
  auto fail = [&](const char* which) noexcept {
    if (failed != nullptr && failed_capacity > 0U) {
      static_cast<void>(std::snprintf(failed, failed_capacity, "%s", which));  // for the message: truncation is harmless
    }
    return false;
  };
  if (path == nullptr || path[0] == '\0') {
    errno = ENOENT;
    return fail("");
  }
  char partial[kMaxDirectoryPath + 1U];
  const std::size_t length = std::strlen(path);
  if (length > kMaxDirectoryPath) {
    errno = ENAMETOOLONG;
    return fail(path);
  }
  std::memcpy(partial, path, length + 1U);
  std::size_t depth = 0U;
  for (std::size_t i = 1U; i < length; ++i) {
    // Each parent, once: at a '/' that ends a name (not a run of slashes).
    if (partial[i] != '/' || partial[i - 1U] == '/') {
      continue;
    }
    if (++depth >= kMaxDirectoryDepth) {
      errno = ENAMETOOLONG;
      return fail(path);
    }
    partial[i] = '\0';
    const bool made = make_directory(partial);
    if (!made) {
      return fail(partial);
    }
    partial[i] = '/';
  }
  return make_directory(path) || fail(path);
}

}  // namespace cli
}  // namespace tcpest
