// What `tcpest run`, `demo` and `bench` share: building the loop from the
// configuration file and the command line (camera and instrument models,
// the `loop:`/`can:`/`rt:` sections, the frame source, the CAN bus, the
// vision pipeline), the SIGINT/SIGTERM stop flag, and the summary.
#pragma once

#include <atomic>
#include <cstdio>
#include <memory>

#include "cli/setup.hpp"
#include "tcpest/hal/camera/frame_source.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/hal/can/sim_bus.hpp"
#include "tcpest/hal/can/socketcan_bus.hpp"
#include "tcpest/hal/clock/clock.hpp"
#include "tcpest/loop/can_node_port.hpp"
#include "tcpest/loop/config.hpp"
#include "tcpest/loop/executive.hpp"
#include "tcpest/loop/prerendered_source.hpp"
#include "tcpest/loop/vision_pipeline.hpp"

namespace tcpest {
namespace cli {

struct RigRequest {
  const char* command = "run";
  const char* config_path = nullptr;
  const char* calib_path = nullptr;
  const char* source = nullptr;  // overrides loop.source
  const char* bus = nullptr;     // overrides can.bus
  long long frames = -1;         // overrides loop.frames when >= 0
  bool no_pacing = false;
  bool start_operational = false;  // sets can.start_operational (no NMT master on the bus)
  std::uint32_t sim_frames = 100U;  // frames rendered for the "sim" source
  bool quiet = false;
};

class LoopRig {
 public:
  LoopRig() noexcept = default;
  ~LoopRig();
  LoopRig(const LoopRig&) = delete;
  LoopRig& operator=(const LoopRig&) = delete;
  LoopRig(LoopRig&&) = delete;
  LoopRig& operator=(LoopRig&&) = delete;

  // Models and configuration (with the command-line overrides applied).
  int load(const RigRequest& request) noexcept;
  // The frame source named by config.loop.source.
  int open_source() noexcept;
  // The bus named by config.can.bus, and the CAN node on it; `log_path`
  // (optional) records every frame in candump format whatever the bus.
  int open_bus(const char* log_path = nullptr) noexcept;
  // The vision pipeline and the executive (after the source and the bus).
  int build() noexcept;
  // All four.
  int open_all(const RigRequest& request) noexcept;
  // Closes the candump log, if there is one, and prints its line to `out`
  // (lines, and the write errors with the first one's reason, also on
  // stderr). False when a write or the close failed: the log is incomplete
  // and the command exits 1 (docs/cli.md).
  bool finish_log(std::FILE* out) noexcept;

  RigRequest request{};
  ModelSetup models{};
  loop::LoopConfig config{};
  hal::MonotonicClock clock;
  std::unique_ptr<hal::FrameSource> source;
  loop::PrerenderedSource* sim = nullptr;  // the source, when it is the simulated camera
  std::unique_ptr<hal::SimBus> sim_bus;
  std::unique_ptr<hal::SocketCanBus> socket_bus;
  hal::CandumpLogWriter log;
  bool logging = false;
  char log_file[320] = {};  // the candump log's path, when logging
  char bus_label[320] = {};
  std::unique_ptr<loop::CanNodePort> node;
  std::unique_ptr<loop::FeaturePipeline> pipeline;
  loop::VisionPipeline* vision = nullptr;  // the pipeline, typed (overlays)
  std::unique_ptr<loop::Executive> executive;
};

// SIGINT/SIGTERM set the flag (installed without SA_RESTART, so that a sleep
// returns at once and the loop sees the flag).
const std::atomic<bool>* install_stop_signals() noexcept;

// Per-step and total percentiles, counters, latency.
void print_summary(std::FILE* out, const loop::Executive& executive) noexcept;
// The per-step and total lines of print_summary alone (budget, percentiles,
// overruns).
void print_steps(std::FILE* out, const loop::Executive& executive) noexcept;
// "p50 1.23 ms" helpers.
double ms(std::int64_t ns) noexcept;

}  // namespace cli
}  // namespace tcpest
