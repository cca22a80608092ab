// The loop's settings: the `loop:`, `can:` and `rt:` sections of the same
// YAML configuration file as the instrument (config/instrument.yaml). Every
// key is optional; the defaults below are the documented ones (docs/loop.md).
// Unknown keys in these sections are errors (a misspelt key must not be
// silently ignored).
#pragma once

#include <cstdint>

#include "tcpest/common/diagnostic.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/common/yaml_lite.hpp"
#include "tcpest/vision/frame_estimator.hpp"

namespace tcpest {
namespace loop {

enum class Trigger : std::uint8_t {
  kFrame,   // each frame's arrival (a live camera), or the source's rate for replay
  kPeriod,  // a fixed period on CLOCK_MONOTONIC, absolute deadlines
  kSync,    // the CAN SYNC message
};
const char* to_string(Trigger trigger) noexcept;

constexpr std::size_t kMaxSpecText = 256U;

struct LoopSettings {
  Trigger trigger = Trigger::kFrame;
  std::int64_t period_us = 40000;      // kPeriod; also the pace while the camera is lost
  bool pacing = true;                  // replay at the source's rate (false: as fast as possible)
  std::uint64_t frames = 0U;           // stop after this many cycles; 0 = until the source ends or a signal
  char source[kMaxSpecText] = "sim";   // sim | DIR | LIST.txt | FILE.y4m | /dev/videoN
  bool replay_loop = false;            // replay sources start again at their end
  char v4l2_format[16] = "yuyv";       // yuyv | mjpeg | rgb24
  int track_drop_after = 5;            // consecutive failed frames before the track is dropped (vision::Track)
  // Everything that decides an estimate (solve mode, validity test, outlier
  // rounds, encoders' check, guided rounds and seeds, stage 1's grid): the
  // estimator's own configuration, whose defaults are declared once, in
  // vision/frame_estimator.hpp. The `loop:` keys that set it are listed in
  // docs/loop.md and docs/estimation.md.
  vision::EstimatorConfig estimator{};
  int camera_timeout_ms = 200;         // a live camera silent this long counts as not ready
  int camera_lost_after = 5;           // consecutive not-ready cycles before the camera is lost
  int retry_ms = 1000;                 // reopen attempts for a lost camera or bus
  int status_period_ms = 1000;         // `tcpest run` status line
};

struct CanSettings {
  char bus[kMaxSpecText] = "log:can.log";  // IFACE (SocketCAN) | log:FILE (simulated bus + candump log) | sim
  std::uint8_t node_id = 0x10U;
  int heartbeat_ms = 100;
  int prior_timeout_ms = 100;        // an ENCODER_PRIOR older than this is not used
  int prior_max_counter_gap = 2;     // accepted alive-counter steps (1 = no message lost)
  // CiA 301 auto-start: operational after boot-up without an NMT start. Off:
  // the node stays pre-operational (no PDOs) until the robot's NMT master starts it.
  bool start_operational = false;
  int sync_timeout_ms = 500;         // kSync: no SYNC this long counts as a bus fault
};

struct RtSettings {
  bool lock_memory = false;          // mlockall(MCL_CURRENT | MCL_FUTURE)
  int fifo_priority = 0;             // SCHED_FIFO priority 1..99; 0 = normal scheduling
  int cpu = -1;                      // pin to this CPU; -1 = no affinity
  int prefault_stack_kb = 256;       // touch this much stack at start-up; 0 = off
  // CPU wake-up latency request (PM QoS, /dev/cpu_dma_latency), in us, held
  // while the command runs (rt_setup.hpp): 0 keeps the CPUs out of idle states that take
  // long to leave (they poll instead); -1 = no request.
  int cpu_latency_us = -1;
};

struct LoopConfig {
  LoopSettings loop;
  CanSettings can;
  RtSettings rt;
};

// Reads the three sections from a parsed document (absent sections keep the
// defaults). On error: the file, line and field.
Status<Diagnostic> read_loop_config(const yaml::Document& doc, LoopConfig& out) noexcept;
// Loads `path` (nullptr: defaults). Uses the given document as scratch.
Status<Diagnostic> load_loop_config(const char* path, yaml::Document& scratch, LoopConfig& out) noexcept;

}  // namespace loop
}  // namespace tcpest
