// Reads the APM's MAVLink telemetry byte stream and stores ATTITUDE and RAW_IMU in an ImuCache.
// Uses the C library generated at build time by pymavlink's mavgen (mavlink_subset.h, see
// firmware/tools/gen_mavlink.py) with caller-owned parse buffers (no static MAVLink state).
// Holds one mavlink_message_t (~290 B of RAM on the ATmega). Not thread-safe: main loop only.
#ifndef FIRMWARE_CORE_MAVLINK_IMU_READER_H_
#define FIRMWARE_CORE_MAVLINK_IMU_READER_H_

#include <stdint.h>

#include "imu_cache.h"
#include "mavlink_subset.h"

namespace fw {

class MavlinkImuReader {
 public:
  MavlinkImuReader();
  /// Feeds one telemetry byte received at now_ms; returns true when it completed a frame that
  /// updated `cache`.
  bool feed(uint8_t byte, uint32_t now_ms, ImuCache& cache);
  uint16_t frames_ok() const { return frames_ok_; }
  uint16_t frames_bad() const { return frames_bad_; }

 private:
  mavlink_message_t msg_;
  mavlink_status_t status_;
  uint16_t frames_ok_ = 0;
  uint16_t frames_bad_ = 0;
};

}  // namespace fw

#endif  // FIRMWARE_CORE_MAVLINK_IMU_READER_H_
