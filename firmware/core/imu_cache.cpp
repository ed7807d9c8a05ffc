// Latest-IMU cache; see imu_cache.h.
#include "imu_cache.h"

namespace fw {
namespace {

/// Largest accepted |angle|: a little above pi, which ATTITUDE never exceeds.
constexpr float kMaxAbsAngleRad = 4.0f;

bool valid_angle(float a) {
  // NaN fails both comparisons; +-inf fails the bound.
  return a >= -kMaxAbsAngleRad && a <= kMaxAbsAngleRad;
}

int16_t to_mrad(float rad) {
  const float m = rad * 1000.0f;
  return static_cast<int16_t>(m >= 0.0f ? m + 0.5f : m - 0.5f);
}

}  // namespace

bool ImuCache::set_attitude_rad(float roll_rad, float pitch_rad, float yaw_rad, uint32_t now_ms) {
  if (!valid_angle(roll_rad) || !valid_angle(pitch_rad) || !valid_angle(yaw_rad)) return false;
  attitude_.roll_mrad = to_mrad(roll_rad);
  attitude_.pitch_mrad = to_mrad(pitch_rad);
  attitude_.yaw_mrad = to_mrad(yaw_rad);
  attitude_ms_ = now_ms;
  has_attitude_ = true;
  return true;
}

void ImuCache::set_raw_imu(const RawImuSample& s, uint32_t now_ms) {
  raw_imu_ = s;
  raw_imu_ms_ = now_ms;
  has_raw_imu_ = true;
}

}  // namespace fw
