// tcpest_period_floor: the timer floor for the period-jitter measurements.
// A bare clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME) loop at a fixed
// period that, at each wake-up, optionally writes one CAN frame on a raw
// SocketCAN socket, and nothing else. Whatever jitter it shows is the
// machine's (timer, scheduler, one send syscall), not the loop's: it is the
// floor that `tcpest run` on the period trigger is compared with, measured
// in the same run and the same machine conditions (tests/vcan/loop-jitter.sh,
// docs/loop.md "Measured").
//
// Frames: standard ID --id (default 0x7F0, outside every COB-ID of
// can-protocol.md), 8 bytes, bytes 0-3 the wake-up's sequence number (little
// endian, gaps show skipped deadlines), bytes 4-7 zero.
//
// Prints the wake-up lateness |wake - deadline| in microseconds
// (n, p50, p99, p99.9, max) and the skipped deadlines, as `tcpest bench`.
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>

namespace {

constexpr std::int64_t kNsPerS = 1000000000;
constexpr std::int64_t kNsPerUs = 1000;

std::atomic<bool> g_stop{false};  // NOLINT(cppcoreguidelines-avoid-non-const-global-variables): set by the signal handler

extern "C" void on_stop_signal(int /*signal*/) { g_stop.store(true); }

struct Options {
  const char* iface = nullptr;  // no bus: wake-ups only
  std::uint32_t can_id = 0x7F0U;
  std::int64_t period_us = 40000;
  double seconds = 10.0;
  int fifo_priority = 0;
  bool lock_memory = false;
  std::int64_t busy_us = 0;  // CPU time burnt after each send (a stand-in for a cycle's work)
};

std::int64_t now_ns() noexcept {
  timespec ts{};
  static_cast<void>(clock_gettime(CLOCK_MONOTONIC, &ts));  // cannot fail with a valid pointer
  return static_cast<std::int64_t>(ts.tv_sec) * kNsPerS + static_cast<std::int64_t>(ts.tv_nsec);
}

bool sleep_until(std::int64_t deadline_ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(deadline_ns % kNsPerS);
  return clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == 0;
}

void usage() noexcept {
  std::fprintf(stderr,
               "usage: tcpest_period_floor [--iface IFACE] [--id HEX] [--period-us P] [--seconds S]\n"
               "                           [--fifo PRIO] [--lock] [--busy-us N]\n"
               "A bare clock_nanosleep(TIMER_ABSTIME) loop; with --iface one CAN frame per wake-up;\n"
               "with --busy-us N microseconds of CPU burnt after each wake-up (the floor of a task that\n"
               "works as much as the loop's cycle: the scheduler treats such a task differently).\n");
}

bool parse(int argc, char** argv, Options& o) noexcept {
  for (int i = 1; i < argc; ++i) {
    const char* a = argv[i];
    const bool has_value = i + 1 < argc;
    char* end = nullptr;
    if (std::strcmp(a, "--lock") == 0) {
      o.lock_memory = true;
    } else if (std::strcmp(a, "--iface") == 0 && has_value) {
      o.iface = argv[++i];
    } else if (std::strcmp(a, "--id") == 0 && has_value) {
      const unsigned long id = std::strtoul(argv[++i], &end, 16);
      if (*end != '\0' || id > 0x7FFUL) {
        return false;
      }
      o.can_id = static_cast<std::uint32_t>(id);
    } else if (std::strcmp(a, "--period-us") == 0 && has_value) {
      o.period_us = std::strtoll(argv[++i], &end, 10);
      if (*end != '\0' || o.period_us < 1000) {
        return false;
      }
    } else if (std::strcmp(a, "--seconds") == 0 && has_value) {
      o.seconds = std::strtod(argv[++i], &end);
      if (*end != '\0' || !(o.seconds > 0.0) || o.seconds > 86400.0) {
        return false;
      }
    } else if (std::strcmp(a, "--busy-us") == 0 && has_value) {
      o.busy_us = std::strtoll(argv[++i], &end, 10);
      if (*end != '\0' || o.busy_us < 0) {
        return false;
      }
    } else if (std::strcmp(a, "--fifo") == 0 && has_value) {
      const long priority = std::strtol(argv[++i], &end, 10);
      if (*end != '\0' || priority < 0 || priority > 99) {
        return false;
      }
      o.fifo_priority = static_cast<int>(priority);
    } else {
      return false;
    }
  }
  return true;
}

int open_can(const char* iface) noexcept {
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) {
    return -1;
  }
  ifreq ifr{};
  static_cast<void>(std::snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", iface));  // a long name fails below
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  // Receive nothing: this socket only sends.
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, nullptr, 0) != 0 || ::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) {
    static_cast<void>(::close(fd));  // failing anyway
    return -1;
  }
  addr.can_ifindex = ifr.ifr_ifindex;
  // NOLINTNEXTLINE(cppcoreguidelines-pro-type-reinterpret-cast): the sockets API takes a sockaddr*
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    static_cast<void>(::close(fd));  // failing anyway
    return -1;
  }
  return fd;
}

double quantile_us(const std::vector<std::int64_t>& sorted, double q) noexcept {
  if (sorted.empty()) {
    return 0.0;
  }
  // Nearest rank, as the loop's histograms.
  std::size_t rank = static_cast<std::size_t>(q * static_cast<double>(sorted.size()) + 0.999999);
  rank = rank == 0U ? 1U : (rank > sorted.size() ? sorted.size() : rank);
  return static_cast<double>(sorted[rank - 1U]) / static_cast<double>(kNsPerUs);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (!parse(argc, argv, o)) {
    usage();
    return 2;
  }
  if (o.lock_memory && ::mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    std::fprintf(stderr, "tcpest_period_floor: mlockall: %s (going on without)\n", std::strerror(errno));
  }
  if (o.fifo_priority > 0) {
    sched_param param{};
    param.sched_priority = o.fifo_priority;
    if (::sched_setscheduler(0, SCHED_FIFO, &param) != 0) {
      std::fprintf(stderr, "tcpest_period_floor: SCHED_FIFO %d: %s (going on without)\n", o.fifo_priority,
                   std::strerror(errno));
    }
  }
  int fd = -1;
  if (o.iface != nullptr) {
    fd = open_can(o.iface);
    if (fd < 0) {
      std::fprintf(stderr, "tcpest_period_floor: cannot open CAN interface %s: %s\n", o.iface, std::strerror(errno));
      return 1;
    }
  }
  static_cast<void>(std::signal(SIGINT, on_stop_signal));   // a stop prints what was measured
  static_cast<void>(std::signal(SIGTERM, on_stop_signal));  // idem
  const std::int64_t period_ns = o.period_us * kNsPerUs;
  const auto periods = static_cast<std::size_t>(o.seconds * 1e9 / static_cast<double>(period_ns));
  std::vector<std::int64_t> late_ns;
  late_ns.reserve(periods);  // the only allocation, before the first wake-up
  std::uint64_t skipped = 0U;
  std::uint64_t send_errors = 0U;
  std::uint32_t sequence = 0U;
  can_frame frame{};
  frame.can_id = o.can_id;
  frame.len = 8U;  // NOLINT(cppcoreguidelines-pro-type-union-access): can_frame's length is a union member in linux/can.h
  std::int64_t deadline = now_ns() + period_ns;
  for (std::size_t i = 0; i < periods && !g_stop.load(); ++i) {
    if (!sleep_until(deadline)) {
      continue;  // a signal: the loop condition decides
    }
    const std::int64_t woke = now_ns();
    if (fd >= 0) {
      std::memcpy(frame.data, &sequence, sizeof sequence);  // little endian on every target we run on
      if (::write(fd, &frame, sizeof frame) != static_cast<ssize_t>(sizeof frame)) {
        ++send_errors;
      }
    }
    late_ns.push_back(woke - deadline);
    if (o.busy_us > 0) {
      const std::int64_t until = woke + o.busy_us * kNsPerUs;
      while (now_ns() < until) {
        // burn CPU: the stand-in for a cycle's work
      }
    }
    deadline += period_ns;
    ++sequence;
    if (woke > deadline) {
      // Deadlines already passed are skipped, as hal::PeriodicTimer does.
      const std::int64_t missed = (woke - deadline) / period_ns + 1;
      deadline += missed * period_ns;
      sequence += static_cast<std::uint32_t>(missed);
      skipped += static_cast<std::uint64_t>(missed);
    }
  }
  if (fd >= 0) {
    static_cast<void>(::close(fd));  // nothing to do about a close error at exit
  }
  std::sort(late_ns.begin(), late_ns.end());
  std::printf("%-34s %8s %9s %9s %9s %9s\n", "|actual - nominal| (us)", "n", "p50", "p99", "p99.9", "max");
  std::printf("%-34s %8zu %9.1f %9.1f %9.1f %9.1f\n", "bare clock_nanosleep wake-up", late_ns.size(),
              quantile_us(late_ns, 0.5), quantile_us(late_ns, 0.99), quantile_us(late_ns, 0.999),
              quantile_us(late_ns, 1.0));
  std::printf("period %.3f ms, skipped deadlines %llu, send errors %llu%s, busy %lld us per period\n",
              static_cast<double>(period_ns) / 1e6, static_cast<unsigned long long>(skipped),
              static_cast<unsigned long long>(send_errors), o.iface != nullptr ? "" : " (no bus)",
              static_cast<long long>(o.busy_us));
  return 0;
}
