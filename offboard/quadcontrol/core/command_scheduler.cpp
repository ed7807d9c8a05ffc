// Pose-driven, rate-limited command schedule: see command_scheduler.hpp.
#include "core/command_scheduler.hpp"

#include <algorithm>

#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
// The firmware's failsafe engages 250 ms after the last valid command (firmware/core/limits.h);
// a keep-alive must leave room for at least one lost command before it.
constexpr std::int64_t kFirmwareFailsafeUs = 250000;
constexpr std::int64_t kMinIntervalFloorUs = 1000;  // below 1 ms the timer resolution dominates
}  // namespace

bool CommandScheduleOptions::is_valid(std::string* error) const {
  if (min_interval_us < kMinIntervalFloorUs)
    return reject(error, "firmware.min_interval_ms must be >= 1");
  if (keep_alive_us < min_interval_us)
    return reject(error, "firmware.keep_alive_ms must be >= firmware.min_interval_ms");
  if (keep_alive_us > kFirmwareFailsafeUs / 2) {
    return reject(error,
                  "firmware.keep_alive_ms must be <= 125 (half the firmware's 250 ms failsafe)");
  }
  return true;
}

CommandScheduler::CommandScheduler(CommandScheduleOptions options) : options_(options) {}

void CommandScheduler::on_pose(std::int64_t now_us) {
  if (!pose_us_) pose_us_ = now_us;  // the oldest unsent pose decides; newer ones ride along
}

bool CommandScheduler::on_sent(std::int64_t now_us) {
  const bool driven_by_pose = pose_us_.has_value() && last_sent_us_.has_value();
  last_sent_us_ = now_us;
  pose_us_.reset();
  return driven_by_pose;
}

std::optional<std::int64_t> CommandScheduler::next_send_us() const {
  if (!last_sent_us_) return std::nullopt;
  if (pose_us_) return std::max(*last_sent_us_ + options_.min_interval_us, *pose_us_);
  return *last_sent_us_ + options_.keep_alive_us;
}

bool CommandScheduler::due(std::int64_t now_us) const {
  const auto next = next_send_us();
  return !next || now_us >= *next;
}

}  // namespace rgbdquad::quadcontrol
