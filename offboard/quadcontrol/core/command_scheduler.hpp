// When the ground station sends the next command to the firmware (commands driven by fresh
// poses).
//
// A new pose is sent at once, but never sooner than min_interval after the previous command (what
// the firmware sustains); with no new pose a keep-alive goes out keep_alive after the previous
// command, so the firmware's 250 ms failsafe (docs/failsafe.md) never fires while the ground
// station runs, even when SLAM stops producing poses. Poses arriving while a command waits for its
// slot are coalesced: the one command sent carries the newest pose (the controller runs at send
// time).
//
// Time is passed in (monotonic microseconds); no clock, no threads. Not thread-safe: one owner
// (FirmwareLink's I/O thread).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace rgbdquad::quadcontrol {

struct CommandScheduleOptions {
  /// Shortest gap between two commands. 11 ms: in simavr the real firmware image needs 10.6 ms per
  /// command with one request in flight at the bridge's 1 Mbaud (93.9 commands/s; 16.4 ms and
  /// 61/s at the earlier 500 kbaud, when this was 17 ms; request bytes, ~5.3 ms of firmware time
  /// with 2.7 ms of SipHash, reply bytes). So the firmware never has two requests queued (at 500
  /// kbaud two in flight lost lines to the 128-byte RX ring below 14 ms), and every 30 fps pose
  /// (33 ms) goes through without waiting. docs/firmware.md, "Commands per second".
  std::int64_t min_interval_us = 11000;
  /// Longest gap without a command. 50 ms: five keep-alives fit into the firmware's 250 ms
  /// failsafe (a lost reply or two never trips it), and at 30 fps (33 ms) poses always come first,
  /// so a keep-alive never delays a pose-driven command.
  std::int64_t keep_alive_us = 50000;
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

class CommandScheduler {
 public:
  explicit CommandScheduler(CommandScheduleOptions options = {});

  /// A fresh pose became available at now_us: send as soon as min_interval allows.
  void on_pose(std::int64_t now_us);
  /// A command went out at now_us (or was deliberately withheld: the slot is used either way).
  /// Consumes the pending pose. Returns true when the send was driven by a pose, false for a
  /// keep-alive (and for the very first command).
  bool on_sent(std::int64_t now_us);
  /// Absolute time (us) at which the next command is due; nullopt: due now (nothing sent yet).
  std::optional<std::int64_t> next_send_us() const;
  /// True when a command should go out at now_us.
  bool due(std::int64_t now_us) const;
  bool pose_pending() const { return pose_us_.has_value(); }
  const CommandScheduleOptions& options() const { return options_; }

 private:
  CommandScheduleOptions options_;
  std::optional<std::int64_t> last_sent_us_;
  std::optional<std::int64_t> pose_us_;  ///< arrival of the oldest pose not yet sent
};

}  // namespace rgbdquad::quadcontrol
