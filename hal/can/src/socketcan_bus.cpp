#include "tcpest/hal/can/socketcan_bus.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>

namespace tcpest {
namespace hal {
namespace {

std::int64_t monotonic_us() noexcept {
  timespec now{};
  static_cast<void>(clock_gettime(CLOCK_MONOTONIC, &now));  // cannot fail for CLOCK_MONOTONIC
  return static_cast<std::int64_t>(now.tv_sec) * 1000000 + now.tv_nsec / 1000;
}

void sleep_us(std::int64_t duration_us) noexcept {
  timespec wait{};
  wait.tv_sec = static_cast<time_t>(duration_us / 1000000);
  wait.tv_nsec = static_cast<long>((duration_us % 1000000) * 1000);
  // An early wake-up (signal) only shortens one retry wait.
  static_cast<void>(nanosleep(&wait, nullptr));
}

bool is_queue_full(int error_number) noexcept { return error_number == ENOBUFS || error_number == EAGAIN; }
bool is_gone(int error_number) noexcept {
  return error_number == ENETDOWN || error_number == ENODEV || error_number == ENXIO;
}

// struct can_frame keeps `len` in a union with the deprecated `can_dlc`:
// the kernel's ABI, read and written in these two places only.
std::uint8_t frame_length(const can_frame& raw) noexcept {
  return raw.len;  // NOLINT(cppcoreguidelines-pro-type-union-access): kernel ABI union (len / can_dlc)
}
void set_frame_length(can_frame& raw, std::uint8_t length) noexcept {
  raw.len = length;  // NOLINT(cppcoreguidelines-pro-type-union-access): kernel ABI union (len / can_dlc)
}

// The error classes the backend wants to see.
constexpr can_err_mask_t kErrorMask = CAN_ERR_BUSOFF | CAN_ERR_CRTL | CAN_ERR_RESTARTED | CAN_ERR_TX_TIMEOUT;

}  // namespace

const char* to_string(CanBusError error) noexcept {
  switch (error) {
    case CanBusError::kNotSupported: return "CAN not supported by this kernel";
    case CanBusError::kNoSuchInterface: return "no such CAN interface";
    case CanBusError::kInterfaceDown: return "CAN interface down";
    case CanBusError::kTxQueueFull: return "TX queue full, frame dropped";
    case CanBusError::kBusOff: return "bus-off";
    case CanBusError::kPermissionDenied: return "permission denied";
    case CanBusError::kBadFrame: return "not a classic CAN frame";
    case CanBusError::kInvalidArgument: return "invalid argument";
    case CanBusError::kNotOpen: return "bus not open";
    case CanBusError::kOutOfResources: return "out of resources";
    case CanBusError::kIoError: return "I/O error";
  }
  return "unknown error";
}

const char* to_string(BusState state) noexcept {
  switch (state) {
    case BusState::kUp: return "up";
    case BusState::kErrorPassive: return "error-passive";
    case BusState::kBusOff: return "bus-off";
    case BusState::kDown: return "down";
  }
  return "unknown";
}

CanBusError error_from_errno(int error_number) noexcept {
  switch (error_number) {
    case EAFNOSUPPORT:
    case EPROTONOSUPPORT:
    case ESOCKTNOSUPPORT:
      return CanBusError::kNotSupported;
    case ENODEV:
    case ENXIO:
      return CanBusError::kNoSuchInterface;
    case ENETDOWN:
      return CanBusError::kInterfaceDown;
    case ENOBUFS:
    case EAGAIN:
      return CanBusError::kTxQueueFull;
    case EPERM:
    case EACCES:
      return CanBusError::kPermissionDenied;
    case EINVAL:
    case ENAMETOOLONG:
      return CanBusError::kInvalidArgument;
    case EMFILE:
    case ENFILE:
    case ENOMEM:
      return CanBusError::kOutOfResources;
    default:
      return CanBusError::kIoError;
  }
}

SocketCanBus::~SocketCanBus() { close(); }

void SocketCanBus::close() noexcept {
  if (fd_ >= 0) {
    static_cast<void>(::close(fd_));  // nothing useful to do if close fails on a socket
    fd_ = -1;
  }
  state_ = BusState::kDown;
}

Status<CanBusError> SocketCanBus::open(const char* interface_name, const SocketCanConfig& config) noexcept {
  close();
  configured_ = false;
  if (interface_name == nullptr || interface_name[0] == '\0' || std::strlen(interface_name) >= sizeof name_ ||
      config.tx_retry_wait_us < 0 || config.reopen_interval_us < 0 || config.receive_buffer_bytes < 0) {
    return Status<CanBusError>::failure(CanBusError::kInvalidArgument);
  }
  std::memset(name_, 0, sizeof name_);
  std::memcpy(name_, interface_name, std::strlen(interface_name));
  config_ = config;
  for (const std::uint32_t id : config_.rx_ids) {
    if (id > can::kMaxStandardId) {
      return Status<CanBusError>::failure(CanBusError::kInvalidArgument);
    }
  }
  configured_ = true;
  const Status<CanBusError> opened = open_socket();
  if (!opened && (opened.error() == CanBusError::kInterfaceDown || opened.error() == CanBusError::kNoSuchInterface)) {
    // Usable: it comes back by itself when the interface is up.
    ++stats_.down_events;
    next_reopen_us_ = monotonic_us() + config_.reopen_interval_us;
  }
  return opened;
}

Status<CanBusError> SocketCanBus::open_socket() noexcept {
  using S = Status<CanBusError>;
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    stats_.last_errno = errno;
    return S::failure(error_from_errno(stats_.last_errno));
  }
  const auto fail = [&](int error_number) noexcept {
    stats_.last_errno = error_number;
    static_cast<void>(::close(fd));  // failing open: the socket is abandoned either way
    return S::failure(error_from_errno(error_number));
  };

  ifreq request{};
  std::memcpy(request.ifr_name, name_, sizeof name_);
  if (::ioctl(fd, SIOCGIFINDEX, &request) < 0) {
    return fail(errno == ENODEV ? ENODEV : errno);
  }
  const int if_index = request.ifr_ifindex;

  std::array<can_filter, kMaxRxFilters> filters{};
  std::size_t filter_count = 0U;
  for (const std::uint32_t id : config_.rx_ids) {
    filters[filter_count].can_id = id;
    // Exact standard ID, data frames only.
    filters[filter_count].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
    ++filter_count;
  }
  if (filter_count > 0U &&
      ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                   static_cast<socklen_t>(filter_count * sizeof(can_filter))) < 0) {
    return fail(errno);
  }
  const can_err_mask_t error_mask = kErrorMask;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &error_mask, sizeof error_mask) < 0) {
    return fail(errno);
  }
  const int enable = 1;
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &enable, sizeof enable) < 0 ||
      ::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &enable, sizeof enable) < 0) {
    return fail(errno);
  }
  if (config_.receive_buffer_bytes > 0 &&
      ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &config_.receive_buffer_bytes, sizeof config_.receive_buffer_bytes) <
          0) {
    return fail(errno);
  }
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = if_index;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) < 0) {  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): the sockets API takes sockaddr*
    return fail(errno);
  }
  // A bound socket on a down interface would fail every send: report it.
  if (::ioctl(fd, SIOCGIFFLAGS, &request) < 0) {
    return fail(errno);
  }
  if ((static_cast<unsigned>(request.ifr_flags) & IFF_UP) == 0U) {
    return fail(ENETDOWN);
  }
  fd_ = fd;
  state_ = BusState::kUp;
  stats_.rx_kernel_dropped = 0U;  // SO_RXQ_OVFL counts per socket
  return S::success(Unit{});
}

bool SocketCanBus::interface_up() const noexcept {
  if (fd_ < 0) {
    return false;
  }
  ifreq request{};
  std::memcpy(request.ifr_name, name_, sizeof name_);
  return ::ioctl(fd_, SIOCGIFFLAGS, &request) == 0 && (static_cast<unsigned>(request.ifr_flags) & IFF_UP) != 0U;
}

void SocketCanBus::mark_down(int error_number) noexcept {
  stats_.last_errno = error_number;
  // Down but still there: the bound socket survives and works again once the
  // interface is up. Gone (unregistered): the kernel unbound it, open anew.
  if (error_number != ENETDOWN) {
    close();
  }
  if (state_ != BusState::kDown) {
    ++stats_.down_events;
  }
  state_ = BusState::kDown;
  next_reopen_us_ = monotonic_us() + config_.reopen_interval_us;
}

bool SocketCanBus::ensure_open() noexcept {
  if (fd_ >= 0 && state_ != BusState::kDown) {
    return true;
  }
  if (!configured_) {
    return false;
  }
  const std::int64_t now_us = monotonic_us();
  if (now_us < next_reopen_us_) {
    return false;
  }
  next_reopen_us_ = now_us + config_.reopen_interval_us;
  if (fd_ >= 0) {
    if (!interface_up()) {
      return false;
    }
    state_ = BusState::kUp;
  } else if (!open_socket()) {
    return false;
  }
  ++stats_.recoveries;
  return true;
}

Status<CanBusError> SocketCanBus::send(const can::Frame& frame) noexcept {
  using S = Status<CanBusError>;
  if (frame.id > can::kMaxStandardId || frame.length > can::kMaxDataLength) {
    ++stats_.tx_dropped;
    return S::failure(CanBusError::kBadFrame);
  }
  if (!configured_) {
    return S::failure(CanBusError::kNotOpen);
  }
  if (!ensure_open()) {
    ++stats_.tx_dropped;
    return S::failure(fd_ >= 0 ? CanBusError::kInterfaceDown : CanBusError::kNoSuchInterface);
  }
  if (state_ == BusState::kBusOff) {
    ++stats_.tx_dropped;
    return S::failure(CanBusError::kBusOff);
  }
  can_frame raw{};
  raw.can_id = frame.id;
  set_frame_length(raw, frame.length);
  std::memcpy(raw.data, frame.data.data(), frame.length);
  for (std::uint32_t attempt = 0U;; ++attempt) {
    const ssize_t written = ::write(fd_, &raw, sizeof raw);
    if (written == static_cast<ssize_t>(sizeof raw)) {
      ++stats_.tx_frames;
      return S::success(Unit{});
    }
    const int error_number = written < 0 ? errno : EIO;
    stats_.last_errno = error_number;
    if (error_number == EINTR) {
      continue;  // not a failure of the bus; bounded by the signals received
    }
    if (is_queue_full(error_number) && attempt < config_.tx_retry_count) {
      ++stats_.tx_retries;
      sleep_us(config_.tx_retry_wait_us);
      continue;
    }
    ++stats_.tx_dropped;
    if (is_gone(error_number)) {
      mark_down(error_number);
      return S::failure(CanBusError::kInterfaceDown);
    }
    return S::failure(error_from_errno(error_number));
  }
}

void SocketCanBus::handle_error_frame(std::uint32_t can_id, const std::uint8_t* data) noexcept {
  ++stats_.error_frames;
  if ((can_id & CAN_ERR_BUSOFF) != 0U) {
    ++stats_.bus_off;
    state_ = BusState::kBusOff;
  }
  if ((can_id & CAN_ERR_CRTL) != 0U) {
    ++stats_.controller_problems;
    constexpr std::uint8_t kPassiveOrWarning =
        CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING | CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE;
    if ((data[1] & kPassiveOrWarning) != 0U && state_ == BusState::kUp) {
      state_ = BusState::kErrorPassive;
    }
    if ((data[1] & CAN_ERR_CRTL_ACTIVE) != 0U && state_ == BusState::kErrorPassive) {
      state_ = BusState::kUp;
    }
  }
  if ((can_id & CAN_ERR_RESTARTED) != 0U) {
    ++stats_.restarts;
    state_ = BusState::kUp;
  }
}

Result<std::size_t, CanBusError> SocketCanBus::receive(ReceivedFrame* out, std::size_t max_frames) noexcept {
  using R = Result<std::size_t, CanBusError>;
  if (!configured_) {
    return R::failure(CanBusError::kNotOpen);
  }
  if (out == nullptr && max_frames > 0U) {
    return R::failure(CanBusError::kInvalidArgument);
  }
  if (!ensure_open()) {
    return R::failure(CanBusError::kInterfaceDown);
  }
  std::size_t count = 0U;
  // Error frames and skipped frames also cost a read: bound the reads too.
  for (std::size_t reads = 0U; count < max_frames && reads < 2U * max_frames; ++reads) {
    can_frame raw{};
    iovec io{};
    io.iov_base = &raw;
    io.iov_len = sizeof raw;
    alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timeval)) + CMSG_SPACE(sizeof(std::uint32_t))> control{};
    msghdr message{};
    message.msg_iov = &io;
    message.msg_iovlen = 1;
    message.msg_control = control.data();
    message.msg_controllen = control.size();
    const ssize_t got = ::recvmsg(fd_, &message, MSG_DONTWAIT);
    if (got < 0) {
      const int error_number = errno;
      if (error_number == EAGAIN || error_number == EINTR) {
        break;
      }
      stats_.last_errno = error_number;
      if (error_number == ENETDOWN && interface_up()) {
        continue;  // the notification of a down that is already over: keep reading
      }
      if (is_gone(error_number)) {
        mark_down(error_number);
        return count > 0U ? R::success(count) : R::failure(CanBusError::kInterfaceDown);
      }
      return count > 0U ? R::success(count) : R::failure(error_from_errno(error_number));
    }
    if (got != static_cast<ssize_t>(sizeof raw)) {
      ++stats_.rx_ignored;  // CAN FD or truncated: not ours
      continue;
    }
    std::int64_t timestamp_us = 0;
    for (cmsghdr* header = CMSG_FIRSTHDR(&message); header != nullptr; header = CMSG_NXTHDR(&message, header)) {
      if (header->cmsg_level != SOL_SOCKET) {
        continue;
      }
      if (header->cmsg_type == SO_TIMESTAMP) {
        timeval stamp{};
        std::memcpy(&stamp, CMSG_DATA(header), sizeof stamp);
        timestamp_us = static_cast<std::int64_t>(stamp.tv_sec) * 1000000 + stamp.tv_usec;
      } else if (header->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t dropped = 0U;
        std::memcpy(&dropped, CMSG_DATA(header), sizeof dropped);
        stats_.rx_kernel_dropped = dropped;
      }
    }
    if ((raw.can_id & CAN_ERR_FLAG) != 0U) {
      handle_error_frame(raw.can_id, raw.data);
      continue;
    }
    if ((raw.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) != 0U || frame_length(raw) > can::kMaxDataLength) {
      ++stats_.rx_ignored;
      continue;
    }
    ReceivedFrame& slot = out[count];
    slot.frame = can::Frame{};
    slot.frame.id = raw.can_id & CAN_SFF_MASK;
    slot.frame.length = frame_length(raw);
    std::memcpy(slot.frame.data.data(), raw.data, slot.frame.length);
    slot.timestamp_us = timestamp_us;
    ++count;
    ++stats_.rx_frames;
  }
  return R::success(count);
}

}  // namespace hal
}  // namespace tcpest
