// The firmware REST client of quad-control (thesis: two clients take turns sending the latest
// command as HTTP PUT and wait for the IMU reply, so one timed-out client never stalls control).
//
// Every period_ms the link picks the next idle client (round robin), asks the command provider for
// the command of this instant (the controller runs at send time, on the newest pose: no extra wait
// between computing and sending) and sends it (protocol/control: PUT /control?...&mac=...,
// SipHash-2-4 under the craft key, strictly increasing sequence). Before the first command it reads
// GET /status to continue above the sequence number the craft last accepted. Each request has its
// own deadline (timeout_ms); a client still waiting is skipped. With send_on_pose
// the fixed period is replaced by a CommandScheduler: notify_pose() makes the next command go out
// at once, no sooner than min_interval_ms after the previous one (what the firmware sustains), and
// with no new pose a keep-alive goes out every keep_alive_ms (the firmware's 250 ms failsafe never
// fires while poses stop); a pose that finds both clients waiting goes out as soon as one is free.
// Replies (with the craft's IMU reading) are timestamped on arrival and passed to the callback on
// the link's thread. Owns one io_context thread; joined in the destructor.
#pragma once

#include <array>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "app/command_gap.hpp"
#include "core/command_scheduler.hpp"
#include "core/stick_mapping.hpp"
#include "link/control_codec.hpp"
#include "slam/core/thread_priority.hpp"

namespace rgbdquad::quadcontrol {

struct FirmwareLinkOptions {
  std::string host = "192.168.240.1";  ///< Arduino Uno WiFi in its own access-point mode
  std::uint16_t port = 80;
  int timeout_ms = 100;  ///< > 2 periods: a reply later than this is useless for control
  int period_ms = 20;  ///< 50 commands/s, the rate the thesis' firmware handled (send_on_pose off)
  /// Send on each new pose (rate-limited, with keep-alives) instead of every
  /// period_ms. Saves ~half a command period of camera->PWM latency (HIL make demo: pose ->
  /// command 9.9 -> 1.2 ms median); on by default since measured (docs/control.md).
  bool send_on_pose = true;
  /// With send_on_pose: shortest gap between commands, 11 ms >= the firmware's measured 10.6 ms per
  /// command in simavr with one request in flight (reasons in core/command_scheduler.hpp).
  int min_interval_ms = 11;
  /// With send_on_pose: longest gap without a command (5 per firmware failsafe of 250 ms).
  int keep_alive_ms = 50;
  /// The I/O thread (control step + send) is on the real-time path
  /// (GroundStationOptions::realtime).
  slam::ThreadPriorityOptions thread_priority;
  CommandScheduleOptions schedule() const {
    return {std::int64_t{min_interval_ms} * 1000, std::int64_t{keep_alive_ms} * 1000};
  }
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

struct FirmwareLinkStats {
  std::uint64_t sent = 0, ok = 0, timeouts = 0, http_errors = 0, stale = 0, connect_errors = 0;
  double last_latency_ms = 0.0;
  double mean_latency_ms = 0.0;  ///< exponential mean over ~10 replies
  std::optional<rgbd_control::Reply> last_reply;
  std::int64_t last_reply_us = 0;
  std::string last_error;
  std::uint32_t seq = 0;
  std::uint64_t pose_driven = 0;  ///< send_on_pose: commands sent for a fresh pose
  std::uint64_t keep_alives =
      0;  ///< send_on_pose: commands sent because no pose came for keep_alive_ms
  std::uint64_t withheld =
      0;  ///< sends the provider withheld (the controller handed over to the failsafe)
  /// Gaps between two commands longer than CommandGapMonitor's threshold (each logged with its
  /// causes), and the longest gap so far.
  std::uint64_t command_gaps = 0;
  double max_command_gap_ms = 0.0;
  /// Longest time the link went without asking the controller for a command (sent or withheld):
  /// the link's own health, which a blind landing's hand-over (max_command_gap_ms ~8 s) is not.
  double max_link_pause_ms = 0.0;
};

class FirmwareLink {
 public:
  using ReplyCallback =
      std::function<void(std::int64_t received_us, const rgbd_control::Reply& reply)>;
  /// Called on the link's thread just before each command is sent: the command for `now_us`, which
  /// will carry sequence number `seq`, or nullopt to send nothing this period (a blind landing
  /// hands the craft to its own failsafe). Must not call back into the link.
  using CommandProvider =
      std::function<std::optional<PwmCommand>(std::int64_t now_us, std::uint32_t seq)>;

  /// Resolves host:port (numeric addresses never block); throws std::runtime_error on failure.
  FirmwareLink(FirmwareLinkOptions options, ControlSpec spec, rgbd_control::Key key,
               CommandProvider provider, ReplyCallback callback);
  ~FirmwareLink();
  FirmwareLink(const FirmwareLink&) = delete;
  FirmwareLink& operator=(const FirmwareLink&) = delete;

  FirmwareLinkStats stats() const;

  /// A fresh pose is available: with send_on_pose the next command goes out as soon as the minimum
  /// interval allows (the provider then runs the controller on it); without, does nothing.
  /// Thread-safe, never blocks (posts to the link's thread).
  void notify_pose();

 private:
  struct Client {
    std::unique_ptr<boost::beast::tcp_stream> stream;
    boost::beast::http::request<boost::beast::http::empty_body> request;
    boost::beast::http::response<boost::beast::http::string_body> response;
    boost::beast::flat_buffer buffer;
    bool busy = false;
    bool is_status = false;
    std::int64_t started_us = 0;
  };

  void schedule();
  void tick();
  /// send_on_pose: (re)arms the timer for the scheduler's next send, or sends now when due.
  void arm_scheduled();
  void on_scheduled();
  /// Starts a command on an idle client; false when both are still waiting for replies.
  bool start_on_idle_client();
  void start(Client& client);
  void finish(Client& client, boost::beast::error_code ec);
  /// A command went out at now_us: checks the gap since the previous one (logged with its causes).
  void note_command_sent(std::int64_t now_us, std::int64_t provider_us);

  FirmwareLinkOptions options_;
  ControlSpec spec_;
  rgbd_control::Key key_;
  CommandProvider provider_;
  ReplyCallback callback_;
  boost::asio::io_context io_;
  boost::asio::steady_timer timer_;
  std::chrono::steady_clock::time_point next_tick_{};
  boost::asio::ip::tcp::resolver::results_type endpoints_;
  std::array<Client, 2> clients_;
  std::size_t next_client_ = 0;
  CommandScheduler scheduler_;       ///< send_on_pose only; the link's thread only
  bool waiting_for_client_ = false;  ///< a due command waits for a reply to free a client
  bool seq_known_ = false;
  // Command gap diagnosis (the link's thread only).
  CommandGapMonitor gap_monitor_;
  CommandGapCauses gap_causes_;        ///< accumulated since the previous command
  std::int64_t timer_target_us_ = 0;   ///< when the armed timer should fire
  std::int64_t waiting_since_us_ = 0;  ///< a due send found both clients busy at this time
  std::uint64_t failures_at_last_send_ =
      0;  ///< timeouts + errors when the previous command went out
  std::uint64_t timeouts_at_last_send_ = 0;
  mutable slam::PriorityInheritanceMutex
      mutex_;  ///< the I/O thread (real-time) and stats() readers
  FirmwareLinkStats stats_;
  std::thread thread_;
};

}  // namespace rgbdquad::quadcontrol
