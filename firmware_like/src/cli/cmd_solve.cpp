// tcpest solve: the pose solver alone, for users who bring their own corner
// detector. One JSON object in (a file, or one per line on standard input),
// one JSON line out per input.
#include <cerrno>
#include <cstdio>
#include <cstring>

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
    {"corners", "FILE", "JSON {\"corners\": [12 x ([u, v] or null)], \"prior\": [lambda, phi, theta]}; "
                        "- reads one object per line from standard input"},
    {"prior", "LAMBDA,PHI,THETA", "start joints (mm, rad, rad); default: mid-range, phi = theta = 0"},
    {"fixed-model", nullptr, "estimate lambda, phi, theta only, with the channel pose held at its nominal value"},
};
constexpr std::size_t kSpecCount = sizeof kSpecs / sizeof kSpecs[0];

constexpr std::size_t kMaxOutputLine = 1024U;

// Reads one line into `line` (without the newline). Returns false at end of
// input; `too_long` when the line did not fit (the rest is skipped).
bool read_line(std::FILE* in, char* line, std::size_t capacity, std::size_t& length, bool& too_long) noexcept {
  length = 0U;
  too_long = false;
  bool any = false;
  for (;;) {  // bounded by the input: each pass consumes one character
    const int c = std::fgetc(in);
    if (c == EOF) {
      return any;
    }
    any = true;
    if (c == '\n') {
      return true;
    }
    if (length + 1U < capacity) {
      line[length++] = static_cast<char>(c);
    } else {
      too_long = true;
    }
  }
}

bool blank(const char* text, std::size_t length) noexcept {
  for (std::size_t i = 0U; i < length; ++i) {
    if (text[i] != ' ' && text[i] != '\t' && text[i] != '\r') {
      return false;
    }
  }
  return true;
}

void write_error(std::FILE* out, const char* message, unsigned long line) noexcept {
  char buffer[kMaxOutputLine];
  if (format_error_json(message, line, buffer, sizeof buffer)) {
    std::fputs(buffer, out);
  } else {
    std::fputs("{\"error\": \"message too long\", \"line\": 0}\n", out);
  }
}

}  // namespace

void solve_one(const CornersInput& input, const ModelSetup& setup, solver::SolveMode mode,
               const double* default_prior, std::FILE* out) noexcept {
  solver::PoseSolver solver_instance(setup.camera, setup.instrument);  // a few KB of fixed-size scratch
  const double* joints = input.has_prior ? input.prior : default_prior;
  solver::PoseVector r = setup.instrument.geometry().nominal_pose(joints[0], joints[1], joints[2]);
  const solver::PoseVector start = r;
  const solver::SolveSummary summary = solver_instance.solve(input.observed, mode, r);
  r = solver::nearest_equivalent_joints(r, start);  // the start's turn of phi and sign of theta
  char buffer[kMaxOutputLine];
  if (format_solve_json(summary, r, setup.instrument.tcp(r), buffer, sizeof buffer)) {
    std::fputs(buffer, out);
  } else {
    write_error(out, "result too long to format", 0U);
  }
  static_cast<void>(std::fflush(out));  // line by line for pipes; a failed flush shows at exit
}

SolveStreamResult solve_stream(std::FILE* in, std::FILE* out, const ModelSetup& setup, solver::SolveMode mode,
                               const double* default_prior) noexcept {
  static char line[kMaxCornersLine];
  SolveStreamResult result;
  unsigned long number = 0U;
  std::size_t length = 0U;
  bool too_long = false;
  while (read_line(in, line, sizeof line, length, too_long)) {
    ++number;
    if (too_long) {
      write_error(out, "line too long", number);
      ++result.malformed;
      continue;
    }
    if (blank(line, length)) {
      continue;
    }
    CornersInput input;
    char error[256];
    if (!parse_corners_json(line, length, input, error, sizeof error)) {
      write_error(out, error, number);
      ++result.malformed;
      continue;
    }
    solve_one(input, setup, mode, default_prior, out);
    ++result.solved;
  }
  return result;
}

int cmd_solve(int argc, char** argv) {
  Args args;
  char error[256];
  if (!args.parse(argc, argv, 1, kSpecs, kSpecCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest solve: %s\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest solve [--calib CAM.yaml] [--config CFG.yaml] --corners FILE|- [--prior LAMBDA,PHI,THETA] "
                "[--fixed-model]",
                "Solves the instrument's configuration from measured corners (bring your own detector) and prints\n"
                "one JSON line per input: {\"status\", \"tcp\" [mm], \"r\" [x_ch, y_ch, psi, mu, lambda, phi, theta]\n"
                "(mm, rad), \"rms_px\", \"iterations\", \"corners_used\"}. Angles are in radians. r, tcp and rms_px\n"
                "are null when the input is refused (see docs/solver.md for the statuses). Exit status 3 when\n"
                "an input could not be read (its line says why; the other lines are still solved).",
                kSpecs, kSpecCount);
    return kExitOk;
  }
  if (args.positional_count() != 0U) {
    std::fprintf(stderr, "tcpest solve: unexpected argument '%s'\n", args.positional(0));
    return kExitUsage;
  }
  const char* corners_path = args.value("corners");
  if (corners_path == nullptr) {
    std::fprintf(stderr, "tcpest solve: --corners FILE (or -) is required\n");
    return kExitUsage;
  }
  static ModelSetup setup;
  if (!load_model_setup("solve", args.value("calib"), args.value("config"), setup)) {
    return kExitConfig;
  }
  const solver::InstrumentGeometry& g = setup.instrument.geometry();
  double prior[3] = {0.5 * (g.lambda_min_mm + g.lambda_max_mm), 0.0, 0.0};
  if (args.value("prior") != nullptr && !parse_number_list(args.value("prior"), prior, 3U)) {
    std::fprintf(stderr, "tcpest solve: --prior needs three numbers: lambda_mm,phi_rad,theta_rad\n");
    return kExitUsage;
  }
  const solver::SolveMode mode = args.flag("fixed-model") ? solver::SolveMode::FixedModel : solver::SolveMode::Adaptive;

  if (std::strcmp(corners_path, "-") == 0) {
    const SolveStreamResult result = solve_stream(stdin, stdout, setup, mode, prior);
    return (result.malformed == 0U) ? kExitOk : kExitConfig;
  }
  std::FILE* file = std::fopen(corners_path, "rb");
  if (file == nullptr) {
    std::fprintf(stderr, "tcpest solve: cannot open %s: %s\n", corners_path, std::strerror(errno));
    return kExitConfig;
  }
  static char text[kMaxCornersLine];
  const std::size_t length = std::fread(text, 1U, sizeof text, file);
  const bool truncated = length == sizeof text;
  static_cast<void>(std::fclose(file));  // read-only: nothing to lose on close
  if (truncated) {
    std::fprintf(stderr, "tcpest solve: %s: larger than %zu bytes\n", corners_path, sizeof text - 1U);
    return kExitConfig;
  }
  CornersInput input;
  if (!parse_corners_json(text, length, input, error, sizeof error)) {
    std::fprintf(stderr, "tcpest solve: %s: %s\n", corners_path, error);
    return kExitConfig;
  }
  solve_one(input, setup, mode, prior, stdout);
  return kExitOk;
}

}  // namespace cli
}  // namespace tcpest
