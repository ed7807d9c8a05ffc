// slam-server client: see slam_server_client.hpp.
#include "app/slam_server_client.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "app/log_line.hpp"
#include "app/thread_setup.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace proto = rgbdquad::protocol;

namespace {
constexpr const char* kPeerName = "quad-control";
constexpr std::size_t kReadChunkBytes = 64 * 1024;

std::string hex_id(std::uint64_t id) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(id));
  return buf;
}

void log_link(const std::string& s) { log_line("SLAM link: " + s); }

std::uint64_t random_session_id() {
  std::random_device rd;
  std::uint64_t id = 0;
  while (id == 0) id = (static_cast<std::uint64_t>(rd()) << 32) ^ rd();
  return id;
}

Eigen::Isometry3d to_isometry(const proto::Pose3& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(p.q_xyzw[3], p.q_xyzw[0], p.q_xyzw[1], p.q_xyzw[2])
                   .normalized()
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.t_m[0], p.t_m[1], p.t_m[2]);
  return T;
}

const char* state_name(proto::TrackingState s) {
  switch (s) {
    case proto::TrackingState::kInitializing:
      return "initialising";
    case proto::TrackingState::kTracking:
      return "tracking";
    case proto::TrackingState::kLost:
      return "lost";
    case proto::TrackingState::kRelocalized:
      return "relocalised";
  }
  return "?";
}

proto::ImageFrame image(const CameraFrame& f, proto::PixelFormat format,
                        std::vector<std::uint8_t> payload) {
  proto::ImageFrame im;
  im.header.sequence = static_cast<std::uint32_t>(f.sequence);
  im.header.capture_timestamp_us = static_cast<std::uint64_t>(f.capture_us);
  im.header.send_timestamp_us = static_cast<std::uint64_t>(monotonic_now_us());
  im.header.width = static_cast<std::uint16_t>(f.rgb.cols);
  im.header.height = static_cast<std::uint16_t>(f.rgb.rows);
  im.header.pixel_format = format;
  im.header.encoding = proto::Encoding::kRaw;
  im.header.payload_length = static_cast<std::uint32_t>(payload.size());
  im.payload = std::move(payload);
  return im;
}
}  // namespace

bool SlamServerOptions::is_valid(std::string* error) const {
  if (host.empty() || port == 0) return reject(error, "slam.host/slam.port must be set");
  if (reply_timeout_ms < 10 || reconnect_interval_ms < 10)
    return reject(error, "slam timeouts must be >= 10 ms");
  return true;
}

SlamServerClient::SlamServerClient(SlamServerOptions options, Callback callback)
    : options_(std::move(options)), callback_(std::move(callback)) {
  if (options_.session_id == 0) options_.session_id = random_session_id();
  status_.session_id = hex_id(options_.session_id);
  thread_ = std::thread([this] { run(); });
}

SlamServerClient::~SlamServerClient() {
  stop_ = true;
  mailbox_.close();
  socket_.wake_up();  // a wait in progress returns at once
  if (thread_.joinable()) thread_.join();
}

std::string SlamServerClient::name() const {
  return "slam-server at " + options_.host + ":" + std::to_string(options_.port);
}

bool SlamServerClient::submit(const CameraFrame& frame) { return mailbox_.offer(frame); }

SlamStats SlamServerClient::stats() const { return mailbox_.stats(); }

SlamLinkStatus SlamServerClient::link_status() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return status_;
}

void SlamServerClient::disconnect() {
  socket_.close();
  connected_ = false;
  decoder_ = proto::StreamDecoder{};
}

bool SlamServerClient::send(const proto::Message& message, Clock::time_point deadline,
                            std::string* error) {
  const auto encoded = proto::encode(message);
  if (!encoded.ok()) {
    *error = "encode: " + encoded.error;
    return false;
  }
  return socket_.write_all(encoded.bytes.data(), encoded.bytes.size(), deadline, error);
}

std::optional<proto::Message> SlamServerClient::receive(Clock::time_point deadline,
                                                        const std::string& what,
                                                        std::string* error) {
  std::vector<std::uint8_t> buf(kReadChunkBytes);
  while (!stop_) {
    auto r = decoder_.next();
    if (r.status == proto::DecodeStatus::kMessage) return r.message;
    if (r.status == proto::DecodeStatus::kError) {
      const std::string e =
          std::string("dropped bytes: ") + proto::to_string(r.error) + " " + r.detail;
      if (decode_errors_++ == 0) log_link(e + " (further ones counted)");
      mailbox_.note_error(e);
      continue;
    }
    std::size_t n = 0;
    std::string read_error;
    switch (socket_.read_some(buf.data(), buf.size(), deadline, &n, &read_error)) {
      case SlamLinkSocket::ReadStatus::kData:
        decoder_.feed(buf.data(), n);
        continue;
      case SlamLinkSocket::ReadStatus::kTimeout:
        *error = "no " + what + " within " + std::to_string(options_.reply_timeout_ms) + " ms (" +
                 std::to_string(decoder_.buffered_bytes()) + " bytes of a message received)";
        return std::nullopt;
      case SlamLinkSocket::ReadStatus::kClosed:
        *error =
            stop_
                ? "stopping"
                : "slam-server closed the connection (end of file) while quad-control waited for " +
                      what;
        return std::nullopt;
      case SlamLinkSocket::ReadStatus::kError:
        *error = read_error;
        return std::nullopt;
    }
  }
  *error = "stopping";
  return std::nullopt;
}

bool SlamServerClient::connect(std::string* error) {
  const auto deadline = Clock::now() + std::chrono::milliseconds(options_.reply_timeout_ms);
  std::string why;
  if (!socket_.connect(options_.host, options_.port, deadline, &why)) {
    *error = "cannot connect to " + name() + ": " + why;
    disconnect();
    return false;
  }
  proto::SlamHello hello;
  hello.peer_name = kPeerName;
  hello.session_id = options_.session_id;
  if (!send(hello, deadline, error)) {
    disconnect();
    return false;
  }
  auto reply = receive(deadline, "SlamHello answer", error);
  if (!reply) {
    disconnect();
    return false;
  }
  const auto* peer = std::get_if<proto::SlamHello>(&*reply);
  if (peer == nullptr) {
    *error = "slam-server did not answer SlamHello with SlamHello";
    disconnect();
    return false;
  }
  if (const std::string incompatible = proto::hello_incompatibility(*peer); !incompatible.empty()) {
    *error = "slam-server is incompatible: " + incompatible;
    disconnect();
    return false;
  }
  if (!peer->refusal.empty()) {
    *error = "slam-server refused the connection: " + peer->refusal;
    disconnect();
    return false;
  }
  connected_ = true;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    if (peer->resumed && session_ > 0) {
      ++status_.resumes;
    } else {
      ++status_.sessions_started;
      session_ = status_.sessions_started;
    }
  }
  if (peer->resumed && session_ > 0)
    log_link("connected to " + name() + ": map " + hex_id(peer->session_id) +
             " resumed (world frame kept, " + std::to_string(peer->session_frames) + " frames)");
  else
    log_link(
        "connected to " + name() + ": map " + hex_id(peer->session_id) + " started (new" +
        (session_ > 1 ? ", new world frame: SLAM map reset #" + std::to_string(session_ - 1) : "") +
        ")");
  return true;
}

std::optional<SlamResult> SlamServerClient::exchange(const CameraFrame& f, std::string* error) {
  if (f.rgb.type() != CV_8UC3 || f.depth.type() != CV_16UC1 || f.rgb.size() != f.depth.size()) {
    *error = "frame is not 8-bit BGR + 16-bit depth of one size";
    return std::nullopt;
  }
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(f.rgb.total()) * 3);
  std::vector<std::uint8_t> depth(static_cast<std::size_t>(f.depth.total()) * 2);
  std::size_t i = 0, k = 0;
  for (int v = 0; v < f.rgb.rows; ++v) {
    const auto* bgr = f.rgb.ptr<cv::Vec3b>(v);
    const auto* d = f.depth.ptr<std::uint16_t>(v);
    for (int u = 0; u < f.rgb.cols; ++u) {
      rgb[i++] = bgr[u][2];
      rgb[i++] = bgr[u][1];
      rgb[i++] = bgr[u][0];
      depth[k++] = static_cast<std::uint8_t>(d[u] & 0xFF);  // little-endian, explicitly
      depth[k++] = static_cast<std::uint8_t>(d[u] >> 8);
    }
  }
  proto::RgbdFrame m;
  m.pair_sequence = static_cast<std::uint32_t>(f.sequence);
  m.intrinsics.fx_px = f.intrinsics.fx_px;
  m.intrinsics.fy_px = f.intrinsics.fy_px;
  m.intrinsics.cx_px = f.intrinsics.cx_px;
  m.intrinsics.cy_px = f.intrinsics.cy_px;
  for (std::size_t j = 0; j < 5; ++j) m.intrinsics.distortion[j] = f.intrinsics.distortion[j];
  m.depth_scale_units_per_m = f.intrinsics.depth_units_per_m;
  if (f.q_ned_cam) {
    const Eigen::Quaterniond q = f.q_ned_cam->normalized();
    m.attitude = proto::CameraAttitude{true, {q.x(), q.y(), q.z(), q.w()}};
  }
  if (f.accel) {  // as received, sensor axes: slam-server's gate rotates it
    const auto& a = *f.accel;
    m.accel =
        proto::AccelSample{true,
                           static_cast<std::uint64_t>(std::llround(std::max(0.0, a.stamp_s) * 1e6)),
                           {a.f_sensor_mps2.x(), a.f_sensor_mps2.y(), a.f_sensor_mps2.z()}};
  }
  m.rgb = image(f, proto::PixelFormat::kRgb8, std::move(rgb));
  m.depth = image(f, proto::PixelFormat::kDepth16, std::move(depth));
  // One deadline for the whole exchange: sending, SLAM on the server, the reply.
  const auto deadline = Clock::now() + std::chrono::milliseconds(options_.reply_timeout_ms);
  if (!send(m, deadline, error)) return std::nullopt;
  const std::string what = "PoseUpdate for frame " + std::to_string(m.pair_sequence);
  while (true) {
    auto reply = receive(deadline, what, error);
    if (!reply) return std::nullopt;
    const auto* pose = std::get_if<proto::PoseUpdate>(&*reply);
    if (pose == nullptr || pose->pair_sequence != m.pair_sequence) continue;  // not ours: skip
    SlamResult r;
    r.frame_sequence = f.sequence;
    r.capture_us = f.capture_us;
    r.state = state_name(pose->tracking_state);
    r.tracking = pose->tracking_state == proto::TrackingState::kTracking ||
                 pose->tracking_state == proto::TrackingState::kRelocalized;
    r.T_world_cam = to_isometry(pose->T_world_cam);
    r.inliers = pose->inlier_count;
    r.map_correction_count = pose->map_correction_count;
    return r;
  }
}

void SlamServerClient::run() {
  slam::name_current_thread("qc-slam-link");
  raise_this_thread(options_.thread_priority, "SLAM link");
  while (auto taken = mailbox_.take()) {
    const CameraFrame& frame = *taken;
    std::string error;
    std::optional<SlamResult> result;
    const std::int64_t now = monotonic_now_us();
    if (!connected_ &&
        (reconnect_now_ || now - last_attempt_us_ >= options_.reconnect_interval_ms * 1000LL)) {
      reconnect_now_ = false;
      last_attempt_us_ = now;
      if (!connect(&error)) {
        if (error != last_connect_error_)
          log_link(error + " (retrying every " + std::to_string(options_.reconnect_interval_ms) +
                   " ms)");
        last_connect_error_ = error;
      } else {
        last_connect_error_.clear();
      }
    }
    if (connected_) {
      result = exchange(frame, &error);
      if (!result && !stop_) {
        log_link("disconnected: " + error + "; reconnecting to resume map " +
                 hex_id(options_.session_id) + " (slam-server keeps it for a grace period)");
        {
          std::lock_guard<std::mutex> lock(status_mutex_);
          ++status_.disconnects;
          status_.last_disconnect = error;
        }
        disconnect();
        reconnect_now_ = true;
      }
    } else if (error.empty()) {
      // Between attempts the last attempt's reason stays visible (dashboard, tests).
      error = "not connected (retrying every " + std::to_string(options_.reconnect_interval_ms) +
              " ms): " + last_connect_error_;
    }
    if (result) {
      result->latency_ms = static_cast<double>(monotonic_now_us() - frame.received_us) / 1000.0;
      result->session = session_;
    }
    mailbox_.finish(result.has_value(), result ? result->latency_ms : 0.0, error);
    if (result && callback_) callback_(*result, frame);
  }
}

}  // namespace rgbdquad::quadcontrol
