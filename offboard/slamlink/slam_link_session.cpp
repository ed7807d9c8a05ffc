// SLAM-link session: SlamHello / RgbdFrame -> PoseUpdate.
#include "slam_link_session.hpp"

#include <cstring>
#include <opencv2/imgproc.hpp>

#include "rgbdquad/protocol/codec.hpp"

namespace slam {

namespace proto = rgbdquad::protocol;

namespace {
proto::Pose3 to_pose3(const Eigen::Isometry3d& T) {
  proto::Pose3 p;
  const Eigen::Quaterniond q(T.rotation());
  p.t_m = {T.translation().x(), T.translation().y(), T.translation().z()};
  p.q_xyzw = {q.x(), q.y(), q.z(), q.w()};
  return p;
}

proto::TrackingState to_wire(TrackingState s) {
  switch (s) {
    case TrackingState::kInitialising: return proto::TrackingState::kInitializing;
    case TrackingState::kTracking: return proto::TrackingState::kTracking;
    case TrackingState::kLost: return proto::TrackingState::kLost;
  }
  return proto::TrackingState::kLost;
}
}  // namespace

SlamLinkSession::SlamLinkSession(PipelineOptions options, std::string server_name)
    : options_(std::move(options)), server_name_(std::move(server_name)) {
  options_.mode = PipelineMode::kSequential;
}

std::optional<RgbdFrame> SlamLinkSession::to_frame(const proto::RgbdFrame& m, std::string* error) const {
  const auto& rh = m.rgb.header;
  const auto& dh = m.depth.header;
  if (rh.encoding != proto::Encoding::kRaw || dh.encoding != proto::Encoding::kRaw) {
    if (error) *error = "slam-link: only RAW image encodings are supported by slam-server";
    return std::nullopt;
  }
  if (rh.pixel_format != proto::PixelFormat::kRgb8 || dh.pixel_format != proto::PixelFormat::kDepth16 ||
      rh.width != dh.width || rh.height != dh.height || rh.width == 0 || rh.height == 0) {
    if (error) *error = "slam-link: need RGB8 and DEPTH16 images of the same non-zero size";
    return std::nullopt;
  }
  const std::size_t n = static_cast<std::size_t>(rh.width) * rh.height;
  if (m.rgb.payload.size() != 3 * n || m.depth.payload.size() != 2 * n) {
    if (error) *error = "slam-link: payload size does not match width x height";
    return std::nullopt;
  }
  RgbdFrame f;
  f.index = static_cast<std::int64_t>(frames_);
  f.stamp_s = static_cast<double>(dh.capture_timestamp_us) * 1e-6;
  cv::Mat rgb(rh.height, rh.width, CV_8UC3, const_cast<std::uint8_t*>(m.rgb.payload.data()));
  cv::cvtColor(rgb, f.rgb, cv::COLOR_RGB2BGR);  // copies
  f.depth.create(dh.height, dh.width, CV_16UC1);
  const std::uint8_t* src = m.depth.payload.data();
  for (std::size_t i = 0; i < n; ++i)  // little-endian on the wire
    f.depth.ptr<std::uint16_t>()[i] = static_cast<std::uint16_t>(src[2 * i] | (src[2 * i + 1] << 8));
  return f;
}

std::vector<proto::Message> SlamLinkSession::on_message(const proto::Message& message,
                                                        std::string* error, bool* fatal) {
  std::vector<proto::Message> out;
  if (fatal) *fatal = false;
  if (const auto* hello = std::get_if<proto::SlamHello>(&message)) {
    const std::string why = proto::hello_incompatibility(*hello);
    if (!why.empty()) {
      if (error) *error = "slam-link: incompatible peer '" + hello->peer_name + "': " + why;
      if (fatal) *fatal = true;
      return out;
    }
    hello_received_ = true;
    proto::SlamHello reply;
    reply.peer_name = server_name_;
    out.emplace_back(reply);
    return out;
  }
  const auto* frame = std::get_if<proto::RgbdFrame>(&message);
  if (!frame) {
    if (error) *error = "slam-link: unexpected message type for slam-server (ignored)";
    return out;
  }
  if (!hello_received_) {
    if (error) *error = "slam-link: RgbdFrame before SlamHello (ignored)";
    return out;
  }
  if (!pipeline_) {
    Intrinsics k;
    k.fx_px = frame->intrinsics.fx_px;
    k.fy_px = frame->intrinsics.fy_px;
    k.cx_px = frame->intrinsics.cx_px;
    k.cy_px = frame->intrinsics.cy_px;
    k.distortion = frame->intrinsics.distortion;
    k.depth_units_per_m = frame->depth_scale_units_per_m;
    std::string err;
    pipeline_ = Pipeline::create(options_, k, &err);
    if (!pipeline_) {
      if (error) *error = "slam-link: cannot start the pipeline: " + err;
      return out;
    }
    intrinsics_ = k;
  }
  auto f = to_frame(*frame, error);
  if (!f) return out;
  const std::int64_t index = f->index;
  pipeline_->submit(std::move(*f));
  ++frames_;
  auto rec = pipeline_->record(index);
  if (!rec || !rec->ok) {
    if (error) *error = "slam-link: frame rejected: " + (rec ? rec->error : std::string("no record"));
    return out;
  }
  proto::PoseUpdate u;
  u.pair_sequence = frame->pair_sequence;
  u.timestamp_us = frame->rgb.header.capture_timestamp_us;
  u.tracking_state = to_wire(rec->state);
  u.T_world_cam = to_pose3(rec->T_world_cam);
  u.T_prev_cur = to_pose3(rec->T_prev_cur);
  u.is_keyframe = rec->keyframe;
  u.inlier_count = static_cast<std::uint32_t>(rec->inliers);
  out.emplace_back(u);
  return out;
}

}  // namespace slam
