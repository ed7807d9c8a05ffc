// Table-driven unit tests of firmware/core: failsafe outputs, hard-limit clamping, the
// line assembler, the EEPROM key record, the IMU cache and MAVLink reader, reply bounds and the PWM
// schedule. GIVEN/WHEN/THEN in each table row's name; time is always passed in.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "controller.h"
#include "failsafe.h"
#include "imu_cache.h"
#include "key_store.h"
#include "line_assembler.h"
#include "mavlink_imu_reader.h"
#include "pwm_schedule.h"
#include "request_parser.h"
#include "rgbd_control/siphash24.h"
#include "seq_store.h"

namespace {

const uint8_t kKey[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};

std::string sign(const std::string& unsigned_line, const uint8_t* key = kKey) {
  uint8_t tag[8];
  rgbd_control::siphash24_tag_bytes(
      rgbd_control::siphash24(key, reinterpret_cast<const uint8_t*>(unsigned_line.data()),
                              unsigned_line.size()),
      tag);
  static const char* d = "0123456789abcdef";
  std::string s = unsigned_line + "&mac=";
  for (uint8_t b : tag) {
    s += d[b >> 4];
    s += d[b & 15];
  }
  return s;
}

std::string cmd(uint32_t seq, int arm, int roll, int pitch, int thr, int yaw) {
  return sign("PUT /control?seq=" + std::to_string(seq) + "&arm=" + std::to_string(arm) +
              "&roll=" + std::to_string(roll) + "&pitch=" + std::to_string(pitch) +
              "&thr=" + std::to_string(thr) + "&yaw=" + std::to_string(yaw));
}

int send(fw::Controller& c, const std::string& line, uint32_t now_ms) {
  fw::ImuCache imu;
  char reply[fw::kReplyBufferBytes];
  c.handle_line(line.data(), line.size(), now_ms, imu, reply, sizeof(reply));
  return std::atoi(reply);
}

// ---- failsafe outputs
// -------------------------------------------------------------------------------
struct FailsafeRow {
  const char* name;
  int roll, pitch, thr, yaw;  ///< last valid command before the link went silent
};

TEST(FailsafeOutputs, StepToNeutralAndBelowFsThrValueAtTheEngageInstantForEveryLastCommand) {
  // GIVEN an armed craft whose last valid command (at 1000 ms) is any of these
  const FailsafeRow rows[] = {
      {"hover", 1500, 1500, 1500, 1500},
      {"climbing at the throttle ceiling, leaning", 1750, 1250, 1750, 1250},
      {"descending, AltHold dead band edge", 1500, 1500, 1399, 1500},
      {"low throttle near the ground", 1500, 1500, 1100, 1500},
      {"on the ground, throttle fully down", 1500, 1500, 1000, 1500},
  };
  const uint16_t fs[4] = {1500, 1500, 950, 1500};
  for (const auto& r : rows) {
    fw::Controller c(kKey);
    ASSERT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), 990), 200) << r.name;
    ASSERT_EQ(send(c, cmd(2, 1, r.roll, r.pitch, r.thr, r.yaw), 1000), 200) << r.name;
    uint16_t out[4];
    // WHEN time passes without a valid command
    // THEN the last command is output until 1249 ms
    c.update(1249);
    c.outputs_us(out);
    EXPECT_EQ(out[fw::kChThrottle], r.thr) << r.name;
    EXPECT_EQ(out[fw::kChRoll], r.roll) << r.name;
    // AND from the engage instant (1250 ms) on: neutral sticks and the failsafe throttle at once,
    // no ramp (any throttle above FS_THR_VALUE on the way down would be flown by the APM)
    for (uint32_t t : {1250u, 1251u, 1310u, 5000u, 3601250u}) {
      c.update(t);
      c.outputs_us(out);
      for (int ch = 0; ch < 4; ++ch)
        EXPECT_EQ(out[ch], fs[ch]) << r.name << " @" << t << " ch" << ch + 1;
    }
  }
}

TEST(FailsafeOutputs, ThrottleIsBelowFsThrValueAndAValidPulseAndGroundThrottleIsNot) {
  // The hand-over contract with ArduCopter's radio failsafe (limits.h, docs/failsafe.md).
  uint16_t out[4];
  fw::failsafe_outputs_us(out);
  EXPECT_LT(out[fw::kChThrottle], fw::kApmFsThrValueUs);
  EXPECT_GT(out[fw::kChThrottle], fw::kApmRcPulseMinValidUs);
  EXPECT_GT(fw::kThrottleLowUs, fw::kApmFsThrValueUs);  // disarmed/on the ground: no failsafe
  EXPECT_GT(fw::kThrottleMinUs, fw::kApmFsThrValueUs);  // no command can trigger it by accident
  EXPECT_EQ(fw::kApmLandHandoverMs, 60u);
}

TEST(Failsafe, EngagesExactlyAtTimeoutAfterLastValidCommand) {
  // GIVEN an armed controller whose last valid command was at 1000 ms
  fw::Controller c(kKey);
  ASSERT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), 990), 200);
  ASSERT_EQ(send(c, cmd(2, 1, 1500, 1500, 1500, 1500), 1000), 200);
  // WHEN time passes THEN it stays armed until 1249 ms and is in failsafe at 1250 ms
  c.update(1249);
  EXPECT_EQ(c.state(), fw::ArmState::kArmed);
  c.update(1250);
  EXPECT_EQ(c.state(), fw::ArmState::kFailsafe);
  EXPECT_EQ(c.failsafe_start_ms(), 1250u);
}

TEST(Failsafe, EngageTimeIsTheDeadlineEvenWhenUpdateRunsLate) {
  fw::Controller c(kKey);
  ASSERT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), 0), 200);
  ASSERT_EQ(send(c, cmd(2, 1, 1500, 1500, 1500, 1500), 10), 200);
  c.update(300);  // main loop was busy
  ASSERT_EQ(c.state(), fw::ArmState::kFailsafe);
  uint16_t out[4];
  c.outputs_us(out);
  EXPECT_EQ(out[fw::kChThrottle], fw::kFailsafeThrottleUs);
  EXPECT_EQ(c.failsafe_start_ms(), 260u);
}

TEST(Failsafe, SurvivesClockWrap) {
  fw::Controller c(kKey);
  const uint32_t t0 = 0xFFFFFF00u;
  ASSERT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), t0), 200);
  c.update(t0 + 249);
  EXPECT_EQ(c.state(), fw::ArmState::kArmed);
  c.update(t0 + 250);  // wrapped past zero
  EXPECT_EQ(c.state(), fw::ArmState::kFailsafe);
}

// ---- arming and clamping
// ----------------------------------------------------------------------------
struct ClampRow {
  const char* name;
  int roll, pitch, thr, yaw;
  uint16_t want[4];
  uint8_t want_mask;
};

TEST(Limits, ClampTable) {
  const ClampRow rows[] = {
      {"centre passes", 1500, 1500, 1500, 1500, {1500, 1500, 1500, 1500}, 0},
      {"roll high clamps", 2000, 1500, 1500, 1500, {1750, 1500, 1500, 1500}, 1},
      {"roll low clamps", 1000, 1500, 1500, 1500, {1250, 1500, 1500, 1500}, 1},
      {"pitch edges pass", 1500, 1250, 1500, 1500, {1500, 1250, 1500, 1500}, 0},
      {"pitch high clamps", 1500, 1751, 1500, 1500, {1500, 1750, 1500, 1500}, 2},
      {"throttle ceiling", 1500, 1500, 2000, 1500, {1500, 1500, 1750, 1500}, 4},
      {"throttle floor passes", 1500, 1500, 1000, 1500, {1500, 1500, 1000, 1500}, 0},
      {"yaw clamps when flying", 1500, 1500, 1101, 2000, {1500, 1500, 1101, 1750}, 8},
      {"yaw full range on ground (gesture)", 1500, 1500, 1100, 2000, {1500, 1500, 1100, 2000}, 0},
      {"yaw full left on ground", 1500, 1500, 1000, 1000, {1500, 1500, 1000, 1000}, 0},
      {"yaw limit uses clamped throttle", 1500, 1500, 2000, 1000, {1500, 1500, 1750, 1250}, 12},
      {"all clamp", 1000, 2000, 2000, 2000, {1250, 1750, 1750, 1750}, 15},
  };
  for (const auto& r : rows) {
    fw::Controller c(kKey);
    ASSERT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), 0), 200) << r.name;
    ASSERT_EQ(send(c, cmd(2, 1, r.roll, r.pitch, r.thr, r.yaw), 1), 200) << r.name;
    uint16_t out[4];
    c.outputs_us(out);
    for (int ch = 0; ch < 4; ++ch) EXPECT_EQ(out[ch], r.want[ch]) << r.name << " ch" << ch + 1;
    EXPECT_EQ(c.clamped_mask(), r.want_mask) << r.name;
  }
}

struct ArmRow {
  const char* name;
  fw::ArmState from;
  int arm;
  int thr;
  int want_status;
  fw::ArmState to;
};

void drive_to(fw::Controller& c, fw::ArmState s, uint32_t* seq, uint32_t* t) {
  if (s == fw::ArmState::kDisarmed) return;
  ASSERT_EQ(send(c, cmd((*seq)++, 1, 1500, 1500, 1000, 1500), (*t)++), 200);
  if (s == fw::ArmState::kFailsafe) {
    *t += 1000;
    c.update(*t);
    ASSERT_EQ(c.state(), fw::ArmState::kFailsafe);
  }
}

TEST(Arming, TransitionTable) {
  using S = fw::ArmState;
  const ArmRow rows[] = {
      {"disarmed + arm, throttle low -> armed", S::kDisarmed, 1, 1000, 200, S::kArmed},
      {"disarmed + arm, throttle at limit -> armed", S::kDisarmed, 1, 1100, 200, S::kArmed},
      {"disarmed + arm, throttle high -> refused", S::kDisarmed, 1, 1101, 403, S::kDisarmed},
      {"disarmed + disarm -> disarmed", S::kDisarmed, 0, 1800, 200, S::kDisarmed},
      {"armed + arm -> armed", S::kArmed, 1, 1600, 200, S::kArmed},
      {"armed + disarm -> disarmed", S::kArmed, 0, 1600, 200, S::kDisarmed},
      {"failsafe + arm -> refused, stays", S::kFailsafe, 1, 1000, 403, S::kFailsafe},
      {"failsafe + disarm -> disarmed", S::kFailsafe, 0, 1000, 200, S::kDisarmed},
  };
  for (const auto& r : rows) {
    fw::Controller c(kKey);
    uint32_t seq = 1;
    uint32_t t = 0;
    drive_to(c, r.from, &seq, &t);
    EXPECT_EQ(send(c, cmd(seq, r.arm, 1500, 1500, r.thr, 1500), t), r.want_status) << r.name;
    EXPECT_EQ(c.state(), r.to) << r.name;
    uint16_t out[4];
    c.outputs_us(out);
    if (r.to == S::kDisarmed) {
      EXPECT_EQ(out[fw::kChThrottle], fw::kThrottleLowUs) << r.name;
      EXPECT_EQ(out[fw::kChRoll], fw::kNeutralUs) << r.name;
    }
  }
}

// ---- authentication
// -----------------------------------------------------------------------------------
TEST(Auth, ReplayOldSeqForgedAndWrongKeyAreRejectedAndChangeNothing) {
  fw::Controller c(kKey);
  ASSERT_EQ(send(c, cmd(10, 1, 1500, 1500, 1000, 1500), 0), 200);
  ASSERT_EQ(send(c, cmd(11, 1, 1600, 1500, 1400, 1500), 5), 200);
  const uint8_t other[16] = {16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31};
  std::string forged = cmd(12, 1, 1500, 1500, 1400, 1500);
  forged.replace(forged.find("thr=1400"), 8, "thr=1700");
  std::string flipped = cmd(12, 1, 1500, 1500, 1400, 1500);
  flipped.back() = flipped.back() == '0' ? '1' : '0';
  const struct {
    const char* name;
    std::string line;
    int want;
  } rows[] = {
      {"exact replay", cmd(11, 1, 1600, 1500, 1400, 1500), 409},
      {"older seq", cmd(3, 1, 1700, 1500, 1700, 1500), 409},
      {"forged field", forged, 401},
      {"one MAC bit flipped", flipped, 401},
      {"other craft's key",
       sign("PUT /control?seq=12&arm=1&roll=1500&pitch=1500&thr=1700&yaw=1500", other), 401},
  };
  for (const auto& r : rows) {
    EXPECT_EQ(send(c, r.line, 100), r.want) << r.name;
    EXPECT_EQ(c.last_seq(), 11u) << r.name;
    uint16_t out[4];
    c.outputs_us(out);
    EXPECT_EQ(out[fw::kChRoll], 1600) << r.name;
    EXPECT_EQ(out[fw::kChThrottle], 1400) << r.name;
  }
  // Rejected commands did not feed the timer: failsafe 250 ms after the last valid one (5 ms).
  c.update(254);
  EXPECT_EQ(c.state(), fw::ArmState::kArmed);
  c.update(255);
  EXPECT_EQ(c.state(), fw::ArmState::kFailsafe);
}

TEST(Auth, NoKeyRefusesEverything) {
  fw::Controller c(nullptr);
  EXPECT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), 0), 503);
  EXPECT_EQ(c.state(), fw::ArmState::kDisarmed);
}

// ---- parser details
// -----------------------------------------------------------------------------------
TEST(Parser, ReadsNoByteBeyondLength) {
  // GIVEN a valid line followed by garbage in the same buffer, WHEN parsed with the exact length,
  // THEN it is valid; with any shorter length it is rejected (never reads past len).
  const std::string line = cmd(1, 1, 1500, 1500, 1000, 1500);
  const std::string buf = line + "GARBAGE";
  EXPECT_EQ(fw::parse_request(buf.data(), line.size()).status, fw::Status::kOk);
  for (size_t n = 0; n < line.size(); ++n) {
    EXPECT_NE(fw::parse_request(line.data(), n).status, fw::Status::kOk) << n;
  }
}

TEST(Parser, SaturatesOverflowingValues) {
  const std::string line =
      "PUT "
      "/control?seq=4294967296&arm=1&roll=9999999999&pitch=1500&thr=1000&yaw=1500&mac="
      "0000000000000000";
  const fw::ParsedRequest r = fw::parse_request(line.data(), line.size());
  EXPECT_EQ(r.status, fw::Status::kOk);
  EXPECT_TRUE(r.value_overflow);
  EXPECT_EQ(r.seq, 0xFFFFFFFFu);
}

// ---- line assembler
// -------------------------------------------------------------------------------------
TEST(LineAssembler, LinesOverlongAndStall) {
  fw::LineAssembler a;
  const std::string l = "GET /status\r\n";
  fw::LineEvent ev = fw::LineEvent::kNone;
  for (char ch : l) ev = a.feed(static_cast<uint8_t>(ch), 0);
  ASSERT_EQ(ev, fw::LineEvent::kLine);
  EXPECT_EQ(std::string(a.line(), a.length()), "GET /status");
  // Exactly kMaxRequestBytes is accepted; one more is too long.
  for (size_t n : {size_t{fw::kMaxRequestBytes}, size_t{fw::kMaxRequestBytes} + 1, size_t{1000}}) {
    std::vector<fw::LineEvent> events;
    for (size_t i = 0; i < n; ++i) {
      ev = a.feed('A', 1);
      if (ev != fw::LineEvent::kNone) events.push_back(ev);
    }
    ev = a.feed('\n', 1);
    if (ev != fw::LineEvent::kNone) events.push_back(ev);
    ASSERT_EQ(events.size(), 1u) << n;
    EXPECT_EQ(events[0], n <= fw::kMaxRequestBytes ? fw::LineEvent::kLine : fw::LineEvent::kTooLong)
        << n;
  }
  // A partial line stalls kLineStallTimeoutMs after its last byte.
  a.feed('P', 100);
  a.feed('U', 150);
  EXPECT_EQ(a.poll(249), fw::LineEvent::kNone);
  EXPECT_EQ(a.poll(250), fw::LineEvent::kStalled);
  EXPECT_EQ(a.poll(400), fw::LineEvent::kNone);  // reported once
  for (char ch : l) ev = a.feed(static_cast<uint8_t>(ch), 401);
  ASSERT_EQ(ev, fw::LineEvent::kLine);
  EXPECT_EQ(std::string(a.line(), a.length()), "GET /status");
}

struct OverlongRow {
  const char* name;
  size_t bytes;          ///< line length without the newline
  uint32_t byte_gap_us;  ///< time between bytes (20 us = 500 kbaud back to back; the link runs 1
                         ///< Mbaud, 10 us)
  bool newline;          ///< false: the newline was lost in transit
};

TEST(LineAssembler, OverlongLineIsAnswered414OnItsFirstExcessByteWhateverItsLengthOrPace) {
  // Regression: the 414 used to wait for the newline, and the stall timer counted from the first
  // byte, so a long or slow over-long line - or one whose newline was lost - got a 408 instead (and
  // the rest of it then counted as a new line: two replies for one line).
  const OverlongRow rows[] = {
      {"132 B at line rate", 132, 20, true},
      {"272 B at line rate", 272, 20, true},
      {"312 B at line rate", 312, 20, true},
      {"612 B at line rate", 612, 20, true},
      {"272 B, newline lost", 272, 20, false},
      {"20000 B: 400 ms of back-to-back bytes", 20000, 20, true},
      {"300 B trickled over 1.5 s (5 ms apart)", 300, 5000, true},
  };
  for (const auto& r : rows) {
    fw::LineAssembler a;
    std::vector<std::pair<fw::LineEvent, size_t>> events;  // (event, byte index)
    const uint32_t t0_us = 1000000;
    uint32_t t_us = t0_us;
    for (size_t i = 0; i <= r.bytes; ++i) {
      if (i == r.bytes && !r.newline) break;
      t_us = t0_us + static_cast<uint32_t>(i) * r.byte_gap_us;
      const fw::LineEvent ev = a.feed(i == r.bytes ? '\n' : 'X', t_us / 1000);
      if (ev != fw::LineEvent::kNone) events.push_back({ev, i});
      const fw::LineEvent p = a.poll(t_us / 1000);
      if (p != fw::LineEvent::kNone) events.push_back({p, i});
    }
    // WHEN the link then stays quiet for a while
    for (uint32_t ms = t_us / 1000; ms < t_us / 1000 + 500; ++ms) {
      const fw::LineEvent p = a.poll(ms);
      if (p != fw::LineEvent::kNone) events.push_back({p, r.bytes + 1});
    }
    // THEN exactly one event: kTooLong, on the first byte past kMaxRequestBytes
    ASSERT_EQ(events.size(), 1u) << r.name;
    EXPECT_EQ(events[0].first, fw::LineEvent::kTooLong) << r.name;
    EXPECT_EQ(events[0].second, size_t{fw::kMaxRequestBytes}) << r.name;
    EXPECT_FALSE(a.discarding()) << r.name;
    // AND the next line is assembled normally
    fw::LineEvent ev = fw::LineEvent::kNone;
    for (char ch : std::string("GET /status\n"))
      ev = a.feed(static_cast<uint8_t>(ch), t_us / 1000 + 600);
    ASSERT_EQ(ev, fw::LineEvent::kLine) << r.name;
    EXPECT_EQ(std::string(a.line(), a.length()), "GET /status") << r.name;
  }
}

TEST(LineAssembler, DiscardingCoversExactlyTheRestOfTheOverlongLine) {
  fw::LineAssembler a;
  for (size_t i = 0; i < fw::kMaxRequestBytes; ++i) ASSERT_EQ(a.feed('X', 0), fw::LineEvent::kNone);
  EXPECT_FALSE(a.discarding());
  EXPECT_EQ(a.feed('X', 0), fw::LineEvent::kTooLong);
  EXPECT_TRUE(a.discarding());
  EXPECT_EQ(a.feed('\r', 0), fw::LineEvent::kNone);
  EXPECT_EQ(a.feed('\n', 0), fw::LineEvent::kNone);
  EXPECT_FALSE(a.discarding());  // a caller draining while discarding() stops right here
}

TEST(LineAssembler, SlowButSteadyLineIsNotStalled) {
  // A valid line whose bytes come 50 ms apart (total > kLineStallTimeoutMs) is not cut: the stall
  // timer measures silence, not line duration.
  fw::LineAssembler a;
  const std::string l = "GET /status\n";
  fw::LineEvent ev = fw::LineEvent::kNone;
  for (size_t i = 0; i < l.size(); ++i) {
    const uint32_t t = static_cast<uint32_t>(i) * 50;
    ev = a.feed(static_cast<uint8_t>(l[i]), t);
    if (i + 1 < l.size()) {
      ASSERT_EQ(a.poll(t + 49), fw::LineEvent::kNone) << i;
    }
  }
  ASSERT_EQ(ev, fw::LineEvent::kLine);
  EXPECT_EQ(std::string(a.line(), a.length()), "GET /status");
}

// ---- key store
// -------------------------------------------------------------------------------------------
TEST(KeyStore, RecordRoundTripAndCorruption) {
  const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(fw::crc16_ccitt(check, sizeof(check)), 0x29B1);
  uint8_t rec[fw::kKeyRecordBytes];
  fw::make_key_record(kKey, rec);
  uint8_t key[16] = {};
  ASSERT_TRUE(fw::load_key_record(rec, key));
  EXPECT_EQ(0, memcmp(key, kKey, 16));
  for (size_t i = 0; i < sizeof(rec); ++i) {
    uint8_t bad[fw::kKeyRecordBytes];
    memcpy(bad, rec, sizeof(rec));
    bad[i] ^= 0x01;
    EXPECT_FALSE(fw::load_key_record(bad, key)) << "corrupt byte " << i;
  }
  uint8_t erased[fw::kKeyRecordBytes];
  memset(erased, 0xFF, sizeof(erased));
  EXPECT_FALSE(fw::load_key_record(erased, key));
  const uint8_t zero[16] = {};
  fw::make_key_record(zero, rec);
  EXPECT_FALSE(fw::load_key_record(rec, key)) << "all-zero key";
}

// ---- IMU cache, MAVLink reader, replies
// ------------------------------------------------------------------
TEST(ImuCache, RejectsNonFiniteAndReportsAge) {
  fw::ImuCache c;
  EXPECT_FALSE(c.has_attitude());
  EXPECT_FALSE(c.set_attitude_rad(NAN, 0, 0, 10));
  EXPECT_FALSE(c.set_attitude_rad(0, INFINITY, 0, 10));
  EXPECT_FALSE(c.set_attitude_rad(0, 0, 5.0f, 10));
  EXPECT_FALSE(c.has_attitude());
  EXPECT_TRUE(c.set_attitude_rad(0.1234f, -0.5f, 3.1415926f, 10));
  EXPECT_EQ(c.attitude().roll_mrad, 123);
  EXPECT_EQ(c.attitude().pitch_mrad, -500);
  EXPECT_EQ(c.attitude().yaw_mrad, 3142);
  EXPECT_EQ(c.attitude_age_ms(35), 25u);
}

std::vector<uint8_t> frame_bytes(const mavlink_message_t& m) {
  uint8_t buf[MAVLINK_MAX_PACKET_LEN];
  const uint16_t n = mavlink_msg_to_send_buffer(buf, &m);
  return std::vector<uint8_t>(buf, buf + n);
}

TEST(MavlinkImuReader, DecodesAttitudeAndRawImuAndRejectsCorruptFrames) {
  fw::MavlinkImuReader reader;
  fw::ImuCache cache;
  mavlink_message_t m;
  mavlink_msg_attitude_pack(1, 1, &m, 1234, 0.25f, -0.125f, 1.5f, 0.0f, 0.0f, 0.0f);
  std::vector<uint8_t> att = frame_bytes(m);
  mavlink_msg_raw_imu_pack(1, 1, &m, 5678, 10, -20, -1000, 1, 2, -3, 0, 0, 0, 0, 25);
  std::vector<uint8_t> imu = frame_bytes(m);
  mavlink_msg_scaled_pressure_pack(1, 1, &m, 1, 1013.0f, 0.0f, 2000, 0);  // not in the subset
  std::vector<uint8_t> other = frame_bytes(m);
  // A corrupted ATTITUDE (one payload bit flipped) must not reach the cache.
  std::vector<uint8_t> bad = att;
  bad[12] ^= 0x40;
  for (uint8_t b : bad) reader.feed(b, 5, cache);
  for (uint8_t b : other) reader.feed(b, 6, cache);
  EXPECT_FALSE(cache.has_attitude());
  for (uint8_t b : att) reader.feed(b, 7, cache);
  for (uint8_t b : imu) reader.feed(b, 8, cache);
  ASSERT_TRUE(cache.has_attitude());
  ASSERT_TRUE(cache.has_raw_imu());
  EXPECT_EQ(cache.attitude().roll_mrad, 250);
  EXPECT_EQ(cache.attitude().pitch_mrad, -125);
  EXPECT_EQ(cache.attitude().yaw_mrad, 1500);
  EXPECT_EQ(cache.raw_imu().acc_raw[2], -1000);
  EXPECT_EQ(cache.raw_imu().gyro_raw[2], -3);
  EXPECT_EQ(reader.frames_ok(), 2u);
  EXPECT_GE(reader.frames_bad(), 1u);
}

TEST(Reply, WorstCaseFitsBufferAndCarriesImu) {
  fw::Controller c(kKey);
  ASSERT_EQ(send(c, cmd(0xFFFFFFFE, 1, 1500, 1500, 1000, 1500), 0), 200);
  fw::ImuCache imu;
  imu.set_attitude_rad(-3.1415f, -3.1415f, -3.1415f, 0);
  fw::RawImuSample s;
  for (int i = 0; i < 3; ++i) {
    s.acc_raw[i] = -32768;
    s.gyro_raw[i] = -32768;
  }
  imu.set_raw_imu(s, 0);
  char reply[fw::kReplyBufferBytes];
  const size_t n = c.reply_error(fw::Status::kOutOfRange, 0xFFFFFFFFu, imu, reply, sizeof(reply));
  ASSERT_GT(n, 0u);
  EXPECT_LT(n, sizeof(reply) - 1);
  EXPECT_EQ(reply[n - 1], '\n');
  const std::string r(reply, n);
  EXPECT_NE(r.find("\"att_mrad\":[-3142,-3142,-3142]"), std::string::npos) << r;
  EXPECT_NE(r.find("\"imu_raw\":[-32768,-32768,-32768,-32768,-32768,-32768]"), std::string::npos)
      << r;
  EXPECT_NE(r.find("\"att_age_ms\":4294967295"), std::string::npos) << r;
  // The control-link schema version comes first (control_spec.json), and the line keeps the spec's
  // bound that ground stations size their buffers from.
  EXPECT_EQ(r.rfind("422 {\"ver\":" + std::to_string(rgbd_control::kControlLinkVersion) + ",", 0),
            0u)
      << r;
  EXPECT_LE(n - 1, rgbd_control::kMaxReplyBytes);
  std::printf("worst-case reply: %zu bytes\n", n);
}

TEST(Reply, TruncatesSafelyInASmallBuffer) {
  fw::Controller c(kKey);
  fw::ImuCache imu;
  char small[16];
  memset(small, 'Z', sizeof(small));
  const size_t n = c.reply_error(fw::Status::kMalformed, 0, imu, small, 10);
  EXPECT_EQ(n, 9u);
  EXPECT_EQ(small[9], '\0');
  EXPECT_EQ(small[10], 'Z');
}

// ---- PWM schedule
// -----------------------------------------------------------------------------------------
TEST(PwmSchedule, FrameIs20msAndPulsesAreBounded) {
  const struct {
    uint16_t in[4];
    uint16_t want_ticks[5];
  } rows[] = {
      {{1500, 1500, 1000, 1500}, {3000, 3000, 2000, 3000, 29000}},
      {{1000, 2000, 950, 1750}, {2000, 4000, 1900, 3500, 28600}},
      {{0, 65535, 899, 2101}, {1800, 4200, 1800, 4200, 28000}},
  };
  for (const auto& r : rows) {
    uint16_t ticks[5];
    fw::make_pwm_schedule(r.in, ticks);
    uint32_t total = 0;
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(ticks[i], r.want_ticks[i]) << i;
      total += ticks[i];
    }
    EXPECT_EQ(total, 40000u);
  }
}

}  // namespace

// ---- robustness
// -------------------------------------------------------------------------------------------
namespace {

/// Deterministic xorshift32 (seeded): the same byte streams on every run.
class Rng {
 public:
  explicit Rng(uint32_t seed) : s_(seed) {}
  uint32_t next() {
    s_ ^= s_ << 13;
    s_ ^= s_ >> 17;
    s_ ^= s_ << 5;
    return s_;
  }

 private:
  uint32_t s_;
};

}  // namespace

TEST(Robustness, MutatedAndRandomStreamsNeverApplyAnythingOrOverflow) {
  // GIVEN an armed controller holding a known command, WHEN 20000 mutated copies of valid lines and
  // random byte runs (seeded) arrive through the line assembler, THEN no reply overflows its
  // buffer, every reply is a complete line, and none of them is a 200 for a control request (a
  // mutation cannot carry a valid MAC) - checked under ASan/UBSan in build-asan as well.
  fw::Controller c(kKey);
  fw::LineAssembler a;
  fw::ImuCache imu;
  ASSERT_EQ(send(c, cmd(1, 1, 1500, 1500, 1000, 1500), 0), 200);
  ASSERT_EQ(send(c, cmd(2, 1, 1600, 1400, 1300, 1500), 1), 200);
  Rng rng(12345);
  const std::string base = cmd(3, 1, 1700, 1300, 1700, 1700);
  uint32_t t = 2;
  int replies = 0;
  for (int iter = 0; iter < 20000; ++iter) {
    std::string s;
    if (iter % 2 == 0) {
      s = base;
      const int edits = 1 + static_cast<int>(rng.next() % 3);
      for (int e = 0; e < edits; ++e) {
        const size_t pos = rng.next() % s.size();
        switch (rng.next() % 3) {
          case 0:
            s[pos] = static_cast<char>(rng.next() & 0xFF);
            break;
          case 1:
            s.erase(pos, 1 + rng.next() % 4);
            break;
          default:
            s.insert(pos, 1, static_cast<char>(rng.next() & 0xFF));
            break;
        }
        if (s.empty()) s = "x";
      }
      s += '\n';
    } else {
      const size_t n = rng.next() % 300;
      for (size_t i = 0; i < n; ++i) s += static_cast<char>(rng.next() & 0xFF);
    }
    for (char b : s) {
      const fw::LineEvent ev = a.feed(static_cast<uint8_t>(b), t);
      char reply[fw::kReplyBufferBytes];
      size_t len = 0;
      if (ev == fw::LineEvent::kLine) {
        len = c.handle_line(a.line(), a.length(), t, imu, reply, sizeof(reply));
        const std::string line(a.line(), a.length());
        if (line.rfind("PUT ", 0) == 0) {
          ASSERT_NE(std::atoi(reply), 200) << line;
        }
      } else if (ev == fw::LineEvent::kTooLong) {
        len = c.reply_error(fw::Status::kTooLong, t, imu, reply, sizeof(reply));
      } else {
        continue;
      }
      ++replies;
      ASSERT_GT(len, 0u);
      ASSERT_LT(len, sizeof(reply));
      ASSERT_EQ(reply[len - 1], '\n');
    }
    c.update(t);  // time stands still: the failsafe must not engage, and nothing may change outputs
  }
  uint16_t out[4];
  c.outputs_us(out);
  EXPECT_EQ(c.state(), fw::ArmState::kArmed);
  EXPECT_EQ(c.last_seq(), 2u);
  EXPECT_EQ(out[fw::kChRoll], 1600);
  EXPECT_EQ(out[fw::kChThrottle], 1300);
  EXPECT_GT(replies, 10000);
}

// ---- replay protection across resets
// ------------------------------------------------------------------------
namespace {

/// EEPROM stand-in: two slots, records every write.
class FakeSeqStore final : public fw::SeqStore {
 public:
  FakeSeqStore() {
    for (auto& b : slots) b = 0xFF;  // erased EEPROM
  }
  void persist_seq_floor(uint32_t floor) override {
    fw::encode_seq_slot(floor, slots + fw::seq_slot_to_write(slots) * fw::kSeqSlotBytes);
    ++writes;
  }
  uint8_t slots[fw::kSeqSlotsBytes];
  int writes = 0;
};

}  // namespace

TEST(SeqStore, ReplayAfterResetIsRejectedAndGroundStationResyncs) {
  FakeSeqStore store;
  ASSERT_EQ(fw::load_seq_floor(store.slots), 0u);
  const std::string recorded_arm = cmd(5, 1, 1500, 1500, 1000, 1500);
  {
    // GIVEN a craft that accepted seq 5..7 before a reset
    fw::Controller c(kKey, fw::load_seq_floor(store.slots), &store);
    ASSERT_EQ(send(c, recorded_arm, 0), 200);
    ASSERT_EQ(send(c, cmd(6, 1, 1500, 1500, 1200, 1500), 10), 200);
    ASSERT_EQ(send(c, cmd(7, 1, 1500, 1500, 1200, 1500), 20), 200);
    EXPECT_EQ(store.writes, 1) << "one EEPROM write per kSeqReserveCount numbers";
  }
  // WHEN it reboots and an attacker replays the recorded arm command (or a later one)
  fw::Controller rebooted(kKey, fw::load_seq_floor(store.slots), &store);
  EXPECT_EQ(send(rebooted, recorded_arm, 0), 409);
  EXPECT_EQ(send(rebooted, cmd(8, 1, 1500, 1500, 1000, 1500), 0), 409);
  EXPECT_EQ(rebooted.state(), fw::ArmState::kDisarmed);
  // THEN the ground station resumes after the seq its 409 reply reports
  EXPECT_EQ(rebooted.last_seq(), 5u + fw::kSeqReserveCount);
  EXPECT_EQ(send(rebooted, cmd(rebooted.last_seq() + 1, 1, 1500, 1500, 1000, 1500), 1), 200);
  EXPECT_EQ(store.writes, 2);
}

TEST(SeqStore, ReservationIsWrittenOncePerWindowAndBeforeItIsUsed) {
  FakeSeqStore store;
  fw::Controller c(kKey, 0, &store);
  uint32_t seq = 1;
  for (int i = 0; i < 300; ++i, seq += 1000) {
    ASSERT_EQ(send(c, cmd(seq, 0, 1500, 1500, 1000, 1500), static_cast<uint32_t>(i)), 200);
    ASSERT_GE(fw::load_seq_floor(store.slots), seq)
        << "accepted a number not yet covered in EEPROM";
  }
  EXPECT_EQ(store.writes, 5);  // 299001 / 65536 -> windows starting at 1, 65537+.., ...
}

TEST(SeqStore, SlotsSurviveATornWriteAndSaturate) {
  uint8_t slots[fw::kSeqSlotsBytes];
  for (auto& b : slots) b = 0xFF;
  EXPECT_EQ(fw::load_seq_floor(slots), 0u);
  EXPECT_EQ(fw::seq_slot_to_write(slots), 0);
  fw::encode_seq_slot(70000, slots);
  EXPECT_EQ(fw::seq_slot_to_write(slots), 1);
  fw::encode_seq_slot(140000, slots + 8);
  EXPECT_EQ(fw::load_seq_floor(slots), 140000u);
  EXPECT_EQ(fw::seq_slot_to_write(slots), 0);
  // A write of 210000 into slot 0 torn after 3 bytes: slot 0 invalid, slot 1 still covers.
  uint8_t next[8];
  fw::encode_seq_slot(210000, next);
  for (int i = 0; i < 3; ++i) slots[i] = next[i];
  EXPECT_EQ(fw::load_seq_floor(slots), 140000u);
  EXPECT_EQ(fw::seq_slot_to_write(slots), 0);
  // Near the top the reservation saturates instead of wrapping.
  FakeSeqStore store;
  fw::Controller c(kKey, 0, &store);
  ASSERT_EQ(send(c, cmd(0xFFFFFFF0u, 0, 1500, 1500, 1000, 1500), 0), 200);
  EXPECT_EQ(fw::load_seq_floor(store.slots), 0xFFFFFFFFu);
}
