// cycles.csv (tcpest demo): one row per loop cycle, with the timing of every
// step, what was sent and why it has the status it has. The columns are
// documented in docs/loop.md ("cycles.csv"); new ones are appended, so a
// reader that takes the first columns by position keeps working.
#pragma once

#include <cstdint>
#include <cstdio>

#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/loop/executive.hpp"

namespace tcpest {
namespace cli {

// The header line. False when the stream refused the write.
bool write_cycles_csv_header(std::FILE* out) noexcept;

// The row of cycle `r`; `t0_ns` is the trigger time of the first row
// (t_ms counts from it); `truth`: the frame's, from a simulated source
// (nullptr: none). False when the stream refused the write.
bool write_cycles_csv_row(std::FILE* out, const loop::CycleRecord& r, const hal::FrameTruth* truth,
                          std::int64_t t0_ns) noexcept;

}  // namespace cli
}  // namespace tcpest
