#include "tcpest/can_iface/emcy.hpp"

#include <array>

namespace tcpest {
namespace can {
namespace {

constexpr std::uint8_t kGeneric = kErrorRegisterGeneric;
constexpr std::uint8_t kComm = kErrorRegisterGeneric | kErrorRegisterCommunication;
constexpr std::uint8_t kManufacturer = kErrorRegisterGeneric | kErrorRegisterManufacturer;

// Indexed by fault id - 1. Codes from CiA 301 table 21 where one fits,
// 0xFFxx (device specific) for the estimator's own faults.
constexpr std::array<FaultInfo, kFaultCount> kFaults = {{
    {Fault::kCameraTimeout, 0xFF01U, kManufacturer, "camera_timeout"},
    {Fault::kImageCorrupt, 0xFF02U, kManufacturer, "image_corrupt"},
    {Fault::kTrackingLost, 0xFF03U, kManufacturer, "tracking_lost"},
    {Fault::kSolverFailed, 0xFF04U, kManufacturer, "solver_failed"},
    {Fault::kCycleOverrun, 0x6100U, kGeneric, "cycle_overrun"},
    {Fault::kConfigurationInvalid, 0x6300U, kGeneric, "configuration_invalid"},
    {Fault::kPriorTimeout, 0x8250U, kComm, "prior_timeout"},
    {Fault::kPriorE2eError, 0x8200U, kComm, "prior_e2e_error"},
    {Fault::kCanRxOverrun, 0x8110U, kComm, "can_rx_overrun"},
    {Fault::kCanErrorPassive, 0x8120U, kComm, "can_error_passive"},
    {Fault::kCanBusOffRecovered, 0x8140U, kComm, "can_bus_off_recovered"},
    {Fault::kCanTxDropped, 0x8100U, kComm, "can_tx_dropped"},
    {Fault::kInternalError, 0x6100U, kManufacturer, "internal_error"},
}};

}  // namespace

const FaultInfo* fault_info(Fault fault) noexcept {
  const auto id = static_cast<std::uint8_t>(fault);
  if (id < 1U || id > kFaultCount) {
    return nullptr;
  }
  return &kFaults[id - 1U];
}

const char* to_string(Fault fault) noexcept {
  const FaultInfo* info = fault_info(fault);
  return info != nullptr ? info->name : "unknown_fault";
}

}  // namespace can
}  // namespace tcpest
