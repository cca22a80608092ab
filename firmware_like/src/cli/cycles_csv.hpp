// cycles.csv (tcpest demo, tcpest run --record): one row per loop cycle, with
// the timing of every step, what was sent and why it has the status it has.
// The columns are documented in docs/loop.md ("cycles.csv"); new ones are
// appended, so a reader that takes the first columns by position keeps
// working. A field with nothing to say (no latency: nothing was sent; no
// estimate; no truth for this frame) is empty. The truth columns (truth_x_mm
// .. error_mm) are there only for a source that knows the truth (the
// simulated camera).
//
// The row is formatted into a caller's buffer (no allocation, no I/O), so
// that the recorder's writer thread and the demo share one definition.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>

#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/loop/executive.hpp"

namespace tcpest {
namespace cli {

// Longest header or row (all fields at their widest).
constexpr std::size_t kCyclesCsvMaxLine = 1024U;

// The header line (with its '\n') into `out`; returns its length, 0 when
// `capacity` is too small.
std::size_t format_cycles_csv_header(bool with_truth, char* out, std::size_t capacity) noexcept;

// The row of cycle `r` into `out`; `t0_ns` is the trigger time of the first
// row (t_ms counts from it); `truth`: the frame's (nullptr or not valid:
// empty truth fields), written only `with_truth`. Returns its length, 0 when
// `capacity` is too small.
std::size_t format_cycles_csv_row(const loop::CycleRecord& r, const hal::FrameTruth* truth, bool with_truth,
                                  std::int64_t t0_ns, char* out, std::size_t capacity) noexcept;

// The same, written to a stream. False when the stream refused the write.
bool write_cycles_csv_header(std::FILE* out, bool with_truth) noexcept;
bool write_cycles_csv_row(std::FILE* out, const loop::CycleRecord& r, const hal::FrameTruth* truth, bool with_truth,
                          std::int64_t t0_ns) noexcept;

}  // namespace cli
}  // namespace tcpest
