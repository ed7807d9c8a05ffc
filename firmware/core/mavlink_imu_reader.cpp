// MAVLink ATTITUDE / RAW_IMU reader; see mavlink_imu_reader.h.
#include "mavlink_imu_reader.h"

namespace fw {

MavlinkImuReader::MavlinkImuReader() : msg_(), status_() {}

bool MavlinkImuReader::feed(uint8_t byte, uint32_t now_ms, ImuCache& cache) {
  const uint8_t r = mavlink_frame_char_buffer(&msg_, &status_, byte, nullptr, nullptr);
  if (r == MAVLINK_FRAMING_INCOMPLETE) return false;
  if (r != MAVLINK_FRAMING_OK) {
    ++frames_bad_;
    return false;
  }
  ++frames_ok_;
  if (msg_.msgid == MAVLINK_MSG_ID_ATTITUDE) {
    mavlink_attitude_t a;
    mavlink_msg_attitude_decode(&msg_, &a);
    return cache.set_attitude_rad(a.roll, a.pitch, a.yaw, now_ms);
  }
  if (msg_.msgid == MAVLINK_MSG_ID_RAW_IMU) {
    mavlink_raw_imu_t m;
    mavlink_msg_raw_imu_decode(&msg_, &m);
    RawImuSample s;
    s.acc_raw[0] = m.xacc;
    s.acc_raw[1] = m.yacc;
    s.acc_raw[2] = m.zacc;
    s.gyro_raw[0] = m.xgyro;
    s.gyro_raw[1] = m.ygyro;
    s.gyro_raw[2] = m.zgyro;
    cache.set_raw_imu(s, now_ms);
    return true;
  }
  return false;
}

}  // namespace fw
