// libFuzzer target: slam-server's socket-free serving path - SlamConnection (bytes in, bytes out,
// deadlines), SessionRegistry (sessions, resume, take-over) and SlamLinkSession (RgbdFrame ->
// exactly one PoseUpdate) - with the SLAM engine replaced by a scripted fake behind
// SessionPipeline (slam_link_session.hpp). Two client connections share one registry. The input
// scripts both sides: what the clients send (valid SlamHello / RgbdFrame messages with hostile
// fields - sizes, encodings, intrinsics, depth scale, session ids, versions - other message
// types, garbage, all delivered in chunks at advancing times) and what the fake pipeline answers
// (ok or rejected, tracking state, poses that are fine, non-finite, huge, not a rotation, or a
// rotation that is one only to rounding; records missing; exceptions).
// Properties (abort on violation):
//   * the server's output always decodes without error into SlamHello and PoseUpdate messages
//     that pass the spec's checks, nothing after a closing cause;
//   * one PoseUpdate per RgbdFrame the connection took (the connection's frame count), with that
//     frame's pair_sequence, in order;
//   * an update says TRACKING only for a frame the pipeline tracked with a pose that fits the
//     wire, and then carries that pose; every faulted frame is LOST with 0 inliers;
//   * a frame the pipeline tracked with a pose that fits the wire is answered TRACKING;
//   * the pipeline only ever gets RGB8/DEPTH16 images of equal, non-zero size whose pixels are
//     the frame's (RGB->BGR, little-endian depth). (The fake refuses invalid intrinsics as
//     Pipeline::create does, through Intrinsics::is_valid, and sometimes refuses valid ones.)
//   * deadlines are consistent: timed_out(now) is set exactly when next_deadline_ms() <= now;
//     after expire(now) no parked session's expiry is at or before now.
#include <fuzzer/FuzzedDataProvider.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rgbdquad/protocol/codec.hpp"
#include "slam_connection.hpp"
#include "slam_link_session.hpp"
#include "slam_sessions.hpp"

namespace slam = rgbdquad::slam;
namespace slamlink = rgbdquad::slamlink;

namespace {

namespace proto = rgbdquad::protocol;

constexpr int kMaxSteps = 96;
constexpr int kConnections = 2;
constexpr std::uint16_t kMaxSide_px = 6;  // tiny images: the pipeline is fake, the sizes matter
constexpr double kPoseTolerance = 1e-9;

void require(bool ok) {
  if (!ok) std::abort();
}

/// What the fake pipeline answered for one submitted frame.
struct Verdict {
  bool threw = false;
  bool has_record = true;
  slam::FrameRecord record;
};

/// The script of the fake pipeline: the fuzzer's bytes decide each verdict.
class FakePipeline final : public slamlink::SessionPipeline {
 public:
  FakePipeline(FuzzedDataProvider& in, std::map<std::uint32_t, Verdict>* verdicts)
      : in_(in), verdicts_(verdicts) {}

  void submit(slam::RgbdFrame frame) override {
    // The session hands over only consistent images.
    require(!frame.rgb.empty() && frame.rgb.type() == CV_8UC3 && frame.depth.type() == CV_16UC1);
    require(frame.rgb.size() == frame.depth.size());
    expected_pixels_check(frame);
    Verdict v;
    v.threw = in_.ConsumeIntegralInRange<int>(0, 15) == 0;
    v.has_record = in_.ConsumeIntegralInRange<int>(0, 15) != 0;
    v.record.index = frame.index;
    v.record.ok = in_.ConsumeIntegralInRange<int>(0, 7) != 0;
    v.record.error = v.record.ok ? "" : "rejected by the fake";
    v.record.state = static_cast<slam::TrackingState>(in_.ConsumeIntegralInRange<int>(0, 2));
    v.record.T_world_cam = pose(in_);
    v.record.T_prev_cur = pose(in_);
    v.record.keyframe = in_.ConsumeBool();
    v.record.inliers = in_.ConsumeIntegralInRange<std::size_t>(0, 5000);
    // The harness stamps every frame with its pair sequence as capture time (exact in a double).
    (*verdicts_)[static_cast<std::uint32_t>(std::llround(frame.stamp_s * 1e6))] = v;
    if (v.threw) throw std::runtime_error("fake pipeline threw");
    if (v.has_record)
      records_[frame.index] = v.record;
    else
      records_.erase(frame.index);
  }
  std::optional<slam::FrameRecord> record(std::int64_t index) const override {
    const auto it = records_.find(index);
    if (it == records_.end()) return std::nullopt;
    return it->second;
  }
  bool load_map(const std::string&, std::string* error) override {
    if (error) *error = "fake: no maps";
    return false;
  }
  bool save_map(const std::string&, std::string* error) const override {
    if (error) *error = "fake: no maps";
    return false;
  }
  void finish() override {}
  slam::PipelineSummary summary() const override { return {}; }
  bool start_tables(const std::string&, std::string* error) override {
    if (error) *error = "fake: no tables";
    return false;
  }
  bool finish_tables(std::string* error) override {
    if (error) *error = "fake: no tables";
    return false;
  }

  /// Set by the harness before a frame is processed: its first pixel as sent.
  static inline std::optional<std::array<std::uint8_t, 5>> next_first_pixel;

 private:
  static void expected_pixels_check(const slam::RgbdFrame& frame) {
    if (!next_first_pixel) return;
    const auto& p = *next_first_pixel;
    const cv::Vec3b bgr = frame.rgb.at<cv::Vec3b>(0, 0);
    require(bgr[0] == p[2] && bgr[1] == p[1] && bgr[2] == p[0]);
    require(frame.depth.at<std::uint16_t>(0, 0) == static_cast<std::uint16_t>(p[3] | (p[4] << 8)));
  }

  static Eigen::Isometry3d pose(FuzzedDataProvider& in) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const Eigen::Quaterniond q(in.ConsumeFloatingPointInRange<double>(-1, 1),
                               in.ConsumeFloatingPointInRange<double>(-1, 1),
                               in.ConsumeFloatingPointInRange<double>(-1, 1),
                               in.ConsumeFloatingPointInRange<double>(-1, 1));
    if (q.norm() > 1e-6) T.linear() = q.normalized().toRotationMatrix();
    static const double kHostile[] = {std::numeric_limits<double>::quiet_NaN(),
                                      std::numeric_limits<double>::infinity(),
                                      1e300,
                                      -1e6,
                                      99999.0,
                                      100001.0,
                                      1.0000000000000002,
                                      2.0};
    for (int i = 0; i < 3; ++i)
      T.translation()[i] = in.ConsumeFloatingPointInRange<double>(-5.0, 5.0);
    switch (in.ConsumeIntegralInRange<int>(0, 9)) {
      case 0:
        T.translation()[in.ConsumeIntegralInRange<int>(0, 2)] =
            kHostile[in.ConsumeIntegralInRange<int>(0, 5)];
        break;
      case 1:
        T.linear() *= kHostile[in.ConsumeIntegralInRange<int>(6, 7)];
        break;  // scaled: not a rotation
      case 2:
        T.linear()(in.ConsumeIntegralInRange<int>(0, 2), in.ConsumeIntegralInRange<int>(0, 2)) +=
            in.ConsumeFloatingPointInRange<double>(-1e-12, 1e-12);
        break;  // a rotation to rounding
      case 3:
        T.linear()(0, 0) = kHostile[in.ConsumeIntegralInRange<int>(0, 1)];
        break;
      default:
        break;
    }
    return T;
  }

  FuzzedDataProvider& in_;
  std::map<std::uint32_t, Verdict>* verdicts_;
  std::map<std::int64_t, slam::FrameRecord> records_;
};

/// The wire form a pose must take (an independent statement of pose_to_wire's contract).
std::optional<Eigen::Quaterniond> wire_rotation(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return std::nullopt;
  const Eigen::Quaterniond q(T.linear());
  if (!(std::fabs(q.norm() - 1.0) <= 1e-3)) return std::nullopt;
  for (int i = 0; i < 3; ++i) {
    const double t = T.translation()[i];
    if (!(t >= proto::field_range::kPose3TM.lo && t <= proto::field_range::kPose3TM.hi))
      return std::nullopt;
  }
  return q.normalized();
}

bool same_rotation(const Eigen::Quaterniond& a, const std::array<double, 4>& b_xyzw) {
  const double dot = a.x() * b_xyzw[0] + a.y() * b_xyzw[1] + a.z() * b_xyzw[2] + a.w() * b_xyzw[3];
  return std::fabs(std::fabs(dot) - 1.0) <= 1e-9;
}

struct Client {
  std::unique_ptr<slamlink::SlamConnection> conn;
  std::deque<std::uint32_t> frames_sent;  ///< pair sequences of well-formed frames, in order
  proto::StreamDecoder replies;
  std::size_t updates = 0;
};

proto::SlamHello hello(FuzzedDataProvider& in) {
  proto::SlamHello h;
  h.peer_name = "quad-control";
  static const std::uint64_t kIds[] = {0, 1, 2, 3, 0x5E55000000000001ull};
  h.session_id = kIds[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kIds) - 1)];
  switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0:
      h.protocol_version = static_cast<std::uint16_t>(h.protocol_version + 1);
      break;
    case 1:
      h.schema_hash ^= 1;
      break;
    default:
      break;
  }
  return h;
}

proto::RgbdFrame frame(FuzzedDataProvider& in, std::uint32_t pair_sequence) {
  proto::RgbdFrame f;
  f.pair_sequence = pair_sequence;
  static const double kValues[] = {525.0, 517.3, 1.0, 0.0, -1.0, 1e-300, 1e6, 5000.0, 1000.0};
  const auto pick = [&] {
    return kValues[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kValues) - 1)];
  };
  f.intrinsics.fx_px = in.ConsumeBool() ? 525.0 : pick();
  f.intrinsics.fy_px = in.ConsumeBool() ? 525.0 : pick();
  f.intrinsics.cx_px = pick();
  f.intrinsics.cy_px = pick();
  f.depth_scale_units_per_m = in.ConsumeBool() ? 5000.0 : pick();
  f.attitude.valid = in.ConsumeBool();
  if (in.ConsumeIntegralInRange<int>(0, 3) == 0)
    f.attitude.q_xyzw = {pick(), pick(), pick(), pick()};
  const std::uint16_t w = in.ConsumeIntegralInRange<std::uint16_t>(0, kMaxSide_px);
  const std::uint16_t h = in.ConsumeIntegralInRange<std::uint16_t>(0, kMaxSide_px);
  const bool consistent = in.ConsumeIntegralInRange<int>(0, 3) != 0;
  for (proto::ImageFrame* img : {&f.rgb, &f.depth}) {
    const bool rgb = img == &f.rgb;
    img->header.sequence = pair_sequence;
    img->header.capture_timestamp_us = pair_sequence;  // names the frame for the fake pipeline
    img->header.width = consistent ? w : in.ConsumeIntegralInRange<std::uint16_t>(0, kMaxSide_px);
    img->header.height = consistent ? h : in.ConsumeIntegralInRange<std::uint16_t>(0, kMaxSide_px);
    img->header.pixel_format = rgb ? proto::PixelFormat::kRgb8 : proto::PixelFormat::kDepth16;
    if (!consistent && in.ConsumeBool())
      img->header.pixel_format = proto::PixelFormat(in.ConsumeIntegralInRange<int>(0, 1));
    img->header.encoding = in.ConsumeIntegralInRange<int>(0, 7) == 0
                               ? proto::Encoding(in.ConsumeIntegralInRange<int>(0, 3))
                               : proto::Encoding::kRaw;
    std::size_t bytes =
        static_cast<std::size_t>(img->header.width) * img->header.height * (rgb ? 3 : 2);
    if (!consistent && in.ConsumeBool())
      bytes = in.ConsumeIntegralInRange<std::size_t>(0, 3 * kMaxSide_px * kMaxSide_px);
    img->payload = in.ConsumeBytes<std::uint8_t>(bytes);
    img->payload.resize(bytes, 0x5a);
    img->header.payload_length = static_cast<std::uint32_t>(bytes);
  }
  return f;
}

/// Reads every reply the server queued for `c`, checks it, and marks it consumed.
void take_output(Client& c, std::int64_t now_ms, const std::map<std::uint32_t, Verdict>& verdicts) {
  const auto& out = c.conn->output();
  c.replies.feed(out.data(), out.size());
  c.conn->consumed_output(out.size(), now_ms);
  for (;;) {
    proto::DecodeResult r = c.replies.next();
    if (r.status == proto::DecodeStatus::kNeedMoreBytes) break;
    require(r.status == proto::DecodeStatus::kMessage);
    require(proto::validate(*r.message).empty());
    if (std::holds_alternative<proto::SlamHello>(*r.message)) continue;
    const auto* u = std::get_if<proto::PoseUpdate>(&*r.message);
    require(u != nullptr);
    // In order, one per frame taken: the pair sequence of a frame this client sent.
    while (!c.frames_sent.empty() && c.frames_sent.front() != u->pair_sequence)
      c.frames_sent.pop_front();
    require(!c.frames_sent.empty());
    c.frames_sent.pop_front();
    ++c.updates;
    require(u->timestamp_us == u->pair_sequence);
    // The pipeline's verdict on this frame (none when the session refused it before the pipeline).
    const auto it = verdicts.find(u->pair_sequence);
    const Verdict* v = it == verdicts.end() ? nullptr : &it->second;
    const bool tracked = v && !v->threw && v->has_record && v->record.ok &&
                         v->record.state == slam::TrackingState::kTracking;
    const auto q = tracked ? wire_rotation(v->record.T_world_cam) : std::nullopt;
    const bool sendable = q && wire_rotation(v->record.T_prev_cur);
    require((u->tracking_state == proto::TrackingState::kTracking) == (tracked && sendable));
    if (u->tracking_state == proto::TrackingState::kTracking) {
      for (int i = 0; i < 3; ++i) {
        require(std::fabs(u->T_world_cam.t_m[i] - v->record.T_world_cam.translation()[i]) <=
                kPoseTolerance);
      }
      require(same_rotation(*q, u->T_world_cam.q_xyzw));
      require(u->inlier_count == v->record.inliers && u->is_keyframe == v->record.keyframe);
    }
    if (!v || v->threw || !v->has_record || !v->record.ok) {
      require(u->tracking_state == proto::TrackingState::kLost && u->inlier_count == 0 &&
              !u->is_keyframe);
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  std::map<std::uint32_t, Verdict> verdicts;
  slamlink::PipelineFactory factory =
      [&](const slam::PipelineOptions&, const slam::Intrinsics& k,
          std::string* error) -> std::unique_ptr<slamlink::SessionPipeline> {
    if (!k.is_valid(error)) return nullptr;  // as Pipeline::create (FeatureExtractor::create)
    if (in.ConsumeIntegralInRange<int>(0, 15) == 0) {
      if (error) *error = "fake: refused";
      return nullptr;
    }
    return std::make_unique<FakePipeline>(in, &verdicts);
  };
  slamlink::SessionRegistryOptions ropt;
  ropt.max_sessions = 2;
  ropt.resume_grace_ms = 3000;
  slamlink::SessionRegistry registry(ropt, [&](const slamlink::SessionStart&) {
    return std::make_unique<slamlink::SlamLinkSession>(slam::PipelineOptions{},
                                                       slamlink::SessionMapFiles{}, factory);
  });
  slamlink::ConnectionOptions copt;
  copt.hello_timeout_ms = 500;
  copt.idle_timeout_ms = 2000;
  copt.message_timeout_ms = 1000;
  copt.write_timeout_ms = 1000;

  std::int64_t now_ms = 0;
  std::uint32_t next_pair = 0;
  Client clients[kConnections];
  int next_id = 1;
  for (Client& c : clients)
    c.conn = std::make_unique<slamlink::SlamConnection>(next_id++, "peer", copt, now_ms);

  for (int step = 0; step < kMaxSteps && in.remaining_bytes() > 0; ++step) {
    Client& c = clients[in.ConsumeIntegralInRange<int>(0, kConnections - 1)];
    now_ms += in.ConsumeIntegralInRange<std::int64_t>(0, 700);
    std::vector<std::uint8_t> bytes;
    FakePipeline::next_first_pixel.reset();
    switch (in.ConsumeIntegralInRange<int>(0, 9)) {
      case 0:
      case 1:
        bytes = proto::encode(proto::Message{hello(in)}).bytes;
        break;
      case 2:
        bytes = in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 64));
        break;
      case 3: {
        proto::PoseUpdate stray;  // a message that is not for the server
        bytes = proto::encode(proto::Message{stray}).bytes;
        break;
      }
      default: {
        const proto::RgbdFrame f = frame(in, next_pair++);
        const proto::EncodeResult e = proto::encode(proto::Message{f});
        if (!e.ok()) continue;  // the codec refuses it: a client cannot send it either
        bytes = e.bytes;
        c.frames_sent.push_back(f.pair_sequence);
        if (!f.rgb.payload.empty() && f.depth.payload.size() >= 2)
          FakePipeline::next_first_pixel =
              std::array<std::uint8_t, 5>{f.rgb.payload[0], f.rgb.payload[1], f.rgb.payload[2],
                                          f.depth.payload[0], f.depth.payload[1]};
      }
    }
    // Delivered in up to three chunks, the rest perhaps later (a dripping or stalled peer).
    std::size_t sent = 0;
    const int chunks = in.ConsumeIntegralInRange<int>(1, 3);
    for (int i = 0; i < chunks && sent < bytes.size(); ++i) {
      const std::size_t n = i + 1 == chunks
                                ? bytes.size() - sent
                                : in.ConsumeIntegralInRange<std::size_t>(0, bytes.size() - sent);
      c.conn->on_bytes(bytes.data() + sent, n, now_ms);
      sent += n;
      std::vector<int> displaced;
      std::vector<std::string> log;
      bool flush_first = false;
      const auto cause = c.conn->process(registry, now_ms, &displaced, &log, &flush_first);
      take_output(c, now_ms, verdicts);
      require(c.updates == c.conn->frames());
      for (int id : displaced)
        for (Client& o : clients)
          if (o.conn->id() == id) {  // closed by the server loop: a new connection takes its place
            registry.detach(id, now_ms);
            o = Client{};
            o.conn = std::make_unique<slamlink::SlamConnection>(next_id++, "peer", copt, now_ms);
          }
      if (cause) {
        require(!cause->empty());
        registry.detach(c.conn->id(), now_ms);
        c = Client{};
        c.conn = std::make_unique<slamlink::SlamConnection>(next_id++, "peer", copt, now_ms);
        break;
      }
    }
    for (Client& o : clients) {
      const bool late = o.conn->timed_out(now_ms).has_value();
      require(late == (o.conn->next_deadline_ms() <= now_ms));
      if (late) {
        registry.detach(o.conn->id(), now_ms);
        o = Client{};
        o.conn = std::make_unique<slamlink::SlamConnection>(next_id++, "peer", copt, now_ms);
      }
    }
    registry.expire(now_ms);
    const auto expiry = registry.next_expiry_ms();  // the server's poll timeout: never in the past
    require(!expiry || *expiry > now_ms);
  }
  registry.finish_all();
  return 0;
}
