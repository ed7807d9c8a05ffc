// The latest attitude (MAVLink ATTITUDE) and raw IMU (MAVLink RAW_IMU) reading from the APM, with
// the time each arrived, so every reply can carry the values and their age. Time is passed in. Not
// thread-safe: written and read from the main loop only.
#ifndef FIRMWARE_CORE_IMU_CACHE_H_
#define FIRMWARE_CORE_IMU_CACHE_H_

#include <stdint.h>

namespace fw {

struct AttitudeSample {
  int16_t roll_mrad = 0;   ///< body roll, milliradians (ATTITUDE.roll * 1000, rounded)
  int16_t pitch_mrad = 0;  ///< body pitch, milliradians
  int16_t yaw_mrad = 0;    ///< body yaw, milliradians, -3142..3142
};

struct RawImuSample {
  int16_t acc_raw[3] = {0, 0, 0};   ///< RAW_IMU x/y/z acceleration, sensor raw units (as sent)
  int16_t gyro_raw[3] = {0, 0, 0};  ///< RAW_IMU x/y/z angular rate, sensor raw units (as sent)
};

class ImuCache {
 public:
  /// Stores an ATTITUDE reading in radians; non-finite or |angle| > 4 rad is ignored (returns
  /// false).
  bool set_attitude_rad(float roll_rad, float pitch_rad, float yaw_rad, uint32_t now_ms);
  void set_raw_imu(const RawImuSample& s, uint32_t now_ms);

  bool has_attitude() const { return has_attitude_; }
  bool has_raw_imu() const { return has_raw_imu_; }
  const AttitudeSample& attitude() const { return attitude_; }
  const RawImuSample& raw_imu() const { return raw_imu_; }
  /// Age at now_ms of the latest reading (only meaningful when has_*()).
  uint32_t attitude_age_ms(uint32_t now_ms) const { return now_ms - attitude_ms_; }
  uint32_t raw_imu_age_ms(uint32_t now_ms) const { return now_ms - raw_imu_ms_; }

 private:
  AttitudeSample attitude_;
  RawImuSample raw_imu_;
  uint32_t attitude_ms_ = 0;
  uint32_t raw_imu_ms_ = 0;
  bool has_attitude_ = false;
  bool has_raw_imu_ = false;
};

}  // namespace fw

#endif  // FIRMWARE_CORE_IMU_CACHE_H_
