// Arming, failsafe, authentication and reply formatting; see controller.h.
#include "controller.h"

#include "failsafe.h"
#include "rgbd_control/siphash24.h"
#include "text_writer.h"

namespace fw {
namespace {

uint16_t clamp_u16(uint32_t v, uint16_t lo, uint16_t hi, bool* clamped) {
  if (v < lo) {
    *clamped = true;
    return lo;
  }
  if (v > hi) {
    *clamped = true;
    return hi;
  }
  return static_cast<uint16_t>(v);
}

void safe_outputs(uint16_t out_us[kChannelCount]) {
  out_us[kChRoll] = kNeutralUs;
  out_us[kChPitch] = kNeutralUs;
  out_us[kChThrottle] = kThrottleLowUs;
  out_us[kChYaw] = kNeutralUs;
}

}  // namespace

const char* arm_state_name(ArmState s) {
  switch (s) {
    case ArmState::kDisarmed:
      return "disarmed";
    case ArmState::kArmed:
      return "armed";
    case ArmState::kFailsafe:
      return "failsafe";
  }
  return "unknown";
}

Controller::Controller(const uint8_t* key, uint32_t seq_floor, SeqStore* seq_store)
    : last_seq_(seq_floor), seq_reserved_(seq_floor), seq_store_(seq_store) {
  for (size_t i = 0; i < kKeyBytes; ++i) key_[i] = key != nullptr ? key[i] : 0;
  has_key_ = key != nullptr;
  safe_outputs(command_us_);
}

Status Controller::apply_control(const ParsedRequest& r, uint32_t now_ms) {
  const bool arm = r.arm == 1;
  switch (state_) {
    case ArmState::kFailsafe:
      if (arm) return Status::kArmRefused;  // leaving failsafe needs disarm then a fresh arm
      state_ = ArmState::kDisarmed;
      break;
    case ArmState::kDisarmed:
      if (arm) {
        if (r.channel_us[kChThrottle] > kArmThrottleMaxUs) return Status::kArmRefused;
        state_ = ArmState::kArmed;
      }
      break;
    case ArmState::kArmed:
      if (!arm) state_ = ArmState::kDisarmed;
      break;
  }
  if (r.seq > seq_reserved_) {
    // Persist the reservation BEFORE applying, so a reset can never re-open this number.
    seq_reserved_ =
        r.seq > 0xFFFFFFFFUL - kSeqReserveCount ? 0xFFFFFFFFUL : r.seq + kSeqReserveCount;
    if (seq_store_ != nullptr) seq_store_->persist_seq_floor(seq_reserved_);
  }
  last_seq_ = r.seq;
  last_valid_ms_ = now_ms;
  clamped_mask_ = 0;
  if (state_ != ArmState::kArmed) {
    safe_outputs(command_us_);
    return Status::kOk;
  }
  bool c[kChannelCount] = {false, false, false, false};
  command_us_[kChRoll] = clamp_u16(r.channel_us[kChRoll], kRollMinUs, kRollMaxUs, &c[kChRoll]);
  command_us_[kChPitch] = clamp_u16(r.channel_us[kChPitch], kPitchMinUs, kPitchMaxUs, &c[kChPitch]);
  command_us_[kChThrottle] =
      clamp_u16(r.channel_us[kChThrottle], kThrottleMinUs, kThrottleMaxUs, &c[kChThrottle]);
  if (command_us_[kChThrottle] <= kGroundThrottleMaxUs) {
    command_us_[kChYaw] = clamp_u16(r.channel_us[kChYaw], kCommandMinUs, kCommandMaxUs, &c[kChYaw]);
  } else {
    command_us_[kChYaw] = clamp_u16(r.channel_us[kChYaw], kYawMinUs, kYawMaxUs, &c[kChYaw]);
  }
  for (uint8_t ch = 0; ch < kChannelCount; ++ch) {
    if (c[ch]) clamped_mask_ = static_cast<uint8_t>(clamped_mask_ | (1U << ch));
  }
  return Status::kOk;
}

size_t Controller::handle_line(const char* line, size_t len, uint32_t now_ms, const ImuCache& imu,
                               char* reply, size_t cap) {
  const ParsedRequest r = parse_request(line, len);
  Status status = r.status;
  if (status == Status::kOk && r.kind == RequestKind::kControl) {
    if (!has_key_) {
      status = Status::kNoKey;
    } else {
      uint8_t mac[rgbd_control::kSipHashTagBytes];
      rgbd_control::siphash24_tag_bytes(
          rgbd_control::siphash24(key_, reinterpret_cast<const uint8_t*>(line), r.signed_len), mac);
      uint8_t diff = 0;  // constant-time compare
      for (size_t i = 0; i < sizeof(mac); ++i)
        diff = static_cast<uint8_t>(diff | (mac[i] ^ r.mac[i]));
      if (diff != 0) {
        status = Status::kBadMac;
      } else if (r.value_overflow || r.seq <= last_seq_) {
        // An overflowing sequence number is by definition not a valid newer one.
        status = r.value_overflow && r.seq > last_seq_ ? Status::kOutOfRange : Status::kStaleSeq;
      } else {
        status = Status::kOk;
        if (r.arm > 1) status = Status::kOutOfRange;
        for (uint8_t ch = 0; ch < kChannelCount; ++ch) {
          if (r.channel_us[ch] < kCommandMinUs || r.channel_us[ch] > kCommandMaxUs) {
            status = Status::kOutOfRange;
          }
        }
        if (status == Status::kOk) status = apply_control(r, now_ms);
      }
    }
  }
  return write_reply(status, now_ms, imu, reply, cap);
}

size_t Controller::reply_error(Status status, uint32_t now_ms, const ImuCache& imu, char* reply,
                               size_t cap) const {
  return write_reply(status, now_ms, imu, reply, cap);
}

void Controller::update(uint32_t now_ms) {
  if (state_ != ArmState::kArmed) return;
  if (static_cast<uint32_t>(now_ms - last_valid_ms_) >= kFailsafeTimeoutMs) {
    state_ = ArmState::kFailsafe;
    failsafe_start_ms_ = last_valid_ms_ + kFailsafeTimeoutMs;
  }
}

void Controller::outputs_us(uint16_t out_us[kChannelCount]) const {
  switch (state_) {
    case ArmState::kDisarmed:
      safe_outputs(out_us);
      return;
    case ArmState::kArmed:
      for (uint8_t ch = 0; ch < kChannelCount; ++ch) out_us[ch] = command_us_[ch];
      return;
    case ArmState::kFailsafe:
      failsafe_outputs_us(out_us);
      return;
  }
}

size_t Controller::write_reply(Status status, uint32_t now_ms, const ImuCache& imu, char* reply,
                               size_t cap) const {
  TextWriter w(reply, cap);
  uint16_t out[kChannelCount];
  outputs_us(out);
  w.u32(static_cast<uint16_t>(status));
  w.str(" {\"ver\":" RGBD_CONTROL_LINK_VERSION_STRING ",\"err\":\"");
  w.str(status_reason(status));
  w.str("\",\"fw\":\"" FW_VERSION_STRING "\",\"state\":\"");
  w.str(arm_state_name(state_));
  w.str("\",\"seq\":");
  w.u32(last_seq_);
  w.str(",\"out_us\":[");
  for (uint8_t ch = 0; ch < kChannelCount; ++ch) {
    if (ch > 0) w.ch(',');
    w.u32(out[ch]);
  }
  w.str("],\"clamped\":");
  w.u32(clamped_mask_);
  const AttitudeSample& a = imu.attitude();
  w.str(",\"att_mrad\":[");
  w.i32(a.roll_mrad);
  w.ch(',');
  w.i32(a.pitch_mrad);
  w.ch(',');
  w.i32(a.yaw_mrad);
  w.str("],\"att_age_ms\":");
  if (imu.has_attitude()) {
    w.u32(imu.attitude_age_ms(now_ms));
  } else {
    w.str("null");
  }
  const RawImuSample& s = imu.raw_imu();
  w.str(",\"imu_raw\":[");
  for (int i = 0; i < 3; ++i) {
    w.i32(s.acc_raw[i]);
    w.ch(',');
  }
  for (int i = 0; i < 3; ++i) {
    if (i > 0) w.ch(',');
    w.i32(s.gyro_raw[i]);
  }
  w.str("],\"imu_age_ms\":");
  if (imu.has_raw_imu()) {
    w.u32(imu.raw_imu_age_ms(now_ms));
  } else {
    w.str("null");
  }
  w.str("}\n");
  return w.length();
}

}  // namespace fw
