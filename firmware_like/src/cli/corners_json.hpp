// JSON in and out of `tcpest solve` and `tcpest project`:
//   in : {"corners": [12 x ([u, v] or null)], "prior": [lambda, phi, theta]}   ("prior" optional)
//   out: {"status": ..., "tcp": [x, y, z], "r": [7 values], "rms_px": N, "iterations": N, "corners_used": N}
//        {"corners": [12 x ([u, v] or null)], "corners_3d": [12 x ([x, y, z] or null)], "tcp": [x, y, z]}
// Pixels, millimetres, radians. Non-finite numbers are written as null (JSON
// has no NaN). Other members of the input object are ignored.
#pragma once

#include <cstddef>

#include "tcpest/solver/pose_solver.hpp"

namespace tcpest {
namespace cli {

struct CornersInput {
  solver::CornerObservation observed;
  bool has_prior = false;
  double prior[3] = {0.0, 0.0, 0.0};  // lambda (mm), phi, theta (rad)
};

// Parses one object from text[0..length). False with a message in `error`.
bool parse_corners_json(const char* text, std::size_t length, CornersInput& out, char* error,
                        std::size_t error_capacity) noexcept;

// True when the solver produced an estimate worth printing (it iterated);
// refused inputs print null for r, tcp and rms_px.
bool has_estimate(const solver::SolveSummary& summary) noexcept;

// Formats the solve result as one JSON line (with '\n'). False if it does not fit.
bool format_solve_json(const solver::SolveSummary& summary, const solver::PoseVector& r, const solver::Vec3& tcp,
                       char* out, std::size_t capacity) noexcept;
// Formats a configuration error as one JSON line: {"error": "...", "line": N} (line 0: no line).
bool format_error_json(const char* message, unsigned long line, char* out, std::size_t capacity) noexcept;
// Formats the projection of a configuration as one JSON line.
bool format_project_json(const solver::CornerSet& corners, char* out, std::size_t capacity) noexcept;

}  // namespace cli
}  // namespace tcpest

#include <cstdio>

#include "cli/setup.hpp"

namespace tcpest {
namespace cli {

struct SolveStreamResult {
  unsigned long solved = 0U;     // inputs that reached the solver (any status)
  unsigned long malformed = 0U;  // inputs refused before the solver (an error line each)
};

// `tcpest solve --corners -`: one JSON object per line of `in`, each solved
// independently from its own "prior" or `default_prior` (lambda, phi,
// theta), one JSON line per input on `out` (an error line for a malformed
// one; the run goes on). Blank lines are skipped. Lines are at most
// kMaxCornersLine bytes.
constexpr std::size_t kMaxCornersLine = 16384U;
SolveStreamResult solve_stream(std::FILE* in, std::FILE* out, const ModelSetup& setup, solver::SolveMode mode,
                               const double* default_prior) noexcept;

// Solves one parsed input and writes its JSON line.
void solve_one(const CornersInput& input, const ModelSetup& setup, solver::SolveMode mode,
               const double* default_prior, std::FILE* out) noexcept;

}  // namespace cli
}  // namespace tcpest
