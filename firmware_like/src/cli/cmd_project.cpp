// tcpest project: the model alone: corners (pixels), their 3D points and
// the TCP (mm, camera frame) for a configuration r.
#include <cstdio>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/corners_json.hpp"
#include "cli/setup.hpp"

namespace tcpest {
namespace cli {

namespace {

const OptionSpec kSpecs[] = {
    kCalibOption,
    kInstrumentConfigOption,
    {"r", "X,Y,PSI,MU,LAMBDA,PHI,THETA", "configuration: x_ch, y_ch (mm), psi, mu (rad), lambda (mm), phi, theta (rad)"},
};
constexpr std::size_t kSpecCount = sizeof kSpecs / sizeof kSpecs[0];

}  // namespace

int cmd_project(int argc, char** argv) {
  Args args;
  char error[256];
  if (!args.parse(argc, argv, 1, kSpecs, kSpecCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest project: %s\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest project [--calib CAM.yaml] [--config CFG.yaml] --r X,Y,PSI,MU,LAMBDA,PHI,THETA",
                "Projects the instrument model for the configuration r (angles in radians, lengths in mm;\n"
                "negative values work: --r -13.3,6.2,... or --r=-13.3,6.2,...). Prints one JSON line:\n"
                "{\"corners\": 12 x ([u, v] px or null), \"corners_3d\": 12 x ([x, y, z] mm or null),\n"
                "\"tcp\": [x, y, z] mm}, camera frame, corner k = 2 * boundary + side (0 left, 1 right).\n"
                "A corner is null when the model gives none (behind the camera, not projectable, no limb);\n"
                "corners outside the image are printed.",
                kSpecs, kSpecCount);
    return kExitOk;
  }
  if (args.positional_count() != 0U) {
    std::fprintf(stderr, "tcpest project: unexpected argument '%s'\n", args.positional(0));
    return kExitUsage;
  }
  double values[solver::kNumParams];
  if (!parse_number_list(args.value("r"), values, static_cast<std::size_t>(solver::kNumParams))) {
    std::fprintf(stderr, "tcpest project: --r needs seven numbers: x_ch,y_ch,psi,mu,lambda,phi,theta "
                         "(mm, mm, rad, rad, mm, rad, rad)\n");
    return kExitUsage;
  }
  static ModelSetup setup;
  if (!load_model_setup("project", args.value("calib"), args.value("config"), setup)) {
    return kExitConfig;
  }
  solver::PoseVector r;
  for (int i = 0; i < solver::kNumParams; ++i) {
    r[i] = values[i];
  }
  solver::CornerSet corners;
  setup.instrument.corners(setup.camera, r, corners);
  char buffer[4096];
  if (!format_project_json(corners, buffer, sizeof buffer)) {
    std::fprintf(stderr, "tcpest project: output too long\n");
    return kExitFailure;
  }
  std::fputs(buffer, stdout);
  return kExitOk;
}

}  // namespace cli
}  // namespace tcpest
