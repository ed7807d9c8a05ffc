// Closed loop with delayed poses: the FlightController (HIL gains) holding a craft in gusts while
// the SLAM poses reach it late, in the stalls of HIL scenario 5 (2 % loss -> 200 ms TCP stalls),
// once flying on the raw poses (the design before the estimator) and once on PoseEstimator's
// estimate (IMU with gravity, 8 mg noise and a level-trim error, poses fused at capture). Then the
// two position laws (the thesis PID and the cascade) against gust strength: the model half of the
// wind table (docs/control.md, "Position law").
// A model, not the HIL rig: APM AltHold (height on a climb-rate stick), stick -> lean angle with
// the APM's ~0.2 s attitude response, drag, Gauss-Markov gusts; seeded, time passed in.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <deque>
#include <random>

#include "core/flight_controller.hpp"
#include "core/geometry.hpp"
#include "core/pose_estimator.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr double kG = 9.80665;
constexpr double kAngleMaxDeg = 45.0;     // ArduCopter ANGLE_MAX: full stick = 45 deg
constexpr double kAttitudeTauS = 0.22;    // APM angle P 4.5/s (hil/fc_emulator quad_model)
constexpr double kDragPerS = 0.35 / 1.5;  // linear drag 0.35 N per m/s on 1.5 kg (quad_model)
constexpr double kClimbMaxMps = 2.5;      // AltHold PILOT_VELZ_MAX at full stick
constexpr double kGustStdMss = 0.15;      // HIL DISTURBED: 0.15 m/s^2, 2 s correlation
constexpr double kGustTauS = 2.0;
constexpr double kTrimRollDeg = 0.5, kTrimPitchDeg = -0.3;  // HIL DISTURBED trim error
constexpr double kAccelNoiseMg = 8.0;                       // RAW_IMU noise of the FC emulator
constexpr std::int64_t kStepUs = 1000;
constexpr std::int64_t kFramePeriodUs = 33333;     // 30 fps
constexpr std::int64_t kPoseLatencyUs = 40000;     // capture -> pose, idle (HIL median ~35-45 ms)
constexpr std::int64_t kCommandLatencyUs = 30000;  // command -> PWM at the APM (HIL ~25-35 ms)
constexpr std::int64_t kStallUs = 200000;          // LinkProxy's retransmission stall
constexpr double kFrameStallProbability = 0.06;  // 2 % per segment, ~3 segments per JPEG+zstd frame

ControlConfig hil_config(bool estimator, PositionLaw law = PositionLaw::kPid) {
  ControlConfig c;
  c.position_law = law;
  c.roll = {0.04, 0.0, 0.04, 20.0};  // hil/hilrig/slam_flight.py HIL_CONTROLLER_GAINS
  c.pitch = {0.04, 0.0, 0.04, 20.0};
  c.yaw = {0.15, 0.0, 0.02, 30.0};
  c.throttle = {0.025, 0.0, 0.0, 30.0};
  c.apm_throttle_deadband_us = 100.0;
  c.estimator.enabled = estimator;
  return c;
}

struct Craft {
  double gust_std_mss = kGustStdMss;
  Eigen::Vector2d p{0, 0}, v{0, 0}, gust{0, 0};
  double z = 0.3, roll = 0, pitch = 0;  // roll + = right, pitch + = nose up (NED/FRD)
  Eigen::Vector2d accel{0, 0};
  void step(const StickCommand& s, double dt, std::mt19937& rng) {
    if (!s.armed || s.throttle_pct <= 0.0) return;  // on the ground, motors idle
    const double lean = kAngleMaxDeg / kDegPerRad / 100.0;
    const double roll_target = s.roll_pct * lean + kTrimRollDeg / kDegPerRad;
    const double pitch_target =
        -s.pitch_pct * lean + kTrimPitchDeg / kDegPerRad;  // + stick = nose down
    roll += (roll_target - roll) * dt / kAttitudeTauS;
    pitch += (pitch_target - pitch) * dt / kAttitudeTauS;
    const double a = std::exp(-dt / kGustTauS);
    std::normal_distribution<double> n(0.0, gust_std_mss * std::sqrt(1.0 - a * a));
    gust = a * gust + Eigen::Vector2d(n(rng), n(rng));
    // Heading +x (yaw 0): forward = +x, right = -y (floor z up). Hover thrust holds the height.
    const double fwd = -kG * std::tan(pitch), right = kG * std::tan(roll);
    accel = Eigen::Vector2d(fwd, -right) + gust - kDragPerS * v;
    v += accel * dt;
    p += v * dt;
    z += (s.throttle_pct - 50.0) / 50.0 * kClimbMaxMps * dt;
  }
  /// RAW_IMU's specific force (body FRD) with its noise, and the APM's attitude (yaw 0).
  ImuSample imu(std::int64_t t_us, std::mt19937& rng) const {
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();        // body -> NED, yaw 0
    const Eigen::Vector3d a_ned(accel.x(), -accel.y(), 0.0);  // floor (x, y, up) -> NED
    std::normal_distribution<double> n(0.0, kAccelNoiseMg * 1e-3 * kG);
    ImuSample s;
    s.t_us = t_us;
    s.specific_force_frd_mss = R.transpose() * (a_ned - Eigen::Vector3d(0, 0, kG)) +
                               Eigen::Vector3d(n(rng), n(rng), n(rng));
    s.roll_rad = roll;
    s.pitch_rad = pitch;
    return s;
  }
};

struct HoldResult {
  double max_m = 0.0, rms_m = 0.0;
  bool held = false;  ///< in hold at the end
};

/// Take-off, then 30 s of hold; the hold error (truth against the take-off point) after 5 s.
HoldResult fly(bool estimator, bool stalls, unsigned seed, std::int64_t stall_us = kStallUs,
               PositionLaw law = PositionLaw::kPid, double gust_std_mss = kGustStdMss) {
  ControlConfig config = hil_config(estimator, law);
  FlightController fc(config);
  PoseEstimator est(config.estimator);
  Craft craft;
  craft.gust_std_mss = gust_std_mss;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::int64_t link_free_us = 0;                             // stream link stalled until then
  std::deque<std::pair<std::int64_t, CraftPose>> in_flight;  // (delivery, pose stamped at capture)
  std::deque<std::pair<std::int64_t, std::int64_t>> capture_of;  // (delivery, capture)
  std::deque<std::pair<std::int64_t, StickCommand>> to_apm;
  StickCommand applied;
  std::int64_t last_cmd = -1000000;
  HoldResult r;
  double sum_sq = 0.0;
  int n = 0;
  std::optional<std::int64_t> hold_since;
  const auto feed = [&](std::int64_t now) {
    if (!estimator) return false;
    const StateEstimate e = est.estimate(now);
    if (!e.imu_aided) return false;
    fc.on_pose(PoseSample{now, e.valid, e.pose},
               Velocity3{e.velocity_m_per_s.x(), e.velocity_m_per_s.y(), 0.0});
    return true;
  };
  const std::int64_t end_us = 45'000'000;
  for (std::int64_t t = 0; t <= end_us; t += kStepUs) {
    if (t % kFramePeriodUs < kStepUs) {
      const CraftPose truth{craft.p.x(), craft.p.y(), craft.z, 0.0};
      std::int64_t deliver = t + kPoseLatencyUs;
      if (stalls && t >= 3'000'000) {
        if (t < link_free_us)
          deliver = std::max(deliver, link_free_us + kPoseLatencyUs);
        else if (u(rng) < kFrameStallProbability)
          link_free_us = t + stall_us, deliver = link_free_us + kPoseLatencyUs;
      }
      in_flight.push_back({deliver, truth});
      capture_of.push_back({deliver, t});
    }
    if (t % 40000 == 0) est.predict(craft.imu(t, rng));  // ATTITUDE 25 Hz (RAW_IMU repeated)
    bool fresh_pose = false;
    // Poses delivered now: SLAM takes the newest of a burst (the rest are dropped while busy).
    std::optional<std::pair<std::int64_t, CraftPose>> newest;
    while (!in_flight.empty() && in_flight.front().first <= t) {
      newest = {capture_of.front().second, in_flight.front().second};
      in_flight.pop_front();
      capture_of.pop_front();
    }
    if (newest) {
      est.fuse_pose(newest->second, newest->first);
      if (!feed(t)) fc.on_pose(PoseSample{t, true, newest->second});
      fresh_pose = true;
    }
    // Commands: on each fresh pose, else a keep-alive every 50 ms (firmware.send_on_pose).
    if (fresh_pose || t - last_cmd >= 50000) {
      feed(t);
      to_apm.push_back({t + kCommandLatencyUs, fc.update(t)});
      last_cmd = t;
    }
    while (!to_apm.empty() && to_apm.front().first <= t) {
      applied = to_apm.front().second;
      to_apm.pop_front();
    }
    craft.step(applied, kStepUs / 1e6, rng);
    if (t == 500'000) fc.command(t, OperatorCommand::kArm);
    if (t == 4'000'000) fc.command(t, OperatorCommand::kTakeOff);
    if (fc.status().state == FlightState::kHold && !hold_since) hold_since = t;
    if (hold_since && t >= *hold_since + 5'000'000 && t % 20000 == 0) {
      const double e = craft.p.norm();  // hold point = take-off point (0, 0)
      r.max_m = std::max(r.max_m, e);
      sum_sq += e * e;
      ++n;
    }
  }
  r.rms_m = n ? std::sqrt(sum_sq / n) : 0.0;
  r.held = fc.status().state == FlightState::kHold && n > 1000;
  return r;
}

struct StallCase {
  const char* name;
  std::int64_t stall_us;  ///< how late the poses behind a stall arrive (HIL scenario 5: 200-400 ms)
};

class StalledPoses : public ::testing::TestWithParam<StallCase> {};

TEST_P(StalledPoses, GivenScenario5StallsThenTheEstimatorKeepsHolding) {
  const StallCase c = GetParam();
  // GIVEN gusts, a trim error and stream stalls, over 5 seeds
  double worst_raw = 0, worst_est = 0, rms_raw = 0, rms_est = 0;
  int raw_lost = 0;
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u}) {
    // WHEN the controller flies on the raw late poses, and on the fused estimate
    const HoldResult raw = fly(false, true, seed, c.stall_us);
    const HoldResult fused = fly(true, true, seed, c.stall_us);
    // THEN with the estimator the craft is still in hold at the end of every flight
    EXPECT_TRUE(fused.held) << c.name << " seed " << seed;
    if (!raw.held) ++raw_lost;
    worst_raw = std::max(worst_raw, raw.max_m);
    worst_est = std::max(worst_est, fused.max_m);
    rms_raw += raw.rms_m / 5;
    rms_est += fused.rms_m / 5;
  }
  std::printf(
      "%s: raw poses max %.3f m rms %.3f m (%d of 5 flights left hold: lost-hold -> landing); "
      "estimator max %.3f m rms %.3f m\n",
      c.name, worst_raw, rms_raw, raw_lost, worst_est, rms_est);
  // ... and never flies away: a bound at twice the hold target, not the target (measured maxima:
  // docs/control.md; the 0.15 m target is not met in this model by either design)
  EXPECT_LE(worst_est, 0.3) << c.name;
}

// 200 ms: TCP's retransmission stall alone; 300 / 400 ms: plus the burst SLAM works through (HIL
// scenario 5 measured poses 200-400 ms late). Beyond the controller's 300 ms pose timeout the raw
// poses end in lost-hold (neutral sticks) and the blind landing; the estimator bridges up to 500
// ms.
INSTANTIATE_TEST_SUITE_P(Stalls, StalledPoses,
                         ::testing::Values(StallCase{"stall_200ms", 200000},
                                           StallCase{"stall_300ms", 300000},
                                           StallCase{"stall_400ms", 400000}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(EstimatorClosedLoop, GivenStallsBeyondThePoseTimeoutWhenFusionIsDisabledThenTheHoldIsLost) {
  // The check above cannot pass without the fusion: on the raw poses a 300 ms stall (+40 ms
  // latency) exceeds the controller's 300 ms pose timeout and some flights leave hold.
  int lost = 0;
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u}) lost += fly(false, true, seed, 300000).held ? 0 : 1;
  EXPECT_GT(lost, 0);
}

TEST(EstimatorClosedLoop, GivenNoStallsThenTheEstimatorIsNoWorse) {
  double worst_raw = 0, worst_est = 0;
  for (unsigned seed : {1u, 2u, 3u}) {
    worst_raw = std::max(worst_raw, fly(false, false, seed).max_m);
    worst_est = std::max(worst_est, fly(true, false, seed).max_m);
  }
  std::printf("hold without stalls, 3 seeds: raw poses max %.3f m; estimator max %.3f m\n",
              worst_raw, worst_est);
  EXPECT_LE(worst_est, worst_raw * 1.1);
}

struct WindCase {
  const char* name;
  double gust_std_mss;
};

class PositionLawInWind : public ::testing::TestWithParam<WindCase> {};

// The model half of the wind table: both laws (estimator on, as flown), 5 seeds per gust level,
// hold error after 5 s in hold. Printed for docs/control.md; the assertion is the design claim at
// the rig's gust level and below: the cascade holds tighter than the thesis PID.
TEST_P(PositionLawInWind, GivenGustsThenTheCascadeHoldsNoWorseThanThePid) {
  const WindCase c = GetParam();
  double max_pid = 0, max_cas = 0, rms_pid = 0, rms_cas = 0;
  int held_pid = 0, held_cas = 0;
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u}) {
    const HoldResult pid = fly(true, false, seed, kStallUs, PositionLaw::kPid, c.gust_std_mss);
    const HoldResult cas = fly(true, false, seed, kStallUs, PositionLaw::kCascade, c.gust_std_mss);
    max_pid = std::max(max_pid, pid.max_m);
    max_cas = std::max(max_cas, cas.max_m);
    rms_pid += pid.rms_m / 5;
    rms_cas += cas.rms_m / 5;
    held_pid += pid.held;
    held_cas += cas.held;
  }
  std::printf(
      "wind %s (%.2f m/s^2): pid max %.3f rms %.3f held %d/5; cascade max %.3f rms %.3f "
      "held %d/5\n",
      c.name, c.gust_std_mss, max_pid, rms_pid, held_pid, max_cas, rms_cas, held_cas);
  EXPECT_EQ(held_cas, 5);
  // Where the lean limit is not reached (up to 0.5 m/s^2) the velocity integral takes a quarter
  // or more off the RMS; beyond it both laws are saturated and only "no worse" is claimed.
  if (c.gust_std_mss > 0.0) {
    EXPECT_LT(rms_cas, (c.gust_std_mss <= 0.5 ? 0.75 : 1.0) * rms_pid);
  }
  // At the rig's level (0.15 m/s^2) the HIL target, +-0.15 m, is met in every seed with 20 %
  // margin.
  if (c.gust_std_mss <= kGustStdMss) {
    EXPECT_LE(max_cas, 0.12);
  }
}

INSTANTIATE_TEST_SUITE_P(Gusts, PositionLawInWind,
                         ::testing::Values(WindCase{"calm", 0.0}, WindCase{"rig_0_15", 0.15},
                                           WindCase{"g0_3", 0.3}, WindCase{"g0_5", 0.5},
                                           WindCase{"g0_8", 0.8}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace rgbdquad::quadcontrol
