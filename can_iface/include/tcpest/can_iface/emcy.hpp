// The estimator's faults and their CiA 301 emergency codes (the table is in
// docs/can-protocol.md). An EMCY is sent when a fault becomes active, and an
// "error reset" EMCY (code 0x0000) when it clears.
#pragma once

#include <cstdint>

namespace tcpest {
namespace can {

enum class Fault : std::uint8_t {
  kCameraTimeout = 1U,       // no image from the camera within its timeout
  kImageCorrupt = 2U,        // an image could not be decoded
  kTrackingLost = 3U,        // no estimate for the configured number of frames
  kSolverFailed = 4U,        // the pose solver did not converge / residual too large
  kCycleOverrun = 5U,        // a cycle missed its deadline
  kConfigurationInvalid = 6U,  // calibration or configuration rejected
  kPriorTimeout = 7U,        // ENCODER_PRIOR expected but stale
  kPriorE2eError = 8U,       // ENCODER_PRIOR failed CRC or counter checks
  kCanRxOverrun = 9U,        // received frames lost (kernel queue or per-cycle budget)
  kCanErrorPassive = 10U,    // the controller reports error passive / warning
  kCanBusOffRecovered = 11U,  // the controller went bus-off and recovered
  kCanTxDropped = 12U,       // frames dropped after the TX retries
  kInternalError = 13U,      // an internal check failed
};
constexpr std::uint8_t kFaultCount = 13U;  // ids 1..kFaultCount

// CiA 301 error register (object 0x1001) bits.
constexpr std::uint8_t kErrorRegisterGeneric = 0x01U;
constexpr std::uint8_t kErrorRegisterCommunication = 0x10U;
constexpr std::uint8_t kErrorRegisterManufacturer = 0x80U;

struct FaultInfo {
  Fault fault;
  std::uint16_t error_code;      // CiA 301 EMCY code
  std::uint8_t register_bits;    // set in the error register while active
  const char* name;
};

// Info for a fault; nullptr for an id outside the table.
const FaultInfo* fault_info(Fault fault) noexcept;
const char* to_string(Fault fault) noexcept;

}  // namespace can
}  // namespace tcpest
