// tcpest listen: the controllers' side of the protocol on the command line.
// Reads the estimator's frames from a SocketCAN interface or from a candump
// log (what `tcpest run --bus log:FILE` and `tcpest demo` write), decodes
// and checks them with can::Receiver (E2E: CRC, alive counter, age) and
// prints one line per message (or a JSON line with --json), then a summary.
// Exit codes: commands.hpp (0 clean, 1 an E2E failure or counter jump, or
// the interface failed, 2 usage, 3 an unreadable or damaged log).
#include <time.h>

#include <atomic>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/loop_rig.hpp"
#include "tcpest/can_iface/emcy.hpp"
#include "tcpest/can_iface/receiver.hpp"
#include "tcpest/hal/can/candump_log.hpp"
#include "tcpest/hal/can/socketcan_bus.hpp"

namespace tcpest {
namespace cli {

namespace {

constexpr OptionSpec kOptions[] = {
    {"bus", "BUS", "IFACE (SocketCAN, e.g. vcan0) | log:FILE (a candump log, as `tcpest run --bus log:FILE` writes)"},
    {"log", "FILE", "a candump log file (the same as --bus log:FILE)"},
    {"node-id", "N", "the estimator's node ID, 1..127 (default 16 = 0x10)"},
    {"stale-ms", "MS", "no accepted TCP for this long: the estimate is stale (default 100)"},
    {"frames", "N", "SocketCAN: stop after N frames (default 0: until SIGINT/SIGTERM)"},
    {"seconds", "S", "SocketCAN: stop after S seconds (default 0: until SIGINT/SIGTERM)"},
    {"json", nullptr, "one JSON object a line (messages, refusals, then the summary)"},
    {"quiet", nullptr, "the summary only"},
};
constexpr std::size_t kOptionCount = sizeof kOptions / sizeof kOptions[0];

constexpr std::size_t kMaxLogLine = 256U;
constexpr int kIdlePollNs = 2000000;  // 2 ms between reads of an idle interface

struct Printer {
  bool json = false;
  bool quiet = false;
};

void print_time(std::int64_t t_us) noexcept {
  std::printf("(%" PRId64 ".%06" PRId64 ") ", t_us / 1000000, t_us % 1000000);
}

void print_message(const Printer& out, const can::Receiver& rx, can::Message message, std::int64_t t_us) noexcept {
  if (out.quiet) {
    return;
  }
  if (out.json) {
    std::printf("{\"t_us\": %" PRId64 ", \"msg\": \"%s\"", t_us, can::to_string(message));
  } else {
    print_time(t_us);
    std::printf("%-10s", can::to_string(message));
  }
  // Each value below was just accepted: its query cannot fail.
  switch (message) {
    case can::Message::kTcp: {
      const can::TcpMessage m = rx.tcp().value().value;
      std::printf(out.json ? ", \"x_mm\": %.2f, \"y_mm\": %.2f, \"z_mm\": %.2f, \"status\": \"%s\", \"counter\": %u"
                           : " x %.2f y %.2f z %.2f mm, %s, counter %u",
                  m.x_mm, m.y_mm, m.z_mm, can::to_string(m.status), static_cast<unsigned>(m.counter));
      break;
    }
    case can::Message::kJoints: {
      const can::JointsMessage m = rx.joints().value().value;
      std::printf(out.json ? ", \"lambda_mm\": %.2f, \"phi_rad\": %.4f, \"theta_rad\": %.4f, \"status\": \"%s\", "
                             "\"counter\": %u"
                           : " lambda %.2f mm phi %.4f theta %.4f rad, %s, counter %u",
                  m.lambda_mm, m.phi_rad, m.theta_rad, can::to_string(m.status), static_cast<unsigned>(m.counter));
      break;
    }
    case can::Message::kMechanical: {
      const can::MechanicalMessage m = rx.mechanical().value().value;
      std::printf(out.json ? ", \"x_ch_mm\": %.2f, \"y_ch_mm\": %.2f, \"psi_rad\": %.4f, \"mu_rad\": %.4f"
                           : " x_ch %.2f y_ch %.2f mm psi %.4f mu %.4f rad",
                  m.x_ch_mm, m.y_ch_mm, m.psi_rad, m.mu_rad);
      break;
    }
    case can::Message::kQuality: {
      const can::QualityMessage m = rx.quality().value().value;
      std::printf(out.json ? ", \"corners_detected\": %u, \"corners_used\": %u, \"rms_px\": %.2f, \"latency_us\": "
                             "%" PRId64 ", \"frame\": %u"
                           : " corners detected %u used %u, rms %.2f px, latency %" PRId64 " us, frame %u",
                  static_cast<unsigned>(m.corners_detected), static_cast<unsigned>(m.corners_used), m.rms_px,
                  m.latency_us, static_cast<unsigned>(m.frame_counter));
      break;
    }
    case can::Message::kHeartbeat: {
      const can::NmtState state = rx.nmt_state().value().value;
      std::printf(out.json ? ", \"state\": \"%s\"" : " %s", can::to_string(state));
      break;
    }
    case can::Message::kEmcy: {
      const can::EmcyMessage m = rx.last_emcy().value().value;
      const char* fault = can::to_string(static_cast<can::Fault>(m.fault_id));
      std::printf(out.json ? ", \"code\": %u, \"register\": %u, \"fault\": %u, \"fault_name\": \"%s\", \"detail\": %u"
                           : " code 0x%04X register 0x%02X fault %u %s detail %u",
                  static_cast<unsigned>(m.error_code), static_cast<unsigned>(m.error_register),
                  static_cast<unsigned>(m.fault_id), fault, static_cast<unsigned>(m.detail));
      if (!out.json && m.error_code == 0U) {
        std::printf(" (cleared)");
      }
      break;
    }
  }
  std::printf(out.json ? "}\n" : "\n");
}

void print_refusal(const Printer& out, const can::Frame& frame, can::CanError error, std::int64_t t_us) noexcept {
  if (out.quiet) {
    return;
  }
  if (out.json) {
    std::printf("{\"t_us\": %" PRId64 ", \"id\": \"%03X\", \"error\": \"%s\"}\n", t_us,
                static_cast<unsigned>(frame.id), can::to_string(error));
  } else {
    print_time(t_us);
    std::printf("%03X refused: %s\n", static_cast<unsigned>(frame.id), can::to_string(error));
  }
}

// One frame through the receiver; frames of other identifiers are counted only.
void handle(const Printer& out, can::Receiver& rx, const can::Frame& frame, std::int64_t t_us) noexcept {
  const Result<can::Message, can::CanError> got = rx.receive(frame, t_us);
  if (got.ok()) {
    print_message(out, rx, got.value(), t_us);
  } else if (got.error() != can::CanError::kUnknownId) {
    print_refusal(out, frame, got.error(), t_us);
  }
}

struct Totals {
  std::uint64_t unreadable_lines = 0U;
  std::int64_t last_us = 0;
};

void print_summary_line(const Printer& out, const can::Receiver& rx, const Totals& totals) noexcept {
  const can::ReceiverCounters& c = rx.counters();
  const auto nmt = rx.nmt_state();
  const char* state = nmt.ok() ? can::to_string(nmt.value().value) : "none";
  const char* status = can::to_string(rx.estimate_status(totals.last_us));
  if (out.json) {
    std::printf("{\"msg\": \"summary\", \"frames\": %u, \"decoded\": %u, \"other_id\": %u, \"malformed\": %u, "
                "\"e2e_failures\": %u, \"counter_jumps\": %u, \"stale_events\": %u, \"boot_ups\": %u, "
                "\"emcy_raised\": %u, \"emcy_cleared\": %u, \"unreadable_lines\": %llu, \"nmt_state\": \"%s\", "
                "\"estimate\": \"%s\"}\n",
                c.frames, c.decoded, c.other_id, c.malformed, c.e2e_failures, c.counter_jumps, c.stale_events,
                c.boot_ups, c.emcy_raised, c.emcy_cleared, static_cast<unsigned long long>(totals.unreadable_lines),
                state, status);
    return;
  }
  std::printf("frames %u, decoded %u, other identifiers %u, malformed %u\n", c.frames, c.decoded, c.other_id,
              c.malformed);
  std::printf("E2E failures %u (TCP: CRC %u, length %u, counter 15 %u, repeated %u; JOINTS: CRC %u, length %u, "
              "counter 15 %u, repeated %u), counter jumps %u, stale events %u\n",
              c.e2e_failures, rx.tcp_e2e().bad_crc, rx.tcp_e2e().bad_length, rx.tcp_e2e().bad_counter,
              rx.tcp_e2e().repeated, rx.joints_e2e().bad_crc, rx.joints_e2e().bad_length,
              rx.joints_e2e().bad_counter, rx.joints_e2e().repeated, c.counter_jumps, c.stale_events);
  std::printf("boot-ups %u, EMCY raised %u / cleared %u; last NMT state %s, estimate %s\n", c.boot_ups, c.emcy_raised,
              c.emcy_cleared, state, status);
  if (totals.unreadable_lines > 0U) {
    std::printf("unreadable lines %llu\n", static_cast<unsigned long long>(totals.unreadable_lines));
  }
}

int listen_log(const Printer& out, can::Receiver& rx, const char* path, Totals& totals) noexcept {
  std::FILE* file = std::fopen(path, "r");
  if (file == nullptr) {
    std::fprintf(stderr, "tcpest listen: log %s: %s\n", path, std::strerror(errno));
    return kExitConfig;
  }
  char line[kMaxLogLine];
  std::uint64_t line_number = 0U;
  bool in_long_line = false;  // the rest of a line longer than the buffer
  while (std::fgets(line, sizeof line, file) != nullptr) {
    const bool complete = std::strchr(line, '\n') != nullptr || std::feof(file) != 0;
    if (in_long_line) {
      in_long_line = !complete;
      continue;
    }
    ++line_number;
    in_long_line = !complete;
    if (line[0] == '\n' || line[0] == '\0') {
      continue;  // an empty line carries nothing
    }
    can::Frame frame;
    std::int64_t t_us = 0;
    if (in_long_line || !hal::parse_candump_line(line, frame, t_us)) {
      ++totals.unreadable_lines;
      std::fprintf(stderr, "tcpest listen: log %s, line %llu: not a candump line of a classic frame\n", path,
                   static_cast<unsigned long long>(line_number));
      continue;
    }
    handle(out, rx, frame, t_us);
    totals.last_us = t_us;
  }
  const bool read_error = std::ferror(file) != 0;
  static_cast<void>(std::fclose(file));  // read-only: nothing to lose at close
  if (read_error) {
    std::fprintf(stderr, "tcpest listen: log %s: read error\n", path);
    return kExitConfig;
  }
  rx.update(totals.last_us);
  return kExitOk;
}

std::int64_t realtime_us() noexcept {
  timespec ts{};
  static_cast<void>(::clock_gettime(CLOCK_REALTIME, &ts));  // CLOCK_REALTIME always exists
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

int listen_bus(const Printer& out, can::Receiver& rx, const char* iface, unsigned long long max_frames,
               double max_seconds, Totals& totals) noexcept {
  const std::uint8_t node = rx.config().node_id;
  hal::SocketCanConfig config;
  const std::uint32_t ids[] = {can::tcp_id(node),        can::joints_id(node),    can::mechanical_id(node),
                               can::quality_id(node),    can::heartbeat_id(node), can::emcy_id(node)};
  for (const std::uint32_t id : ids) {
    static_cast<void>(config.rx_ids.push_back(id));  // 6 of 16: cannot be full
  }
  auto bus = std::unique_ptr<hal::SocketCanBus>(new (std::nothrow) hal::SocketCanBus());
  if (!bus) {
    return kExitFailure;
  }
  const auto opened = bus->open(iface, config);
  if (!opened.ok() && opened.error() != hal::CanBusError::kInterfaceDown) {
    std::fprintf(stderr, "tcpest listen: CAN interface %s: %s\n", iface, hal::to_string(opened.error()));
    return kExitFailure;
  }
  const std::atomic<bool>* stop = install_stop_signals();
  const std::int64_t start_us = realtime_us();
  const auto limit_us = static_cast<std::int64_t>(max_seconds * 1e6);
  hal::ReceivedFrame batch[can::kMaxRxPerCycle];
  std::uint64_t frames = 0U;
  while (!stop->load(std::memory_order_relaxed)) {
    const std::int64_t now_us = realtime_us();
    if ((max_frames > 0U && frames >= max_frames) || (limit_us > 0 && now_us - start_us >= limit_us)) {
      break;
    }
    const auto received = bus->receive(batch, can::kMaxRxPerCycle);
    const std::size_t n = received.ok() ? received.value() : 0U;
    for (std::size_t i = 0U; i < n && (max_frames == 0U || frames < max_frames); ++i) {
      handle(out, rx, batch[i].frame, batch[i].timestamp_us);
      totals.last_us = batch[i].timestamp_us;
      ++frames;
    }
    if (n == 0U) {
      rx.update(now_us);
      totals.last_us = now_us;
      const timespec idle{0, kIdlePollNs};
      static_cast<void>(::nanosleep(&idle, nullptr));  // interrupted by a signal: the loop checks the flag
    }
    if (!out.quiet) {
      static_cast<void>(std::fflush(stdout));  // a listener's lines are for now
    }
  }
  const hal::CanBusStats& stats = bus->stats();
  if (stats.rx_kernel_dropped > 0U) {
    std::fprintf(stderr, "tcpest listen: the kernel dropped %llu frames (socket queue full)\n",
                 static_cast<unsigned long long>(stats.rx_kernel_dropped));
  }
  return kExitOk;
}

}  // namespace

int cmd_listen(int argc, char** argv) {
  auto args_owner = std::make_unique<Args>();  // large (positional table): not on the stack
  Args& args = *args_owner;
  char error[256];
  if (!args.parse(argc, argv, 1, kOptions, kOptionCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest listen: %s (see --help)\n", error);
    return kExitUsage;
  }
  if (args.help_requested()) {
    print_usage("tcpest listen (--bus IFACE | --bus log:FILE | --log FILE) [--node-id N] [--json] [--quiet]",
                "The controllers' side of the CAN protocol (docs/can-protocol.md): decodes the estimator's TCP,\n"
                "JOINTS, MECHANICAL, QUALITY, heartbeat and EMCY, checks TCP and JOINTS end to end (CRC, alive\n"
                "counter, age), prints one line per message, then a summary (frames, decoded, E2E failures,\n"
                "counter jumps, stale events). Frames of other identifiers are counted, not printed.\n"
                "Exit codes: 0 done, 1 an E2E failure or counter jump (or the interface failed), 2 usage,\n"
                "3 the log cannot be read or has lines that are not candump lines.",
                kOptions, kOptionCount);
    return kExitOk;
  }
  if (args.positional_count() != 0U) {
    std::fprintf(stderr, "tcpest listen: unexpected argument '%s' (see --help)\n", args.positional(0));
    return kExitUsage;
  }
  const char* bus = args.value("bus");
  const char* log = args.value("log");
  if ((bus == nullptr) == (log == nullptr)) {
    std::fprintf(stderr, "tcpest listen: give exactly one of --bus and --log (see --help)\n");
    return kExitUsage;
  }
  if (bus != nullptr && std::strncmp(bus, "log:", 4) == 0) {
    log = bus + 4;
    bus = nullptr;
  }
  if ((log != nullptr && log[0] == '\0') || (bus != nullptr && (bus[0] == '\0' || std::strcmp(bus, "sim") == 0))) {
    std::fprintf(stderr, "tcpest listen: --bus/--log: expected IFACE, log:FILE or a file name (see --help)\n");
    return kExitUsage;
  }
  unsigned long long node_id = can::kDefaultNodeId;
  unsigned long long stale_ms = 100U;
  unsigned long long max_frames = 0U;
  double max_seconds = 0.0;
  if (!unsigned_option(args, "listen", "node-id", can::kMinNodeId, can::kMaxNodeId, node_id) ||
      !unsigned_option(args, "listen", "stale-ms", 1U, 3600000U, stale_ms) ||
      !unsigned_option(args, "listen", "frames", 0U, 1000000000000ULL, max_frames) ||
      !number_option(args, "listen", "seconds", 0.0, 31536000.0, max_seconds)) {
    return kExitUsage;
  }
  can::ReceiverConfig config;
  config.node_id = static_cast<std::uint8_t>(node_id);
  config.e2e.timeout_us = static_cast<std::int64_t>(stale_ms) * 1000;
  can::Receiver rx;
  if (!rx.configure(config).ok()) {
    std::fprintf(stderr, "tcpest listen: receiver configuration refused\n");  // the ranges above make it valid
    return kExitUsage;
  }
  Printer out;
  out.json = args.flag("json");
  out.quiet = args.flag("quiet");
  Totals totals;
  const int code = log != nullptr ? listen_log(out, rx, log, totals)
                                  : listen_bus(out, rx, bus, max_frames, max_seconds, totals);
  if (code != kExitOk && rx.counters().frames == 0U) {
    return code;  // nothing was read: the message said why
  }
  print_summary_line(out, rx, totals);
  if (code != kExitOk) {
    return code;
  }
  if (totals.unreadable_lines > 0U) {
    std::fprintf(stderr, "tcpest listen: log %s: %llu unreadable line(s)\n", log,
                 static_cast<unsigned long long>(totals.unreadable_lines));
    return kExitConfig;
  }
  const can::ReceiverCounters& c = rx.counters();
  if (c.e2e_failures > 0U || c.counter_jumps > 0U) {
    std::fprintf(stderr, "tcpest listen: %u E2E failure(s), %u counter jump(s)\n", c.e2e_failures, c.counter_jumps);
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace cli
}  // namespace tcpest
