// slam-server client: see slam_server_client.hpp.
#include "app/slam_server_client.hpp"

#include <iostream>

#include <sys/socket.h>
#include <sys/time.h>

#include <Eigen/Geometry>
#include <boost/asio/connect.hpp>
#include <boost/asio/write.hpp>

namespace rgbdquad::quadcontrol {

namespace asio = boost::asio;
namespace proto = rgbdquad::protocol;

namespace {
constexpr const char* kPeerName = "quad-control";
constexpr std::size_t kReadChunkBytes = 64 * 1024;

Eigen::Isometry3d to_isometry(const proto::Pose3& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(p.q_xyzw[3], p.q_xyzw[0], p.q_xyzw[1], p.q_xyzw[2]).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.t_m[0], p.t_m[1], p.t_m[2]);
  return T;
}

const char* state_name(proto::TrackingState s) {
  switch (s) {
    case proto::TrackingState::kInitializing: return "initialising";
    case proto::TrackingState::kTracking: return "tracking";
    case proto::TrackingState::kLost: return "lost";
    case proto::TrackingState::kRelocalized: return "relocalised";
  }
  return "?";
}

proto::ImageFrame image(const CameraFrame& f, proto::PixelFormat format, std::vector<std::uint8_t> payload) {
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

std::string SlamServerOptions::validate() const {
  if (host.empty() || port == 0) return "slam.host/slam.port must be set";
  if (reply_timeout_ms < 10 || reconnect_interval_ms < 10) return "slam timeouts must be >= 10 ms";
  return {};
}

SlamServerClient::SlamServerClient(SlamServerOptions options, Callback callback)
    : options_(std::move(options)), callback_(std::move(callback)), socket_(io_) {
  thread_ = std::thread([this] { run(); });
}

SlamServerClient::~SlamServerClient() {
  stop_ = true;
  mailbox_.close();
  const int fd = socket_fd_.load();
  if (fd >= 0) ::shutdown(fd, SHUT_RDWR);  // unblocks a read in progress
  if (thread_.joinable()) thread_.join();
}

std::string SlamServerClient::name() const {
  return "slam-server at " + options_.host + ":" + std::to_string(options_.port);
}

bool SlamServerClient::submit(const CameraFrame& frame) { return mailbox_.offer(frame); }

SlamStats SlamServerClient::stats() const { return mailbox_.stats(); }

void SlamServerClient::disconnect() {
  socket_fd_ = -1;
  boost::system::error_code ignored;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  socket_.close(ignored);
  connected_ = false;
  decoder_ = proto::StreamDecoder{};
}

bool SlamServerClient::send(const proto::Message& message, std::string* error) {
  const auto encoded = proto::encode(message);
  if (!encoded.ok()) {
    *error = "encode: " + encoded.error;
    return false;
  }
  boost::system::error_code ec;
  asio::write(socket_, asio::buffer(encoded.bytes), ec);
  if (ec) {
    *error = "send: " + ec.message();
    return false;
  }
  return true;
}

std::optional<proto::Message> SlamServerClient::receive(std::string* error) {
  std::vector<std::uint8_t> buf(kReadChunkBytes);
  while (!stop_) {
    auto r = decoder_.next();
    if (r.status == proto::DecodeStatus::kMessage) return r.message;
    if (r.status == proto::DecodeStatus::kError) {
      mailbox_.note_error(std::string("dropped bytes: ") + proto::to_string(r.error) + " " + r.detail);
      continue;
    }
    boost::system::error_code ec;
    const std::size_t n = socket_.read_some(asio::buffer(buf), ec);  // SO_RCVTIMEO bounds the wait
    if (ec) {
      *error = ec == asio::error::would_block || ec == asio::error::try_again
                   ? "no reply within " + std::to_string(options_.reply_timeout_ms) + " ms"
                   : "receive: " + ec.message();
      return std::nullopt;
    }
    decoder_.feed(buf.data(), n);
  }
  *error = "stopping";
  return std::nullopt;
}

bool SlamServerClient::connect(std::string* error) {
  asio::ip::tcp::resolver resolver(io_);
  boost::system::error_code ec;
  const auto endpoints = resolver.resolve(options_.host, std::to_string(options_.port), ec);
  if (!ec) asio::connect(socket_, endpoints, ec);
  if (ec) {
    *error = "cannot connect to " + name() + ": " + ec.message();
    disconnect();
    return false;
  }
  socket_fd_ = socket_.native_handle();
  timeval tv{options_.reply_timeout_ms / 1000, (options_.reply_timeout_ms % 1000) * 1000};
  ::setsockopt(socket_.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);
  proto::SlamHello hello;
  hello.peer_name = kPeerName;
  if (!send(hello, error)) {
    disconnect();
    return false;
  }
  auto reply = receive(error);
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
  if (const std::string why = proto::hello_incompatibility(*peer); !why.empty()) {
    *error = "slam-server is incompatible: " + why;
    disconnect();
    return false;
  }
  connected_ = true;
  ++session_;
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
  m.rgb = image(f, proto::PixelFormat::kRgb8, std::move(rgb));
  m.depth = image(f, proto::PixelFormat::kDepth16, std::move(depth));
  if (!send(m, error)) return std::nullopt;
  while (true) {
    auto reply = receive(error);
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
    return r;
  }
}

void SlamServerClient::run() {
  while (auto taken = mailbox_.take()) {
    const CameraFrame& frame = *taken;
    std::string error;
    std::optional<SlamResult> result;
    const std::int64_t now = monotonic_now_us();
    if (!connected_ && now - last_attempt_us_ >= options_.reconnect_interval_ms * 1000LL) {
      last_attempt_us_ = now;
      if (!connect(&error)) last_connect_error_ = error;
    }
    if (connected_) {
      result = exchange(frame, &error);
      if (!result) {
        std::cerr << "quad-control: SLAM link: " << error << "; reconnecting (a new SLAM session)" << std::endl;
        disconnect();
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
