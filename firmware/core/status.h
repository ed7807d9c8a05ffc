// Reply status codes of the control link (HTTP status codes, so the bridge can forward them as-is).
// The codes and reason words are generated from protocol/control/control_spec.json
// (rgbd_control/control_spec_generated.h); the firmware uses them under its own namespace.
#ifndef FIRMWARE_CORE_STATUS_H_
#define FIRMWARE_CORE_STATUS_H_

#include "rgbd_control/control_spec_generated.h"

namespace fw {

using Status = rgbd_control::Status;
using rgbd_control::status_reason;

}  // namespace fw

#endif  // FIRMWARE_CORE_STATUS_H_
