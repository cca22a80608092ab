#include "cli/cycles_csv.hpp"

#include <cmath>
#include <cstddef>

#include "cli/loop_rig.hpp"
#include "tcpest/common/text_buffer.hpp"

namespace tcpest {
namespace cli {

namespace {

// 0/1 for the CSV's flags.
int flag(bool b) noexcept { return b ? 1 : 0; }

// A number with three decimals, or nothing (an empty CSV field).
void number_or_empty(TextBuffer& line, bool present, double value) noexcept {
  if (present) {
    line.add(",%.3f", value);
  } else {
    line.add(",");
  }
}

bool write_all(std::FILE* out, const char* text, std::size_t length) noexcept {
  return length > 0U && std::fwrite(text, 1U, length, out) == length;
}

}  // namespace

std::size_t format_cycles_csv_header(bool with_truth, char* out, std::size_t capacity) noexcept {
  if (capacity == 0U) {
    return 0U;
  }
  TextBuffer line(out, capacity);
  line.add("cycle,frame,t_ms,status,prior,failed_stage,solve_status,corners_detected,corners_used,rms_px,"
           "latency_ms,send_offset_ms,total_ms");
  for (int i = 0; i < loop::kNumSteps; ++i) {
    line.add(",%s_ms", loop::kSchedule[static_cast<std::size_t>(i)].name);
  }
  line.add(",overrun,slipped,tcp_x_mm,tcp_y_mm,tcp_z_mm");
  if (with_truth) {
    line.add(",truth_x_mm,truth_y_mm,truth_z_mm,error_mm");
  }
  // The last four say why an estimate has its status: the model-guided
  // rounds gave it (refined), corners the solve dropped, and the two
  // demotions from valid (the encoders', the image fit's).
  line.add(",refined,corners_rejected,encoder_disagrees,fit_disagrees\n");
  return line.length();
}

std::size_t format_cycles_csv_row(const loop::CycleRecord& r, const hal::FrameTruth* truth, bool with_truth,
                                  std::int64_t t0_ns, char* out, std::size_t capacity) noexcept {
  if (capacity == 0U) {
    return 0U;
  }
  const loop::Publication& p = r.publication;
  // Held repeats the last estimate; invalid carries none.
  const bool estimate = p.status != loop::EstimateStatus::kInvalid;
  TextBuffer line(out, capacity);
  line.add("%llu,%u,%.3f,%s,%s,%s,%s,%u,%u", static_cast<unsigned long long>(r.cycle), r.frame_sequence,
           ms(r.trigger_ns - t0_ns), can::to_string(p.status), vision::to_string(r.prior),
           r.failed_stage >= 0 ? loop::kSchedule[static_cast<std::size_t>(r.failed_stage)].name : "",
           r.failed_stage < 0 && r.have_frame ? solver::to_string(r.solve_status) : "",
           static_cast<unsigned>(p.corners_detected), static_cast<unsigned>(p.corners_used));
  number_or_empty(line, estimate, p.rms_px);
  number_or_empty(line, r.latency_ns >= 0, ms(r.latency_ns));
  number_or_empty(line, r.send_offset_ns >= 0, ms(r.send_offset_ns));
  line.add(",%.3f", ms(r.total_ns));
  for (int i = 0; i < loop::kNumSteps; ++i) {
    line.add(",%.3f", ms(r.step_ns[static_cast<std::size_t>(i)]));
  }
  line.add(",%d,%u", flag(r.overrun), r.slipped);
  for (std::size_t i = 0; i < 3U; ++i) {
    number_or_empty(line, estimate, p.tcp_mm[i]);
  }
  if (with_truth) {
    const bool known = truth != nullptr && truth->valid;
    double error_mm = 0.0;
    for (std::size_t i = 0; i < 3U; ++i) {
      const double d = known ? p.tcp_mm[i] - truth->tcp_mm[i] : 0.0;
      error_mm += d * d;
      number_or_empty(line, known, known ? truth->tcp_mm[i] : 0.0);
    }
    // The error of this frame's own estimate (valid or degraded), against this frame's truth.
    number_or_empty(line, known && p.status <= loop::EstimateStatus::kDegraded, std::sqrt(error_mm));
  }
  line.add(",%d,%d,%d,%d\n", flag(r.refined), r.corners_rejected, flag(r.encoder_disagrees), flag(r.fit_disagrees));
  return line.length();
}

bool write_cycles_csv_header(std::FILE* out, bool with_truth) noexcept {
  char line[kCyclesCsvMaxLine];
  const std::size_t length = format_cycles_csv_header(with_truth, line, sizeof line);
  return write_all(out, line, length);
}

bool write_cycles_csv_row(std::FILE* out, const loop::CycleRecord& r, const hal::FrameTruth* truth, bool with_truth,
                          std::int64_t t0_ns) noexcept {
  char line[kCyclesCsvMaxLine];
  const std::size_t length = format_cycles_csv_row(r, truth, with_truth, t0_ns, line, sizeof line);
  return write_all(out, line, length);
}

}  // namespace cli
}  // namespace tcpest
