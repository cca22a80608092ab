// libFuzzer target: the YAML reader, then each YAML loader on the same
// document: camera calibration and instrument configuration (solver), loop
// configuration (firmware_like/loop); plus every typed accessor on every
// entry. A loader may refuse the input; it must never crash, overrun or hang.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "tcpest/common/yaml_lite.hpp"
#include "tcpest/loop/config.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/config_io.hpp"
#include "tcpest/solver/instrument.hpp"

namespace {

using namespace tcpest;

void read_every_entry(const yaml::Document& doc) {
  char text[64] = {};
  double numbers[8] = {};
  for (std::size_t i = 0U; i < doc.size(); ++i) {
    const char* path = doc.entry(i).path;
    static_cast<void>(doc.number(path));  // any outcome is fine
    static_cast<void>(doc.integer(path));
    static_cast<void>(doc.text(path, text, sizeof text));
    std::size_t count = 0U;
    static_cast<void>(doc.numbers_upto(path, numbers, 8U, count));
  }
  static_cast<void>(doc.first_unused(""));
}

// What start-up does with an accepted file: build the models, then project
// the instrument's corners at its nominal pose (as `tcpest project` does).
void use_models(const Result<solver::CameraIntrinsics, Diagnostic>& intrinsics,
                const Result<solver::InstrumentGeometry, Diagnostic>& geometry) {
  const auto camera = solver::CameraModel::create(intrinsics.ok() ? intrinsics.value() : solver::default_pal_camera());
  const auto instrument = solver::InstrumentModel::create(geometry.ok() ? geometry.value() : solver::InstrumentGeometry{});
  if (!camera.ok() || !instrument.ok() || (!intrinsics.ok() && !geometry.ok())) {
    return;
  }
  solver::CornerSet corners;
  instrument.value().corners(camera.value(), instrument.value().geometry().nominal_pose(20.0, 0.3, 0.8), corners);
  solver::Vec2 normalised;
  static_cast<void>(camera.value().undistort(solver::Vec2(0.0, 0.0), normalised));  // any outcome is fine
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const char* text = reinterpret_cast<const char*>(data);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): bytes as text
  // The scalar parser alone, on the first bytes as a C string.
  char scalar[64] = {};
  std::memcpy(scalar, data, size < sizeof scalar - 1U ? size : sizeof scalar - 1U);
  double value = 0.0;
  static_cast<void>(yaml::parse_double(scalar, value));

  static yaml::Document doc;  // large (the file buffer is a member): static
  if (!doc.parse(text, size, "fuzz.yaml").ok()) {
    return 0;
  }
  const auto intrinsics = solver::read_camera_info(doc);  // refusal is a valid outcome
  const auto geometry = solver::read_instrument_config(doc);
  use_models(intrinsics, geometry);
  static loop::LoopConfig config;
  config = loop::LoopConfig{};
  static_cast<void>(loop::read_loop_config(doc, config));
  read_every_entry(doc);
  return 0;
}
