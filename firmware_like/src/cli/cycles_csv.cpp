#include "cli/cycles_csv.hpp"

#include <cmath>
#include <cstddef>

#include "cli/loop_rig.hpp"

namespace tcpest {
namespace cli {

namespace {

// 0/1 for the CSV's flags.
int flag(bool b) noexcept { return b ? 1 : 0; }

}  // namespace

bool write_cycles_csv_header(std::FILE* out) noexcept {
  bool ok = std::fprintf(out,
                         "cycle,frame,t_ms,status,prior,failed_stage,solve_status,corners_detected,corners_used,rms_px,"
                         "latency_ms,send_offset_ms,total_ms") >= 0;
  for (int i = 0; i < loop::kNumSteps; ++i) {
    ok = std::fprintf(out, ",%s_ms", loop::kSchedule[static_cast<std::size_t>(i)].name) >= 0 && ok;
  }
  // The last four say why an estimate has its status: the model-guided
  // rounds gave it (refined), corners the solve dropped, and the two
  // demotions from valid (the encoders', the image fit's).
  ok = std::fprintf(out,
                    ",overrun,slipped,tcp_x_mm,tcp_y_mm,tcp_z_mm,truth_x_mm,truth_y_mm,truth_z_mm,error_mm,"
                    "refined,corners_rejected,encoder_disagrees,fit_disagrees\n") >= 0 &&
       ok;
  return ok;
}

bool write_cycles_csv_row(std::FILE* out, const loop::CycleRecord& r, const hal::FrameTruth* truth,
                          std::int64_t t0_ns) noexcept {
  const loop::Publication& p = r.publication;
  const hal::FrameTruth t = truth != nullptr ? *truth : hal::FrameTruth{};
  double error_mm = -1.0;  // -1: nothing estimated, or no truth to compare with
  if (t.valid && p.status <= loop::EstimateStatus::kDegraded) {
    const double dx = p.tcp_mm[0] - t.tcp_mm[0];
    const double dy = p.tcp_mm[1] - t.tcp_mm[1];
    const double dz = p.tcp_mm[2] - t.tcp_mm[2];
    error_mm = std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  bool ok = std::fprintf(out, "%llu,%u,%.3f,%s,%s,%s,%s,%u,%u,%.3f,%.3f,%.3f,%.3f",
                         static_cast<unsigned long long>(r.cycle), r.frame_sequence, ms(r.trigger_ns - t0_ns),
                         can::to_string(p.status), vision::to_string(r.prior),
                         r.failed_stage >= 0 ? loop::kSchedule[static_cast<std::size_t>(r.failed_stage)].name : "",
                         r.failed_stage < 0 && r.have_frame ? solver::to_string(r.solve_status) : "",
                         static_cast<unsigned>(p.corners_detected), static_cast<unsigned>(p.corners_used), p.rms_px,
                         r.latency_ns >= 0 ? ms(r.latency_ns) : -1.0,
                         r.send_offset_ns >= 0 ? ms(r.send_offset_ns) : -1.0, ms(r.total_ns)) >= 0;
  for (int i = 0; i < loop::kNumSteps; ++i) {
    ok = std::fprintf(out, ",%.3f", ms(r.step_ns[static_cast<std::size_t>(i)])) >= 0 && ok;
  }
  ok = std::fprintf(out, ",%d,%u,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%d,%d\n", flag(r.overrun), r.slipped,
                    p.tcp_mm[0], p.tcp_mm[1], p.tcp_mm[2], t.tcp_mm[0], t.tcp_mm[1], t.tcp_mm[2],
                    error_mm, flag(r.refined), r.corners_rejected, flag(r.encoder_disagrees),
                    flag(r.fit_disagrees)) >= 0 &&
       ok;
  return ok;
}

}  // namespace cli
}  // namespace tcpest
