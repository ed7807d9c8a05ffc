// Two rotating HTTP clients of the control link: see firmware_link.hpp.
#include "app/firmware_link.hpp"

#include <algorithm>
#include <boost/asio/post.hpp>
#include <stdexcept>

#include "app/frame_source.hpp"
#include "app/log_line.hpp"
#include "app/thread_setup.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;

namespace {
constexpr double kLatencyEmaWeight =
    0.1;  // ~10-reply memory: smooth yet responsive on the dashboard
}

bool FirmwareLinkOptions::is_valid(std::string* error) const {
  if (host.empty()) return reject(error, "firmware.host must not be empty");
  if (port == 0) return reject(error, "firmware.port must be > 0");
  if (timeout_ms < 1 || timeout_ms > 10000)
    return reject(error, "firmware.timeout_ms must be in [1, 10000]");
  if (period_ms < 5 || period_ms > 1000)
    return reject(error, "firmware.period_ms must be in [5, 1000]");
  if (send_on_pose) {
    if (!schedule().is_valid(error)) return false;
  }
  return true;
}

FirmwareLink::FirmwareLink(FirmwareLinkOptions options, ControlSpec spec, rgbd_control::Key key,
                           CommandProvider provider, ReplyCallback callback)
    : options_(std::move(options)),
      spec_(std::move(spec)),
      key_(key),
      provider_(std::move(provider)),
      callback_(std::move(callback)),
      timer_(io_),
      scheduler_(options_.schedule()) {
  if (std::string error; !options_.is_valid(&error)) throw std::runtime_error(error);
  asio::ip::tcp::resolver resolver(io_);
  beast::error_code ec;
  endpoints_ = resolver.resolve(options_.host, std::to_string(options_.port), ec);
  if (ec)
    throw std::runtime_error("firmware: cannot resolve " + options_.host + ": " + ec.message());
  if (options_.send_on_pose) {
    asio::post(io_, [this] { arm_scheduled(); });
  } else {
    schedule();
  }
  thread_ = std::thread([this] {
    slam::name_current_thread("qc-firmware");
    raise_this_thread(options_.thread_priority, "firmware link");
    io_.run();
  });
}

FirmwareLink::~FirmwareLink() {
  io_.stop();
  if (thread_.joinable()) thread_.join();
}

FirmwareLinkStats FirmwareLink::stats() const {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return stats_;
}

void FirmwareLink::schedule() {
  // Absolute deadlines: a late tick does not shift the following ones (holds 50 Hz under load).
  const auto period = std::chrono::milliseconds(options_.period_ms);
  const auto now = std::chrono::steady_clock::now();
  next_tick_ = next_tick_.time_since_epoch().count() == 0 ? now + period : next_tick_ + period;
  if (next_tick_ < now - 5 * period) next_tick_ = now + period;  // far behind: restart the grid
  timer_.expires_at(next_tick_);
  timer_target_us_ =
      monotonic_now_us() +
      std::chrono::duration_cast<std::chrono::microseconds>(next_tick_ - now).count();
  timer_.async_wait([this](beast::error_code ec) {
    if (ec) return;
    gap_causes_.late_us = std::max(gap_causes_.late_us, monotonic_now_us() - timer_target_us_);
    tick();
    schedule();
  });
}

void FirmwareLink::tick() { start_on_idle_client(); }

bool FirmwareLink::start_on_idle_client() {
  // Round robin over idle clients: a client still waiting for its reply is skipped.
  for (std::size_t i = 0; i < clients_.size(); ++i) {
    Client& c = clients_[(next_client_ + i) % clients_.size()];
    if (!c.busy) {
      next_client_ = (next_client_ + i + 1) % clients_.size();
      start(c);
      return true;
    }
  }
  return false;
}

void FirmwareLink::notify_pose() {
  if (!options_.send_on_pose) return;
  asio::post(io_, [this] {
    scheduler_.on_pose(monotonic_now_us());
    if (!waiting_for_client_) arm_scheduled();  // else the next reply sends it
  });
}

void FirmwareLink::arm_scheduled() {
  const std::int64_t now = monotonic_now_us();
  if (scheduler_.due(now)) return on_scheduled();
  // Re-arming cancels an earlier wait (its handler sees operation_aborted): one wait at a time.
  timer_target_us_ = *scheduler_.next_send_us();
  timer_.expires_after(std::chrono::microseconds(timer_target_us_ - now));
  timer_.async_wait([this](beast::error_code ec) {
    if (ec) return;
    gap_causes_.late_us = std::max(gap_causes_.late_us, monotonic_now_us() - timer_target_us_);
    on_scheduled();
  });
}

void FirmwareLink::on_scheduled() {
  const std::int64_t now = monotonic_now_us();
  if (!scheduler_.due(now)) return arm_scheduled();
  if (!start_on_idle_client()) {
    // Both requests still in flight: the firmware has no capacity now; the first reply (or
    // timeout) frees a client and sends the newest command then.
    waiting_for_client_ = true;
    waiting_since_us_ = now;
    return;
  }
  const bool pose_driven = scheduler_.on_sent(now);  // also when the provider withheld the command
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    ++(pose_driven ? stats_.pose_driven : stats_.keep_alives);
  }
  arm_scheduled();
}

void FirmwareLink::start(Client& c) {
  std::string target;
  // Only this thread changes seq_known_ and the sequence: read them, then compute the command
  // without holding the link's lock (the provider takes the ground station's).
  bool wants_command = false;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    wants_command = seq_known_ && stats_.seq < spec_.seq_max;
  }
  const std::uint32_t next_seq = stats().seq + 1;
  std::optional<PwmCommand> command;
  std::int64_t provider_us = 0;
  if (wants_command) {
    const std::int64_t asked_us = monotonic_now_us();
    command = provider_(asked_us, next_seq);
    provider_us = monotonic_now_us() - asked_us;
    if (!command) {  // nothing to send this period
      ++gap_causes_.withheld;
      const std::optional<std::string> handover = gap_monitor_.on_withheld(asked_us);
      {
        std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
        ++stats_.withheld;
        stats_.max_link_pause_ms = static_cast<double>(gap_monitor_.max_pause_us()) / 1000.0;
      }
      // Once per blind landing: its start, which the gap's own line (printed when commanding
      // resumes) cannot give when the ground station dies meanwhile.
      if (handover) log_line("firmware link: " + *handover);
      return;
    }
  }
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    if (!seq_known_) {
      target = spec_.status_path;
      c.is_status = true;
    } else {
      if (stats_.seq >= spec_.seq_max) {
        stats_.last_error = "sequence numbers exhausted: provision a new key";
        return;
      }
      ControlFields f{next_seq,          command->armed,       command->roll_us,
                      command->pitch_us, command->throttle_us, command->yaw_us};
      std::string error;
      auto t = build_control_target(spec_, key_, f, &error);
      if (!t) {
        stats_.last_error = "command not sent: " + error;
        return;
      }
      ++stats_.seq;
      target = *t;
      c.is_status = false;
    }
    ++stats_.sent;
  }
  c.busy = true;
  c.started_us = monotonic_now_us();
  if (!c.is_status) note_command_sent(c.started_us, provider_us);
  c.request = {};
  c.request.method(c.is_status ? http::verb::get : http::verb::put);
  c.request.target(target);
  c.request.version(11);
  c.request.set(http::field::host, options_.host);
  c.request.set(http::field::connection, "close");
  c.response = {};
  c.buffer.clear();
  c.stream = std::make_unique<beast::tcp_stream>(io_);
  c.stream->expires_after(std::chrono::milliseconds(options_.timeout_ms));
  c.stream->async_connect(
      endpoints_, [this, &c](beast::error_code ec, const asio::ip::tcp::endpoint&) {
        if (ec) return finish(c, ec);
        http::async_write(*c.stream, c.request, [this, &c](beast::error_code ec2, std::size_t) {
          if (ec2) return finish(c, ec2);
          http::async_read(*c.stream, c.buffer, c.response,
                           [this, &c](beast::error_code ec3, std::size_t) { finish(c, ec3); });
        });
      });
}

void FirmwareLink::finish(Client& c, beast::error_code ec) {
  const std::int64_t now = monotonic_now_us();
  c.busy = false;
  beast::error_code ignored;
  c.stream->socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  if (waiting_for_client_) {
    // A command became due while both clients were busy: send it after this reply is handled.
    waiting_for_client_ = false;
    gap_causes_.waited_for_client_us += now - waiting_since_us_;
    asio::post(io_, [this] { on_scheduled(); });
  }
  std::optional<rgbd_control::Reply> reply;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    if (ec == beast::error::timeout) {
      ++stats_.timeouts;
      stats_.last_error = "request timed out after " + std::to_string(options_.timeout_ms) + " ms";
      return;
    }
    if (ec) {
      ++stats_.connect_errors;
      stats_.last_error = "link: " + ec.message();
      return;
    }
    std::string error;
    reply =
        parse_control_reply(static_cast<int>(c.response.result_int()), c.response.body(), &error);
    if (!reply) {
      ++stats_.http_errors;
      stats_.last_error = "bad reply: " + error;
      return;
    }
    const double latency_ms = static_cast<double>(now - c.started_us) / 1000.0;
    stats_.last_latency_ms = latency_ms;
    stats_.mean_latency_ms = stats_.ok == 0 ? latency_ms
                                            : (1.0 - kLatencyEmaWeight) * stats_.mean_latency_ms +
                                                  kLatencyEmaWeight * latency_ms;
    stats_.last_reply = reply;
    stats_.last_reply_us = now;
    if (reply->status == 200) {
      ++stats_.ok;
    } else if (reply->status == 409) {
      ++stats_.stale;  // the other client's newer command arrived first: harmless
    } else {
      ++stats_.http_errors;
      stats_.last_error = "firmware replied " + std::to_string(reply->status) + " " + reply->err;
    }
    if (c.is_status || reply->seq > stats_.seq) {
      // Continue above what the craft accepted (restart of quad-control, or a replay rejection).
      if (reply->seq > stats_.seq || !seq_known_) stats_.seq = std::max(stats_.seq, reply->seq);
      seq_known_ = true;
    }
  }
  if (callback_) {
    callback_(now, *reply);
    gap_causes_.max_reply_callback_us =
        std::max(gap_causes_.max_reply_callback_us, monotonic_now_us() - now);
  }
}

void FirmwareLink::note_command_sent(std::int64_t now_us, std::int64_t provider_us) {
  gap_causes_.provider_us = provider_us;
  std::uint64_t timeouts, failures;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    timeouts = stats_.timeouts;
    failures = stats_.connect_errors + stats_.http_errors;
  }
  gap_causes_.timeouts = timeouts - timeouts_at_last_send_;
  gap_causes_.errors = failures - failures_at_last_send_;
  timeouts_at_last_send_ = timeouts;
  failures_at_last_send_ = failures;
  const std::optional<std::string> gap =
      gap_monitor_.on_sent(now_us, read_thread_cpu_times(), gap_causes_);
  gap_causes_ = {};
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    stats_.command_gaps = gap_monitor_.gaps();
    stats_.max_command_gap_ms = static_cast<double>(gap_monitor_.max_gap_us()) / 1000.0;
    stats_.max_link_pause_ms = static_cast<double>(gap_monitor_.max_pause_us()) / 1000.0;
  }
  // Rare (a gap over 100 ms), so the write to the log costs nothing in a healthy flight.
  if (gap) log_line("firmware link: " + *gap);
}

}  // namespace rgbdquad::quadcontrol
