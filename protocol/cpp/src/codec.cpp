// Codecs of every message in protocol/spec/messages.json: structural encode/decode of each field in
// spec order (explicit little-endian), one validate() per message holding every value rule (the
// encoder and the decoder both run it), and the envelope with its incremental StreamDecoder.
#include "rgbdquad/protocol/codec.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <type_traits>

#include "wire.hpp"

namespace rgbdquad::protocol {
namespace {

using wire::Reader;
using wire::Writer;

// |q|^2 may differ from 1 by this much: doubles normalised by any sane code are within 1e-15;
// 2e-6 on |q|^2 is 1e-6 on |q| (spec Pose3 check unit_quaternion).
constexpr double kUnitQuaternionTolerance = 2e-6;

// CRC-32 tables for slicing-by-8 (8 bytes per step; table[0] is the classic bytewise table).
constexpr std::array<std::array<std::uint32_t, 256>, 8> make_crc_tables() {
  std::array<std::array<std::uint32_t, 256>, 8> tables{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    tables[0][i] = c;
  }
  for (std::uint32_t i = 0; i < 256; ++i) {
    for (std::size_t s = 1; s < 8; ++s) {
      tables[s][i] = (tables[s - 1][i] >> 8) ^ tables[0][tables[s - 1][i] & 0xFFu];
    }
  }
  return tables;
}
constexpr std::array<std::array<std::uint32_t, 256>, 8> kCrcTables = make_crc_tables();

std::size_t bytes_per_pixel(PixelFormat format) { return format == PixelFormat::kRgb8 ? 3 : 2; }

// ---------------------------------------------------------------- value checks (validate)
// Each returns "" when fine, else "<field>: <reason>"; the first failure wins.

std::string check_range(double v, FieldRange range, const char* field) {
  const double lo = range.lo;
  const double hi = range.hi;
  if (v >= lo && v <= hi) return {};  // false for NaN
  char buf[160];
  std::snprintf(buf, sizeof buf, "%s: %g outside [%g, %g] or not finite", field, v, lo, hi);
  return buf;
}

std::string check_int_range(std::uint64_t v, FieldRange range, const char* field) {
  const auto lo = static_cast<std::uint64_t>(range.lo);
  const auto hi = static_cast<std::uint64_t>(range.hi);
  if (v >= lo && v <= hi) return {};
  char buf[160];
  std::snprintf(buf, sizeof buf, "%s: %llu outside [%llu, %llu]", field,
                static_cast<unsigned long long>(v), static_cast<unsigned long long>(lo),
                static_cast<unsigned long long>(hi));
  return buf;
}

std::string check_string(const std::string& s, const char* field) {
  if (s.size() > kMaxStringBytes) return std::string(field) + ": longer than kMaxStringBytes";
  for (char c : s) {
    if (c < 0x20 || c > 0x7e) return std::string(field) + ": not printable ASCII";
  }
  return {};
}

#define RGBD_CHECK(expr)                    \
  do {                                      \
    std::string rgbd_err = expr;            \
    if (!rgbd_err.empty()) return rgbd_err; \
  } while (false)

std::string check_intrinsics(const CameraIntrinsics& k) {
  RGBD_CHECK(check_range(k.fx_px, field_range::kCameraIntrinsicsFxPx, "intrinsics.fx_px"));
  RGBD_CHECK(check_range(k.fy_px, field_range::kCameraIntrinsicsFyPx, "intrinsics.fy_px"));
  RGBD_CHECK(check_range(k.cx_px, field_range::kCameraIntrinsicsCxPx, "intrinsics.cx_px"));
  RGBD_CHECK(check_range(k.cy_px, field_range::kCameraIntrinsicsCyPx, "intrinsics.cy_px"));
  for (double d : k.distortion)
    RGBD_CHECK(check_range(d, field_range::kCameraIntrinsicsDistortion, "intrinsics.distortion"));
  return {};
}

std::string check_image(const FrameHeader& h, std::size_t payload_size, const char* field) {
  const std::string prefix = std::string(field) + ".";
  RGBD_CHECK(check_int_range(h.width, field_range::kImageFrameWidth, (prefix + "width").c_str()));
  RGBD_CHECK(
      check_int_range(h.height, field_range::kImageFrameHeight, (prefix + "height").c_str()));
  if (!is_valid_pixel_format(static_cast<std::uint8_t>(h.pixel_format)))
    return prefix + "pixel_format: unknown value";
  if (!is_valid_encoding(static_cast<std::uint8_t>(h.encoding)))
    return prefix + "encoding: unknown value";
  if (!encoding_allows_pixel_format(h.encoding, h.pixel_format))
    return prefix + "encoding: does not carry this pixel_format";
  if (payload_size > kMaxFramePayloadBytes) return prefix + "payload: too large";
  if (h.payload_length != payload_size) return prefix + "payload_length: differs from payload size";
  if (h.encoding == Encoding::kRaw) {
    const std::size_t expected =
        std::size_t{h.width} * std::size_t{h.height} * bytes_per_pixel(h.pixel_format);
    if (payload_size != expected) return prefix + "payload: RAW size != width*height*bpp";
  }
  return {};
}

std::string check_image(const ImageFrame& f, const char* field) {
  return check_image(f.header, f.payload.size(), field);
}

// Range of each element and |q|^2 (spec check unit_quaternion), reported as `<prefix>q_xyzw`.
std::string check_unit_quaternion(const std::array<double, 4>& q, const FieldRange& range,
                                  const std::string& prefix) {
  for (double e : q) RGBD_CHECK(check_range(e, range, (prefix + "q_xyzw").c_str()));
  const double norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  if (!(std::fabs(norm2 - 1.0) <= kUnitQuaternionTolerance))
    return prefix + "q_xyzw: not a unit quaternion";
  return {};
}

std::string check_pose(const Pose3& p, const char* field) {
  const std::string prefix = std::string(field) + ".";
  for (double t : p.t_m)
    RGBD_CHECK(check_range(t, field_range::kPose3TM, (prefix + "t_m").c_str()));
  return check_unit_quaternion(p.q_xyzw, field_range::kPose3QXyzw, prefix);
}

std::string check_stream_kind(StreamKind kind, PixelFormat format) {
  const bool match = (kind == StreamKind::kRgb && format == PixelFormat::kRgb8) ||
                     (kind == StreamKind::kDepth && format == PixelFormat::kDepth16);
  return match ? std::string{} : std::string("pixel_format: does not match stream_kind");
}

std::string validate_one(const Handshake& m) {
  if (!is_valid_stream_kind(static_cast<std::uint8_t>(m.stream_kind)))
    return "stream_kind: unknown value";
  RGBD_CHECK(check_int_range(m.width, field_range::kHandshakeWidth, "width"));
  RGBD_CHECK(check_int_range(m.height, field_range::kHandshakeHeight, "height"));
  if (!is_valid_pixel_format(static_cast<std::uint8_t>(m.pixel_format)))
    return "pixel_format: unknown value";
  if (!is_valid_encoding(static_cast<std::uint8_t>(m.encoding))) return "encoding: unknown value";
  if (!encoding_allows_pixel_format(m.encoding, m.pixel_format))
    return "encoding: does not carry this pixel_format";
  RGBD_CHECK(check_stream_kind(m.stream_kind, m.pixel_format));
  RGBD_CHECK(check_intrinsics(m.intrinsics));
  RGBD_CHECK(check_range(m.depth_scale_units_per_m, field_range::kHandshakeDepthScaleUnitsPerM,
                         "depth_scale_units_per_m"));
  return check_string(m.device_id, "device_id");
}

std::string validate_one(const HandshakeAck& m) { return check_string(m.reason, "reason"); }
std::string validate_one(const StreamChallenge&) { return {}; }  // any 16 bytes

std::string check_accel(const AccelSample& a, const char* field) {
  const std::string prefix = std::string(field) + ".f_mps2";
  for (double f : a.f_mps2)
    RGBD_CHECK(check_range(f, field_range::kAccelSampleFMps2, prefix.c_str()));
  return {};
}

std::string validate_one(const Frame& m) {
  RGBD_CHECK(check_image(m.image, "image"));
  return check_accel(m.accel, "accel");
}

std::string validate_one(const FrameRequest& m) {
  return check_int_range(m.credits, field_range::kFrameRequestCredits, "credits");
}

std::string validate_one(const SlamHello& m) {
  RGBD_CHECK(check_string(m.peer_name, "peer_name"));
  return check_string(m.refusal, "refusal");
}

std::string validate_one(const RgbdFrame& m) {
  RGBD_CHECK(check_intrinsics(m.intrinsics));
  RGBD_CHECK(check_range(m.depth_scale_units_per_m, field_range::kRgbdFrameDepthScaleUnitsPerM,
                         "depth_scale_units_per_m"));
  RGBD_CHECK(
      check_unit_quaternion(m.attitude.q_xyzw, field_range::kCameraAttitudeQXyzw, "attitude."));
  RGBD_CHECK(check_image(m.rgb, "rgb"));
  RGBD_CHECK(check_image(m.depth, "depth"));
  if (m.rgb.header.pixel_format != PixelFormat::kRgb8) return "rgb.pixel_format: must be RGB8";
  if (m.depth.header.pixel_format != PixelFormat::kDepth16)
    return "depth.pixel_format: must be DEPTH16";
  return check_accel(m.accel, "accel");
}

std::string validate_one(const PoseUpdate& m) {
  if (!is_valid_tracking_state(static_cast<std::uint8_t>(m.tracking_state)))
    return "tracking_state: unknown value";
  RGBD_CHECK(check_pose(m.T_world_cam, "T_world_cam"));
  return check_pose(m.T_prev_cur, "T_prev_cur");
}

std::string validate_one(const PoseGraph& m) {
  if (!is_valid_graph_stage(static_cast<std::uint8_t>(m.stage))) return "stage: unknown value";
  if (m.nodes.size() > kMaxGraphNodes) return "nodes: more than kMaxGraphNodes";
  if (m.edges.size() > kMaxGraphEdges) return "edges: more than kMaxGraphEdges";
  for (const auto& n : m.nodes) RGBD_CHECK(check_pose(n.T_world_node, "nodes.T_world_node"));
  for (const auto& e : m.edges) {
    if (!is_valid_edge_kind(static_cast<std::uint8_t>(e.kind))) return "edges.kind: unknown value";
    RGBD_CHECK(check_pose(e.T_from_to, "edges.T_from_to"));
  }
  return {};
}

std::string validate_one(const FloorMap& m) {
  RGBD_CHECK(check_range(m.resolution_m, field_range::kFloorMapResolutionM, "resolution_m"));
  RGBD_CHECK(check_range(m.origin_x_m, field_range::kFloorMapOriginXM, "origin_x_m"));
  RGBD_CHECK(check_range(m.origin_y_m, field_range::kFloorMapOriginYM, "origin_y_m"));
  RGBD_CHECK(check_int_range(m.width_cells, field_range::kFloorMapWidthCells, "width_cells"));
  RGBD_CHECK(check_int_range(m.height_cells, field_range::kFloorMapHeightCells, "height_cells"));
  if (!is_valid_cell_format(static_cast<std::uint8_t>(m.cell_format)))
    return "cell_format: unknown value";
  if (m.cells.size() != std::size_t{m.width_cells} * std::size_t{m.height_cells})
    return "cells: size != width_cells*height_cells";
  return {};
}

// ---------------------------------------------------------------- structural encode

void put_string(Writer& w, const std::string& s) {
  w.u16(static_cast<std::uint16_t>(s.size()));
  w.raw(reinterpret_cast<const std::uint8_t*>(s.data()), s.size());
}

void put_intrinsics(Writer& w, const CameraIntrinsics& k) {
  w.f64(k.fx_px);
  w.f64(k.fy_px);
  w.f64(k.cx_px);
  w.f64(k.cy_px);
  for (double d : k.distortion) w.f64(d);
}

void put_frame_header(Writer& w, const FrameHeader& h) {
  w.u32(h.sequence);
  w.u64(h.capture_timestamp_us);
  w.u64(h.send_timestamp_us);
  w.u16(h.width);
  w.u16(h.height);
  w.u8(static_cast<std::uint8_t>(h.pixel_format));
  w.u8(static_cast<std::uint8_t>(h.encoding));
  w.u32(h.payload_length);
}

void put_image(Writer& w, const ImageFrame& f) {
  put_frame_header(w, f.header);
  w.raw(f.payload.data(), f.payload.size());
}

void put_pose(Writer& w, const Pose3& p) {
  for (double t : p.t_m) w.f64(t);
  for (double q : p.q_xyzw) w.f64(q);
}

void put_body(Writer& w, const Handshake& m) {
  w.u16(m.protocol_version);
  w.u64(m.schema_hash);
  w.u8(static_cast<std::uint8_t>(m.stream_kind));
  w.u16(m.width);
  w.u16(m.height);
  w.u8(static_cast<std::uint8_t>(m.pixel_format));
  w.u8(static_cast<std::uint8_t>(m.encoding));
  put_intrinsics(w, m.intrinsics);
  w.f64(m.depth_scale_units_per_m);
  put_string(w, m.device_id);
  w.raw(m.sender_nonce.data(), m.sender_nonce.size());
  w.raw(m.mac.data(), m.mac.size());
}
void put_body(Writer& w, const HandshakeAck& m) {
  w.u8(m.accepted ? 1 : 0);
  put_string(w, m.reason);
  w.raw(m.mac.data(), m.mac.size());
}
void put_body(Writer& w, const StreamChallenge& m) {
  w.raw(m.receiver_nonce.data(), m.receiver_nonce.size());
}
// Fields a version step added (spec 'since') are written only in envelopes of that version or
// later; the other put_body overloads ignore the version (their layout never changed).
constexpr unsigned kAccelSinceVersion = 2;
void put_accel(Writer& w, const AccelSample& a, unsigned version) {
  if (version < kAccelSinceVersion) return;
  w.u8(a.valid ? 1 : 0);
  w.u64(a.capture_timestamp_us);
  for (double f : a.f_mps2) w.f64(f);
}
void put_body(Writer& w, const Frame& m, unsigned version) {
  put_image(w, m.image);
  put_accel(w, m.accel, version);
}
void put_body(Writer& w, const FrameRequest& m) {
  w.u16(m.credits);
  w.u32(m.last_received_sequence);
}
void put_body(Writer& w, const SlamHello& m) {
  w.u16(m.protocol_version);
  w.u64(m.schema_hash);
  put_string(w, m.peer_name);
  w.u64(m.session_id);
  w.u8(m.resumed ? 1 : 0);
  w.u32(m.session_frames);
  put_string(w, m.refusal);
}
void put_body(Writer& w, const RgbdFrame& m, unsigned version) {
  w.u32(m.pair_sequence);
  put_intrinsics(w, m.intrinsics);
  w.f64(m.depth_scale_units_per_m);
  w.u8(m.attitude.valid ? 1 : 0);
  for (double q : m.attitude.q_xyzw) w.f64(q);
  put_image(w, m.rgb);
  put_image(w, m.depth);
  put_accel(w, m.accel, version);
}
void put_body(Writer& w, const PoseUpdate& m) {
  w.u32(m.pair_sequence);
  w.u64(m.timestamp_us);
  w.u8(static_cast<std::uint8_t>(m.tracking_state));
  put_pose(w, m.T_world_cam);
  put_pose(w, m.T_prev_cur);
  w.u8(m.is_keyframe ? 1 : 0);
  w.u32(m.inlier_count);
  w.u32(m.map_correction_count);
}
void put_body(Writer& w, const PoseGraph& m) {
  w.u32(m.revision);
  w.u64(m.timestamp_us);
  w.u8(static_cast<std::uint8_t>(m.stage));
  w.u32(static_cast<std::uint32_t>(m.nodes.size()));
  for (const auto& n : m.nodes) {
    w.u32(n.node_id);
    w.u64(n.timestamp_us);
    put_pose(w, n.T_world_node);
  }
  w.u32(static_cast<std::uint32_t>(m.edges.size()));
  for (const auto& e : m.edges) {
    w.u32(e.from_id);
    w.u32(e.to_id);
    w.u8(static_cast<std::uint8_t>(e.kind));
    put_pose(w, e.T_from_to);
  }
}
void put_body(Writer& w, const FloorMap& m) {
  w.u32(m.revision);
  w.u64(m.timestamp_us);
  w.f64(m.resolution_m);
  w.f64(m.origin_x_m);
  w.f64(m.origin_y_m);
  w.u16(m.width_cells);
  w.u16(m.height_cells);
  w.u8(static_cast<std::uint8_t>(m.cell_format));
  w.u32(static_cast<std::uint32_t>(m.cells.size()));
  w.raw(m.cells.data(), m.cells.size());
}

template <typename T>
void put_body(Writer& w, const T& m, unsigned /*version*/) {
  put_body(w, m);
}

// ---------------------------------------------------------------- structural decode
// Parsing context: the reader plus the first value error found while parsing (only booleans need
// it: a bool cannot hold the wire value 2). Value errors are reported only when the body is
// structurally sound, the same order as the Python codec.
struct Parse {
  Reader r;
  std::string invalid;
  unsigned version = kProtocolVersion;  ///< envelope version: which fields the body has
};

bool get_bool(Parse& p, const char* field) {
  const std::uint8_t v = p.r.u8();
  if (v > 1 && p.invalid.empty()) p.invalid = std::string(field) + ": bool not 0 or 1";
  return v == 1;
}

std::string get_string(Parse& p, const char* field) {
  const std::uint16_t len = p.r.u16();
  if (p.r.failed()) return {};
  if (len > kMaxStringBytes) {
    p.r.length_error(std::string(field) + ": length above kMaxStringBytes");
    return {};
  }
  const std::uint8_t* s = p.r.take(len);
  return s == nullptr ? std::string{} : std::string(reinterpret_cast<const char*>(s), len);
}

// Length-prefixed bytes: limit checked before the remaining-size check and before allocating.
std::vector<std::uint8_t> get_bytes(Parse& p, std::size_t max_len, const char* field,
                                    std::uint32_t* length_out) {
  const std::uint32_t len = p.r.u32();
  if (length_out != nullptr) *length_out = len;
  if (p.r.failed()) return {};
  if (len > max_len) {
    p.r.length_error(std::string(field) + ": length above its limit");
    return {};
  }
  const std::uint8_t* b = p.r.take(len);
  return b == nullptr ? std::vector<std::uint8_t>{} : std::vector<std::uint8_t>(b, b + len);
}

// Fixed-size byte array (u8[N] in the spec): no length prefix.
template <std::size_t N>
void get_fixed(Parse& p, std::array<std::uint8_t, N>& out) {
  const std::uint8_t* b = p.r.take(N);
  if (b != nullptr) std::copy(b, b + N, out.begin());
}

void get_intrinsics(Parse& p, CameraIntrinsics& k) {
  k.fx_px = p.r.f64();
  k.fy_px = p.r.f64();
  k.cx_px = p.r.f64();
  k.cy_px = p.r.f64();
  for (double& d : k.distortion) d = p.r.f64();
}

void get_image(Parse& p, ImageFrame& f, const char* field) {
  FrameHeader& h = f.header;
  h.sequence = p.r.u32();
  h.capture_timestamp_us = p.r.u64();
  h.send_timestamp_us = p.r.u64();
  h.width = p.r.u16();
  h.height = p.r.u16();
  h.pixel_format = static_cast<PixelFormat>(p.r.u8());
  h.encoding = static_cast<Encoding>(p.r.u8());
  f.payload = get_bytes(p, kMaxFramePayloadBytes, field, &h.payload_length);
}

void get_pose(Parse& p, Pose3& pose) {
  for (double& t : pose.t_m) t = p.r.f64();
  for (double& q : pose.q_xyzw) q = p.r.f64();
}

void get_body(Parse& p, Handshake& m) {
  m.protocol_version = p.r.u16();
  m.schema_hash = p.r.u64();
  m.stream_kind = static_cast<StreamKind>(p.r.u8());
  m.width = p.r.u16();
  m.height = p.r.u16();
  m.pixel_format = static_cast<PixelFormat>(p.r.u8());
  m.encoding = static_cast<Encoding>(p.r.u8());
  get_intrinsics(p, m.intrinsics);
  m.depth_scale_units_per_m = p.r.f64();
  m.device_id = get_string(p, "device_id");
  get_fixed(p, m.sender_nonce);
  get_fixed(p, m.mac);
}
void get_body(Parse& p, HandshakeAck& m) {
  m.accepted = get_bool(p, "accepted");
  m.reason = get_string(p, "reason");
  get_fixed(p, m.mac);
}
void get_body(Parse& p, StreamChallenge& m) { get_fixed(p, m.receiver_nonce); }
void get_accel(Parse& p, AccelSample& a, const char* field) {
  if (p.version < kAccelSinceVersion) return;  // not in this version's body: stays not valid
  a.valid = get_bool(p, field);
  a.capture_timestamp_us = p.r.u64();
  for (double& f : a.f_mps2) f = p.r.f64();
}
void get_body(Parse& p, Frame& m) {
  get_image(p, m.image, "image.payload");
  get_accel(p, m.accel, "accel.valid");
}
void get_body(Parse& p, FrameRequest& m) {
  m.credits = p.r.u16();
  m.last_received_sequence = p.r.u32();
}
void get_body(Parse& p, SlamHello& m) {
  m.protocol_version = p.r.u16();
  m.schema_hash = p.r.u64();
  m.peer_name = get_string(p, "peer_name");
  m.session_id = p.r.u64();
  m.resumed = get_bool(p, "resumed");
  m.session_frames = p.r.u32();
  m.refusal = get_string(p, "refusal");
}
void get_body(Parse& p, RgbdFrame& m) {
  m.pair_sequence = p.r.u32();
  get_intrinsics(p, m.intrinsics);
  m.depth_scale_units_per_m = p.r.f64();
  m.attitude.valid = get_bool(p, "attitude.valid");
  for (double& q : m.attitude.q_xyzw) q = p.r.f64();
  get_image(p, m.rgb, "rgb.payload");
  get_image(p, m.depth, "depth.payload");
  get_accel(p, m.accel, "accel.valid");
}
void get_body(Parse& p, PoseUpdate& m) {
  m.pair_sequence = p.r.u32();
  m.timestamp_us = p.r.u64();
  m.tracking_state = static_cast<TrackingState>(p.r.u8());
  get_pose(p, m.T_world_cam);
  get_pose(p, m.T_prev_cur);
  m.is_keyframe = get_bool(p, "is_keyframe");
  m.inlier_count = p.r.u32();
  m.map_correction_count = p.r.u32();
}

// Node/edge wire sizes: the remaining-bytes check before reserve() bounds the allocation.
constexpr std::size_t kPoseBytes = 7 * 8;
constexpr std::size_t kNodeBytes = 4 + 8 + kPoseBytes;
constexpr std::size_t kEdgeBytes = 4 + 4 + 1 + kPoseBytes;

template <typename Item, typename ReadItem>
void get_array(Parse& p, std::vector<Item>& out, std::size_t max_count, std::size_t item_bytes,
               const char* field, ReadItem read_item) {
  const std::uint32_t count = p.r.u32();
  if (p.r.failed()) return;
  if (count > max_count) {
    p.r.length_error(std::string(field) + ": count above its limit");
    return;
  }
  if (std::size_t{count} * item_bytes > p.r.remaining()) {
    p.r.take(p.r.remaining() + 1);  // marks truncated
    return;
  }
  out.resize(count);
  for (auto& item : out) read_item(item);
}

void get_body(Parse& p, PoseGraph& m) {
  m.revision = p.r.u32();
  m.timestamp_us = p.r.u64();
  m.stage = static_cast<GraphStage>(p.r.u8());
  get_array(p, m.nodes, kMaxGraphNodes, kNodeBytes, "nodes", [&p](PoseGraphNode& n) {
    n.node_id = p.r.u32();
    n.timestamp_us = p.r.u64();
    get_pose(p, n.T_world_node);
  });
  get_array(p, m.edges, kMaxGraphEdges, kEdgeBytes, "edges", [&p](PoseGraphEdge& e) {
    e.from_id = p.r.u32();
    e.to_id = p.r.u32();
    e.kind = static_cast<EdgeKind>(p.r.u8());
    get_pose(p, e.T_from_to);
  });
}
void get_body(Parse& p, FloorMap& m) {
  m.revision = p.r.u32();
  m.timestamp_us = p.r.u64();
  m.resolution_m = p.r.f64();
  m.origin_x_m = p.r.f64();
  m.origin_y_m = p.r.f64();
  m.width_cells = p.r.u16();
  m.height_cells = p.r.u16();
  m.cell_format = static_cast<CellFormat>(p.r.u8());
  m.cells = get_bytes(p, kMaxMapCellsBytes, "cells", nullptr);
}

template <typename T>
BodyResult decode_as(const std::uint8_t* data, std::size_t size, unsigned version) {
  Parse p{Reader(data, size), {}, version};
  T message{};
  get_body(p, message);
  BodyResult result;
  if (!p.r.length_error_detail().empty()) {
    result.error = DecodeError::kLengthTooLarge;
    result.detail = p.r.length_error_detail();
  } else if (p.r.truncated()) {
    result.error = DecodeError::kTruncatedBody;
    result.detail = "body ends inside its fields";
  } else if (p.r.remaining() != 0) {
    result.error = DecodeError::kTrailingBytes;
    result.detail = std::to_string(p.r.remaining()) + " bytes after the last field";
  } else if (!p.invalid.empty()) {
    result.error = DecodeError::kInvalidValue;
    result.detail = p.invalid;
  } else if (std::string err = validate_one(message); !err.empty()) {
    result.error = DecodeError::kInvalidValue;
    result.detail = err;
  } else {
    result.message = std::move(message);
  }
  return result;
}

std::uint32_t get_le32(const std::uint8_t* in) {
  return std::uint32_t{in[0]} | std::uint32_t{in[1]} << 8 | std::uint32_t{in[2]} << 16 |
         std::uint32_t{in[3]} << 24;
}

// Bytes to reserve for a message so encoding never reallocates (its bulk plus a margin for the
// fixed fields and the envelope).
constexpr std::size_t kFixedPartMarginBytes = 512;
std::size_t reserve_hint(const Frame& m) { return m.image.payload.size() + kFixedPartMarginBytes; }
std::size_t reserve_hint(const RgbdFrame& m) {
  return m.rgb.payload.size() + m.depth.payload.size() + kFixedPartMarginBytes;
}
std::size_t reserve_hint(const PoseGraph& m) {
  return m.nodes.size() * kNodeBytes + m.edges.size() * kEdgeBytes + kFixedPartMarginBytes;
}
std::size_t reserve_hint(const FloorMap& m) { return m.cells.size() + kFixedPartMarginBytes; }
template <typename T>
std::size_t reserve_hint(const T&) {
  return kFixedPartMarginBytes;
}

template <typename T>
constexpr MessageType type_of() {
  if constexpr (std::is_same_v<T, Handshake>) return MessageType::kHandshake;
  if constexpr (std::is_same_v<T, HandshakeAck>) return MessageType::kHandshakeAck;
  if constexpr (std::is_same_v<T, Frame>) return MessageType::kFrame;
  if constexpr (std::is_same_v<T, FrameRequest>) return MessageType::kFrameRequest;
  if constexpr (std::is_same_v<T, SlamHello>) return MessageType::kSlamHello;
  if constexpr (std::is_same_v<T, RgbdFrame>) return MessageType::kRgbdFrame;
  if constexpr (std::is_same_v<T, PoseUpdate>) return MessageType::kPoseUpdate;
  if constexpr (std::is_same_v<T, PoseGraph>) return MessageType::kPoseGraph;
  if constexpr (std::is_same_v<T, FloorMap>) return MessageType::kFloorMap;
  if constexpr (std::is_same_v<T, StreamChallenge>) return MessageType::kStreamChallenge;
}

// Writes an envelope straight into `out`: header with placeholders, the body by `put_body`, then
// the length and both CRCs (one pass over a payload for the copy, one for the CRC).
template <typename PutBody>
void write_envelope(std::vector<std::uint8_t>& out, MessageType type, unsigned version,
                    PutBody put_body_fn) {
  Writer w(out);
  w.raw(kMagic, sizeof kMagic);
  w.u8(static_cast<std::uint8_t>(version));
  w.u8(static_cast<std::uint8_t>(type));
  w.u16(0);
  w.u32(0);  // body_length, patched below
  w.u32(0);  // header_crc32, patched below
  put_body_fn(w);
  const std::size_t body_length = out.size() - kEnvelopeHeaderBytes;
  auto patch_le32 = [&out](std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
  };
  patch_le32(8, static_cast<std::uint32_t>(body_length));
  patch_le32(12, crc32(out.data(), 12));
  w.u32(crc32(out.data() + kEnvelopeHeaderBytes, body_length));
}

template <typename T>
EncodeResult encode_typed(const T& message, bool with_envelope,
                          unsigned version = kProtocolVersion) {
  EncodeResult result;
  if (version < kOldestDecodedProtocolVersion || version > kProtocolVersion) {
    result.error = "version " + std::to_string(version) + " is not one this build writes";
    return result;
  }
  result.error = validate_one(message);
  if (!result.error.empty()) return result;
  result.bytes.reserve(reserve_hint(message));
  if (with_envelope) {
    write_envelope(result.bytes, type_of<T>(), version,
                   [&message, version](Writer& w) { put_body(w, message, version); });
  } else {
    Writer w(result.bytes);
    put_body(w, message, version);
  }
  return result;
}

}  // namespace

const char* to_string(DecodeError error) {
  switch (error) {
    case DecodeError::kNone:
      return "none";
    case DecodeError::kGarbageSkipped:
      return "garbage_skipped";
    case DecodeError::kBadHeaderCrc:
      return "bad_header_crc";
    case DecodeError::kUnsupportedVersion:
      return "unsupported_version";
    case DecodeError::kUnknownMessageType:
      return "unknown_message_type";
    case DecodeError::kReservedNonzero:
      return "reserved_nonzero";
    case DecodeError::kBodyTooLarge:
      return "body_too_large";
    case DecodeError::kBadBodyCrc:
      return "bad_body_crc";
    case DecodeError::kTruncatedBody:
      return "truncated_body";
    case DecodeError::kLengthTooLarge:
      return "length_too_large";
    case DecodeError::kTrailingBytes:
      return "trailing_bytes";
    case DecodeError::kInvalidValue:
      return "invalid_value";
  }
  return "?";
}

MessageType message_type(const Message& message) {
  return std::visit([](const auto& m) { return type_of<std::decay_t<decltype(m)>>(); }, message);
}

std::uint32_t crc32(const std::uint8_t* data, std::size_t size, std::uint32_t crc) {
  const auto& t = kCrcTables;
  crc = ~crc;
  std::size_t i = 0;
  for (; i + 8 <= size; i += 8) {  // bytes combined explicitly: independent of host byte order
    const std::uint32_t lo =
        crc ^ (std::uint32_t{data[i]} | std::uint32_t{data[i + 1]} << 8 |
               std::uint32_t{data[i + 2]} << 16 | std::uint32_t{data[i + 3]} << 24);
    crc = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^
          t[3][data[i + 4]] ^ t[2][data[i + 5]] ^ t[1][data[i + 6]] ^ t[0][data[i + 7]];
  }
  for (; i < size; ++i) crc = t[0][(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

std::string validate(const Message& message) {
  return std::visit([](const auto& m) { return validate_one(m); }, message);
}

EncodeResult encode(const Message& message, unsigned version) {
  return std::visit([version](const auto& m) { return encode_typed(m, true, version); }, message);
}
EncodeResult encode_body(const Message& message, unsigned version) {
  return std::visit([version](const auto& m) { return encode_typed(m, false, version); }, message);
}
EncodeResult encode_handshake(const Handshake& m) { return encode_typed(m, true); }
EncodeResult encode_handshake_ack(const HandshakeAck& m) { return encode_typed(m, true); }
EncodeResult encode_frame(const Frame& m) { return encode_typed(m, true); }
EncodeResult encode_frame_request(const FrameRequest& m) { return encode_typed(m, true); }
EncodeResult encode_stream_challenge(const StreamChallenge& m) { return encode_typed(m, true); }

EncodeResult encode_frame(const FrameHeader& header, const std::uint8_t* payload,
                          std::size_t payload_size, const AccelSample& accel) {
  EncodeResult result;
  result.error = check_image(header, payload_size, "image");
  if (result.error.empty()) result.error = check_accel(accel, "accel");
  if (!result.error.empty()) return result;
  if (payload == nullptr && payload_size > 0) {
    result.error = "image.payload: null pointer with a non-zero size";
    return result;
  }
  result.bytes.reserve(payload_size + kFixedPartMarginBytes);
  write_envelope(result.bytes, MessageType::kFrame, kProtocolVersion, [&](Writer& w) {
    put_frame_header(w, header);
    w.raw(payload, payload_size);
    put_accel(w, accel, kProtocolVersion);
  });
  return result;
}

BodyResult decode_body(std::uint8_t type, const std::uint8_t* data, std::size_t size,
                       unsigned version) {
  if (version < kOldestDecodedProtocolVersion || version > kProtocolVersion) {
    BodyResult result;
    result.error = DecodeError::kUnsupportedVersion;
    result.detail = "version " + std::to_string(version);
    return result;
  }
  switch (static_cast<MessageType>(type)) {
    case MessageType::kHandshake:
      return decode_as<Handshake>(data, size, version);
    case MessageType::kHandshakeAck:
      return decode_as<HandshakeAck>(data, size, version);
    case MessageType::kFrame:
      return decode_as<Frame>(data, size, version);
    case MessageType::kFrameRequest:
      return decode_as<FrameRequest>(data, size, version);
    case MessageType::kSlamHello:
      return decode_as<SlamHello>(data, size, version);
    case MessageType::kRgbdFrame:
      return decode_as<RgbdFrame>(data, size, version);
    case MessageType::kPoseUpdate:
      return decode_as<PoseUpdate>(data, size, version);
    case MessageType::kPoseGraph:
      return decode_as<PoseGraph>(data, size, version);
    case MessageType::kFloorMap:
      return decode_as<FloorMap>(data, size, version);
    case MessageType::kStreamChallenge:
      return decode_as<StreamChallenge>(data, size, version);
  }
  BodyResult result;
  result.error = DecodeError::kUnknownMessageType;
  result.detail = "message type " + std::to_string(type) + " is not in the spec";
  return result;
}

namespace {
// A peer of any decoded version is compatible when its hash is that version's hash.
std::string incompatibility(std::uint16_t version, std::uint64_t hash) {
  char buf[200];
  const std::uint64_t expected = schema_hash_of_version(version);
  if (expected == 0) {
    std::snprintf(buf, sizeof buf, "protocol version mismatch: peer %u, ours %u..%u", version,
                  static_cast<unsigned>(kOldestDecodedProtocolVersion),
                  static_cast<unsigned>(kProtocolVersion));
    return buf;
  }
  if (hash != expected) {
    std::snprintf(
        buf, sizeof buf, "schema hash mismatch: peer 0x%016llx, ours 0x%016llx for version %u",
        static_cast<unsigned long long>(hash), static_cast<unsigned long long>(expected), version);
    return buf;
  }
  return {};
}
}  // namespace

std::string handshake_incompatibility(const Handshake& peer) {
  return incompatibility(peer.protocol_version, peer.schema_hash);
}
std::string hello_incompatibility(const SlamHello& peer) {
  return incompatibility(peer.protocol_version, peer.schema_hash);
}

// ---------------------------------------------------------------- StreamDecoder

void StreamDecoder::feed(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return;
  // Compact before growing so a long-lived connection does not keep consumed bytes.
  if (read_offset_ > 0 && read_offset_ >= buffer_.size() / 2) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(read_offset_));
    read_offset_ = 0;
  }
  buffer_.insert(buffer_.end(), data, data + size);
}

void StreamDecoder::consume(std::size_t count) {
  read_offset_ += count;
  if (read_offset_ == buffer_.size()) {
    buffer_.clear();
    read_offset_ = 0;
  }
}

// Drops bytes from read_offset_+from up to the next position that starts with the magic or with a
// prefix of it at the end of the buffer. Returns the total bytes dropped (including `from`).
std::size_t StreamDecoder::discard_to_next_magic(std::size_t from) {
  const std::size_t available = buffered_bytes();
  const std::uint8_t* base = buffer_.data() + read_offset_;
  std::size_t i = from;
  for (; i < available; ++i) {
    const std::size_t n = std::min(sizeof kMagic, available - i);
    if (std::equal(base + i, base + i + n, kMagic)) break;
  }
  consume(i);
  return i;
}

DecodeResult StreamDecoder::next() {
  DecodeResult result;
  if (buffered_bytes() == 0) return result;
  if (const std::size_t skipped = discard_to_next_magic(0); skipped > 0) {
    result.status = DecodeStatus::kError;
    result.error = DecodeError::kGarbageSkipped;
    result.detail = std::to_string(skipped) + " bytes before a magic";
    result.bytes_discarded = skipped;
    return result;
  }
  if (buffered_bytes() < kEnvelopeHeaderBytes) return result;

  const std::uint8_t* h = buffer_.data() + read_offset_;
  const std::uint8_t version = h[4];
  const std::uint8_t type = h[5];
  const std::uint16_t reserved = static_cast<std::uint16_t>(h[6] | (h[7] << 8));
  const std::uint32_t body_length = get_le32(h + 8);
  const std::uint32_t header_crc = get_le32(h + 12);

  auto header_error = [&](DecodeError error, std::string detail) {
    result.status = DecodeStatus::kError;
    result.error = error;
    result.detail = std::move(detail);
    result.bytes_discarded = discard_to_next_magic(1);
    return result;
  };
  if (crc32(h, 12) != header_crc) return header_error(DecodeError::kBadHeaderCrc, "header CRC");
  if (version < kOldestDecodedProtocolVersion || version > kProtocolVersion) {
    return header_error(DecodeError::kUnsupportedVersion,
                        "version " + std::to_string(version) + ", ours " +
                            std::to_string(kOldestDecodedProtocolVersion) + ".." +
                            std::to_string(kProtocolVersion));
  }
  const std::size_t type_max = max_body_bytes(type, version);
  if (type_max == 0) {
    return header_error(DecodeError::kUnknownMessageType, "type " + std::to_string(type));
  }
  if (reserved != 0) return header_error(DecodeError::kReservedNonzero, "reserved bits set");
  const std::size_t cap =
      options_.max_body_bytes > 0 ? std::min(type_max, options_.max_body_bytes) : type_max;
  if (body_length > cap) {
    return header_error(DecodeError::kBodyTooLarge,
                        "body_length " + std::to_string(body_length) + " > " + std::to_string(cap));
  }
  const std::size_t frame_bytes = kEnvelopeHeaderBytes + body_length + kEnvelopeTrailerBytes;
  if (buffered_bytes() < frame_bytes) return result;

  const std::uint8_t* body = h + kEnvelopeHeaderBytes;
  if (crc32(body, body_length) != get_le32(body + body_length)) {
    consume(frame_bytes);
    result.status = DecodeStatus::kError;
    result.error = DecodeError::kBadBodyCrc;
    result.detail = "body CRC";
    result.bytes_discarded = frame_bytes;
    return result;
  }
  BodyResult decoded = decode_body(type, body, body_length, version);
  consume(frame_bytes);
  if (!decoded.ok()) {
    result.status = DecodeStatus::kError;
    result.error = decoded.error;
    result.detail = std::move(decoded.detail);
    result.bytes_discarded = frame_bytes;
    return result;
  }
  result.status = DecodeStatus::kMessage;
  result.message = std::move(decoded.message);
  result.version = version;
  return result;
}

}  // namespace rgbdquad::protocol
