// libFuzzer target: the JSON reader (tokenise, then walk every token with the
// typed accessors) and each JSON loader on the same bytes: colour model
// (vision), dataset sidecar (hal/render), corners input (`tcpest solve`).
// A loader may refuse the input; it must never crash, overrun or hang.
#include <cstddef>
#include <cstdint>

#include "cli/corners_json.hpp"
#include "tcpest/common/json.hpp"
#include "tcpest/render/sidecar.hpp"
#include "tcpest/vision/color_model.hpp"

namespace {

using namespace tcpest;

constexpr std::size_t kTokens = 4096U;
constexpr std::size_t kFormatted = 65536U;

// Every accessor on every token: lookups run on whatever the parser built.
void walk(const json::Document& doc) {
  char text[64] = {};
  double numbers[3] = {};
  for (std::size_t i = 0U; i < doc.token_count(); ++i) {
    switch (doc.type(i)) {
      case json::TokenType::Object:
        static_cast<void>(doc.member(i, "corners"));  // any outcome is fine
        break;
      case json::TokenType::Array:
        static_cast<void>(doc.array_size(i));
        static_cast<void>(doc.element(i, 1U));       // any outcome is fine
        static_cast<void>(doc.numbers(i, numbers, 3U));
        break;
      case json::TokenType::String:
        static_cast<void>(doc.string(i, text, sizeof text));
        static_cast<void>(doc.string_equals(i, "format"));
        break;
      default:
        static_cast<void>(doc.number(i));
        break;
    }
  }
}

// A model or sidecar the reader accepts must be one the product can write
// back and read again (the training command and the renderer write them).
void round_trip_color_model(const vision::ColorModel& model) {
  static char formatted[kFormatted];
  const std::size_t n = vision::format_color_model(model, formatted, sizeof formatted);
  if (n == 0U || !vision::parse_color_model(formatted, n, "formatted.json").ok()) {
    __builtin_trap();
  }
}

void round_trip_sidecar(const render::Sidecar& sidecar) {
  static char formatted[kFormatted];
  const std::size_t n = render::format_sidecar(sidecar, formatted, sizeof formatted);
  if (n == 0U || !render::parse_sidecar(formatted, n, "formatted.json").ok()) {
    __builtin_trap();
  }
}

// What `tcpest solve` does with an accepted line (cli::solve_one): solve from
// the line's prior, format the result.
void solve(const cli::CornersInput& input) {
  static const auto camera = solver::CameraModel::create(solver::default_pal_camera());
  static const auto instrument = solver::InstrumentModel::create(solver::InstrumentGeometry{});
  if (!camera.ok() || !instrument.ok()) {
    __builtin_trap();  // the harness itself is broken
  }
  static solver::PoseSolver pose_solver(camera.value(), instrument.value());
  const double coarse[3] = {20.0, 0.3, 0.8};
  const double* joints = input.has_prior ? input.prior : coarse;
  solver::PoseVector r = instrument.value().geometry().nominal_pose(joints[0], joints[1], joints[2]);
  const solver::PoseVector start = r;
  const solver::SolveSummary summary = pose_solver.solve(input.observed, solver::SolveMode::Adaptive, r);
  r = solver::nearest_equivalent_joints(r, start);
  char line[4096] = {};
  static_cast<void>(cli::format_solve_json(summary, r, instrument.value().tcp(r), line, sizeof line));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const char* text = reinterpret_cast<const char*>(data);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): bytes as text
  static json::Token tokens[kTokens];
  json::Document doc(tokens, kTokens);
  if (doc.parse(text, size).ok()) {
    walk(doc);
  }
  const auto model = vision::parse_color_model(text, size, "fuzz.json");  // refusal is a valid outcome
  if (model.ok()) {
    round_trip_color_model(model.value());
  }
  static render::Sidecar sidecar;
  const auto parsed = render::parse_sidecar(text, size, "fuzz.json");
  if (parsed.ok()) {
    sidecar = parsed.value();
    round_trip_sidecar(sidecar);
  }
  static cli::CornersInput corners;
  char error[256] = {};
  corners = cli::CornersInput{};
  if (cli::parse_corners_json(text, size, corners, error, sizeof error)) {
    solve(corners);
  }
  return 0;
}
