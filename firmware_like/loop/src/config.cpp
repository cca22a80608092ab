#include "tcpest/loop/config.hpp"

#include <cstdio>
#include <cstring>

#include "tcpest/loop/rt_setup.hpp"
#include "tcpest/solver/pose_estimator.hpp"
#include "tcpest/vision/guided_estimate.hpp"

namespace tcpest {
namespace loop {

namespace {

using S = Status<Diagnostic>;

S read_int(const yaml::Document& doc, const char* path, long long lo, long long hi, long long& value) noexcept {
  if (!doc.has(path)) {
    return ok_status<Diagnostic>();
  }
  const auto v = doc.integer(path);
  if (!v.ok()) {
    return S::failure(v.error());
  }
  if (v.value() < lo || v.value() > hi) {
    return S::failure(doc.error_at(doc.find(path), path, "out of range"));
  }
  value = v.value();
  return ok_status<Diagnostic>();
}

template <typename T>
S read_int_as(const yaml::Document& doc, const char* path, long long lo, long long hi, T& out) noexcept {
  long long value = static_cast<long long>(out);
  const S s = read_int(doc, path, lo, hi, value);
  if (s.ok()) {
    out = static_cast<T>(value);
  }
  return s;
}

S read_double(const yaml::Document& doc, const char* path, double lo, double hi, double& out) noexcept {
  if (!doc.has(path)) {
    return ok_status<Diagnostic>();
  }
  const auto v = doc.number(path);
  if (!v.ok()) {
    return S::failure(v.error());
  }
  if (!(v.value() >= lo && v.value() <= hi)) {
    return S::failure(doc.error_at(doc.find(path), path, "out of range"));
  }
  out = v.value();
  return ok_status<Diagnostic>();
}

S read_bool(const yaml::Document& doc, const char* path, bool& out) noexcept {
  if (!doc.has(path)) {
    return ok_status<Diagnostic>();
  }
  char text[16] = {};
  const S s = doc.text(path, text, sizeof text);
  if (!s.ok()) {
    return s;
  }
  if (std::strcmp(text, "true") == 0 || std::strcmp(text, "yes") == 0 || std::strcmp(text, "on") == 0) {
    out = true;
  } else if (std::strcmp(text, "false") == 0 || std::strcmp(text, "no") == 0 || std::strcmp(text, "off") == 0) {
    out = false;
  } else {
    return S::failure(doc.error_at(doc.find(path), path, "expected true or false"));
  }
  return ok_status<Diagnostic>();
}

S read_text(const yaml::Document& doc, const char* path, char* out, std::size_t capacity) noexcept {
  if (!doc.has(path)) {
    return ok_status<Diagnostic>();
  }
  return doc.text(path, out, capacity);
}

// rt.prefault_stack_kb: at most what the reading thread's stack can take
// (the loop runs on it), else the start-up pre-fault would overflow it.
S read_prefault_stack_kb(const yaml::Document& doc, int& out) noexcept {
  constexpr const char* kPath = "rt.prefault_stack_kb";
  if (!doc.has(kPath)) {
    return ok_status<Diagnostic>();
  }
  const auto v = doc.integer(kPath);
  if (!v.ok()) {
    return S::failure(v.error());
  }
  const long long max_kb = max_prefault_stack_kb();
  if (v.value() < 0 || v.value() > max_kb) {
    char message[160];
    static_cast<void>(std::snprintf(message, sizeof message,
                                    "%lld out of range: allowed 0..%lld (KiB; this thread's stack less a margin)",
                                    v.value(), max_kb));  // fits
    return S::failure(doc.error_at(doc.find(kPath), kPath, message));
  }
  out = static_cast<int>(v.value());
  return ok_status<Diagnostic>();
}

#define TCPEST_TRY(expr)   \
  do {                     \
    const S s_ = (expr);   \
    if (!s_.ok()) {        \
      return s_;           \
    }                      \
  } while (false)

}  // namespace

const char* to_string(Trigger trigger) noexcept {
  switch (trigger) {
    case Trigger::kFrame:
      return "frame";
    case Trigger::kPeriod:
      return "period";
    case Trigger::kSync:
      return "sync";
  }
  return "?";
}

Status<Diagnostic> read_loop_config(const yaml::Document& doc, LoopConfig& out) noexcept {
  LoopSettings& l = out.loop;
  vision::EstimatorConfig& e = l.estimator;
  if (doc.has("loop.trigger")) {
    char text[16] = {};
    TCPEST_TRY(doc.text("loop.trigger", text, sizeof text));
    if (std::strcmp(text, "frame") == 0) {
      l.trigger = Trigger::kFrame;
    } else if (std::strcmp(text, "period") == 0) {
      l.trigger = Trigger::kPeriod;
    } else if (std::strcmp(text, "sync") == 0) {
      l.trigger = Trigger::kSync;
    } else {
      return S::failure(doc.error_at(doc.find("loop.trigger"), "loop.trigger", "expected frame, period or sync"));
    }
  }
  TCPEST_TRY(read_int_as(doc, "loop.period_us", 1000, 10000000, l.period_us));
  TCPEST_TRY(read_bool(doc, "loop.pacing", l.pacing));
  TCPEST_TRY(read_int_as(doc, "loop.frames", 0, 1000000000000LL, l.frames));
  TCPEST_TRY(read_text(doc, "loop.source", l.source, sizeof l.source));
  TCPEST_TRY(read_bool(doc, "loop.replay_loop", l.replay_loop));
  TCPEST_TRY(read_text(doc, "loop.v4l2_format", l.v4l2_format, sizeof l.v4l2_format));
  if (doc.has("loop.solve_mode")) {
    char text[16] = {};
    TCPEST_TRY(doc.text("loop.solve_mode", text, sizeof text));
    if (std::strcmp(text, "adaptive") == 0) {
      e.solve_mode = solver::SolveMode::Adaptive;
    } else if (std::strcmp(text, "fixed") == 0) {
      e.solve_mode = solver::SolveMode::FixedModel;
    } else {
      return S::failure(doc.error_at(doc.find("loop.solve_mode"), "loop.solve_mode", "expected adaptive or fixed"));
    }
  }
  if (doc.has("loop.classify_step")) {
    char text[8] = {};
    TCPEST_TRY(doc.text("loop.classify_step", text, sizeof text));
    if (std::strcmp(text, "auto") == 0) {
      e.classify_step = 0;
    } else if (std::strcmp(text, "1") == 0) {
      e.classify_step = 1;
    } else if (std::strcmp(text, "2") == 0) {
      e.classify_step = 2;
    } else {
      return S::failure(doc.error_at(doc.find("loop.classify_step"), "loop.classify_step", "expected auto, 1 or 2"));
    }
  }
  TCPEST_TRY(read_int_as(doc, "loop.track_drop_after", 1, 1000, l.track_drop_after));
  TCPEST_TRY(read_int_as(doc, "loop.min_corners_valid", 4, 12, e.solve.min_corners_valid));
  TCPEST_TRY(read_double(doc, "loop.max_rms_valid_px", 0.0, 1000.0, e.solve.max_rms_valid_px));
  TCPEST_TRY(read_double(doc, "loop.encoder_check_lambda_mm", 0.0, 100.0, e.encoder_check.lambda_tolerance_mm));
  TCPEST_TRY(read_double(doc, "loop.encoder_check_bend_rad", 0.0, 4.0, e.encoder_check.bend_tolerance_rad));
  TCPEST_TRY(read_int_as(doc, "loop.outlier_rounds", 0, solver::kMaxOutlierRounds, e.solve.outlier_rounds));
  vision::GuidedOptions& g = e.guided;
  TCPEST_TRY(read_int_as(doc, "loop.guided_rounds", 0, vision::kMaxGuidedRounds, g.rounds));
  TCPEST_TRY(read_bool(doc, "loop.base_rim_seed", g.base_rim_seed));
  TCPEST_TRY(read_double(doc, "loop.max_valid_tcp_disagreement_mm", 0.0, 100.0, g.max_valid_tcp_disagreement_mm));
  TCPEST_TRY(read_int_as(doc, "loop.camera_timeout_ms", 1, 60000, l.camera_timeout_ms));
  TCPEST_TRY(read_int_as(doc, "loop.camera_lost_after", 1, 10000, l.camera_lost_after));
  TCPEST_TRY(read_int_as(doc, "loop.retry_ms", 10, 600000, l.retry_ms));
  TCPEST_TRY(read_int_as(doc, "loop.status_period_ms", 100, 600000, l.status_period_ms));

  CanSettings& c = out.can;
  TCPEST_TRY(read_text(doc, "can.bus", c.bus, sizeof c.bus));
  TCPEST_TRY(read_int_as(doc, "can.node_id", 1, 127, c.node_id));
  TCPEST_TRY(read_int_as(doc, "can.heartbeat_ms", 10, 60000, c.heartbeat_ms));
  TCPEST_TRY(read_int_as(doc, "can.prior_timeout_ms", 1, 60000, c.prior_timeout_ms));
  TCPEST_TRY(read_int_as(doc, "can.prior_max_counter_gap", 1, 14, c.prior_max_counter_gap));
  if (doc.has("can.autostart")) {
    return S::failure(doc.error_at(doc.find("can.autostart"), "can.autostart",
                                   "renamed: can.start_operational (default false: wait for the NMT start)"));
  }
  TCPEST_TRY(read_bool(doc, "can.start_operational", c.start_operational));
  TCPEST_TRY(read_int_as(doc, "can.sync_timeout_ms", 1, 600000, c.sync_timeout_ms));

  RtSettings& r = out.rt;
  TCPEST_TRY(read_bool(doc, "rt.lock_memory", r.lock_memory));
  TCPEST_TRY(read_int_as(doc, "rt.fifo_priority", 0, 99, r.fifo_priority));
  TCPEST_TRY(read_int_as(doc, "rt.cpu", -1, 1023, r.cpu));
  TCPEST_TRY(read_prefault_stack_kb(doc, r.prefault_stack_kb));
  TCPEST_TRY(read_int_as(doc, "rt.cpu_latency_us", -1, 1000000, r.cpu_latency_us));

  const char* sections[] = {"loop", "can", "rt"};
  for (const char* section : sections) {
    const yaml::Entry* unknown = doc.first_unused(section);
    if (unknown != nullptr) {
      return S::failure(doc.error_at(unknown, unknown->path, "unknown key"));
    }
  }
  return ok_status<Diagnostic>();
}

Status<Diagnostic> load_loop_config(const char* path, yaml::Document& scratch, LoopConfig& out) noexcept {
  out = LoopConfig{};
  if (path == nullptr) {
    return ok_status<Diagnostic>();
  }
  const S loaded = scratch.load(path);
  if (!loaded.ok()) {
    return loaded;
  }
  return read_loop_config(scratch, out);
}

}  // namespace loop
}  // namespace tcpest
