// JSON view of messages (see json_view.hpp).
#include "json_view.hpp"

#include <optional>
#include <stdexcept>
#include <type_traits>

namespace rgbdquad::protocol {
namespace {

using nlohmann::json;

template <typename E, std::size_t N>
json enum_name(E value, const E (&all)[N]) {
  for (E e : all) {
    if (e == value) return std::string(to_string(e));
  }
  return static_cast<int>(value);  // unregistered value: shown as its number
}

template <typename E, std::size_t N>
E enum_from(const json& j, const E (&all)[N], const char* field) {
  if (j.is_number_unsigned()) {
    const auto v = j.get<std::uint64_t>();
    if (v > 255) throw std::invalid_argument(std::string(field) + ": enum number above 255");
    return static_cast<E>(v);
  }
  if (!j.is_string()) throw std::invalid_argument(std::string(field) + ": expected enum name");
  const std::string name = j.get<std::string>();
  for (E e : all) {
    if (to_string(e) == name) return e;
  }
  throw std::invalid_argument(std::string(field) + ": unknown name " + name);
}

const json& at(const json& j, const char* field) {
  if (!j.is_object() || !j.contains(field))
    throw std::invalid_argument(std::string("missing field ") + field);
  return j.at(field);
}

template <typename T>
T num(const json& j, const char* field) {
  const json& v = at(j, field);
  if constexpr (std::is_floating_point_v<T>) {
    if (!v.is_number()) throw std::invalid_argument(std::string(field) + ": expected a number");
    return v.get<T>();
  } else {
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() >= 0))
      throw std::invalid_argument(std::string(field) + ": expected an unsigned integer");
    const auto u = v.get<std::uint64_t>();
    if (u > std::numeric_limits<T>::max())
      throw std::invalid_argument(std::string(field) + ": out of range for its wire type");
    return static_cast<T>(u);
  }
}

template <std::size_t N>
std::array<double, N> doubles(const json& j, const char* field) {
  const json& v = at(j, field);
  if (!v.is_array() || v.size() != N)
    throw std::invalid_argument(std::string(field) + ": expected " + std::to_string(N) +
                                " numbers");
  std::array<double, N> out{};
  for (std::size_t i = 0; i < N; ++i) {
    if (!v[i].is_number()) throw std::invalid_argument(std::string(field) + ": not a number");
    out[i] = v[i].get<double>();
  }
  return out;
}

// u8[N] spec fields: a JSON array of N integers 0..255 (as the Python view).
template <std::size_t N>
std::array<std::uint8_t, N> byte_array(const json& j, const char* field) {
  const json& v = at(j, field);
  if (!v.is_array() || v.size() != N)
    throw std::invalid_argument(std::string(field) + ": expected " + std::to_string(N) + " bytes");
  std::array<std::uint8_t, N> out{};
  for (std::size_t i = 0; i < N; ++i) {
    if (!v[i].is_number_unsigned() || v[i].get<std::uint64_t>() > 255)
      throw std::invalid_argument(std::string(field) + ": not a byte");
    out[i] = static_cast<std::uint8_t>(v[i].get<std::uint64_t>());
  }
  return out;
}

std::string str(const json& j, const char* field) {
  const json& v = at(j, field);
  if (!v.is_string()) throw std::invalid_argument(std::string(field) + ": expected a string");
  return v.get<std::string>();
}

bool boolean(const json& j, const char* field) {
  const json& v = at(j, field);
  if (!v.is_boolean()) throw std::invalid_argument(std::string(field) + ": expected a bool");
  return v.get<bool>();
}

json intrinsics_json(const CameraIntrinsics& k) {
  return {{"fx_px", k.fx_px},
          {"fy_px", k.fy_px},
          {"cx_px", k.cx_px},
          {"cy_px", k.cy_px},
          {"distortion", k.distortion}};
}
CameraIntrinsics intrinsics_from(const json& j) {
  CameraIntrinsics k;
  k.fx_px = num<double>(j, "fx_px");
  k.fy_px = num<double>(j, "fy_px");
  k.cx_px = num<double>(j, "cx_px");
  k.cy_px = num<double>(j, "cy_px");
  k.distortion = doubles<5>(j, "distortion");
  return k;
}

json image_json(const ImageFrame& f) {
  const FrameHeader& h = f.header;
  return {{"sequence", h.sequence},
          {"capture_timestamp_us", h.capture_timestamp_us},
          {"send_timestamp_us", h.send_timestamp_us},
          {"width", h.width},
          {"height", h.height},
          {"pixel_format", enum_name(h.pixel_format, kAllPixelFormat)},
          {"encoding", enum_name(h.encoding, kAllEncoding)},
          {"payload", to_hex(f.payload.data(), f.payload.size())}};
}
ImageFrame image_from(const json& j) {
  ImageFrame f;
  FrameHeader& h = f.header;
  h.sequence = num<std::uint32_t>(j, "sequence");
  h.capture_timestamp_us = num<std::uint64_t>(j, "capture_timestamp_us");
  h.send_timestamp_us = num<std::uint64_t>(j, "send_timestamp_us");
  h.width = num<std::uint16_t>(j, "width");
  h.height = num<std::uint16_t>(j, "height");
  h.pixel_format = enum_from(at(j, "pixel_format"), kAllPixelFormat, "pixel_format");
  h.encoding = enum_from(at(j, "encoding"), kAllEncoding, "encoding");
  f.payload = from_hex(str(j, "payload"));
  h.payload_length = static_cast<std::uint32_t>(f.payload.size());
  return f;
}

json pose_json(const Pose3& p) { return {{"t_m", p.t_m}, {"q_xyzw", p.q_xyzw}}; }
Pose3 pose_from(const json& j) {
  Pose3 p;
  p.t_m = doubles<3>(j, "t_m");
  p.q_xyzw = doubles<4>(j, "q_xyzw");
  return p;
}

json attitude_json(const CameraAttitude& a) { return {{"valid", a.valid}, {"q_xyzw", a.q_xyzw}}; }
CameraAttitude attitude_from(const json& j) {
  CameraAttitude a;
  a.valid = boolean(j, "valid");
  a.q_xyzw = doubles<4>(j, "q_xyzw");
  return a;
}

json fields_of(const Handshake& m) {
  return {{"protocol_version", m.protocol_version},
          {"schema_hash", m.schema_hash},
          {"stream_kind", enum_name(m.stream_kind, kAllStreamKind)},
          {"width", m.width},
          {"height", m.height},
          {"pixel_format", enum_name(m.pixel_format, kAllPixelFormat)},
          {"encoding", enum_name(m.encoding, kAllEncoding)},
          {"intrinsics", intrinsics_json(m.intrinsics)},
          {"depth_scale_units_per_m", m.depth_scale_units_per_m},
          {"device_id", m.device_id},
          {"sender_nonce", m.sender_nonce},
          {"mac", m.mac}};
}
json accel_json(const AccelSample& a) {
  return {
      {"valid", a.valid}, {"capture_timestamp_us", a.capture_timestamp_us}, {"f_mps2", a.f_mps2}};
}
// A view may leave out the accel field (added by protocol version 2): it is then not valid, as
// the Python codec's default.
AccelSample accel_from(const json& fields) {
  AccelSample a;
  if (!fields.contains("accel")) return a;
  const json& j = at(fields, "accel");
  a.valid = boolean(j, "valid");
  a.capture_timestamp_us = num<std::uint64_t>(j, "capture_timestamp_us");
  a.f_mps2 = doubles<3>(j, "f_mps2");
  return a;
}

json fields_of(const HandshakeAck& m) {
  return {{"accepted", m.accepted}, {"reason", m.reason}, {"mac", m.mac}};
}
json fields_of(const StreamChallenge& m) { return {{"receiver_nonce", m.receiver_nonce}}; }
json fields_of(const Frame& m) {
  return {{"image", image_json(m.image)}, {"accel", accel_json(m.accel)}};
}
json fields_of(const FrameRequest& m) {
  return {{"credits", m.credits}, {"last_received_sequence", m.last_received_sequence}};
}
json fields_of(const SlamHello& m) {
  return {{"protocol_version", m.protocol_version},
          {"schema_hash", m.schema_hash},
          {"peer_name", m.peer_name},
          {"session_id", m.session_id},
          {"resumed", m.resumed},
          {"session_frames", m.session_frames},
          {"refusal", m.refusal}};
}
json fields_of(const RgbdFrame& m) {
  return {{"pair_sequence", m.pair_sequence},
          {"intrinsics", intrinsics_json(m.intrinsics)},
          {"depth_scale_units_per_m", m.depth_scale_units_per_m},
          {"attitude", attitude_json(m.attitude)},
          {"rgb", image_json(m.rgb)},
          {"depth", image_json(m.depth)},
          {"accel", accel_json(m.accel)}};
}
json fields_of(const PoseUpdate& m) {
  return {{"pair_sequence", m.pair_sequence},
          {"timestamp_us", m.timestamp_us},
          {"tracking_state", enum_name(m.tracking_state, kAllTrackingState)},
          {"T_world_cam", pose_json(m.T_world_cam)},
          {"T_prev_cur", pose_json(m.T_prev_cur)},
          {"is_keyframe", m.is_keyframe},
          {"inlier_count", m.inlier_count},
          {"map_correction_count", m.map_correction_count}};
}
json fields_of(const PoseGraph& m) {
  json nodes = json::array();
  for (const auto& n : m.nodes) {
    nodes.push_back({{"node_id", n.node_id},
                     {"timestamp_us", n.timestamp_us},
                     {"T_world_node", pose_json(n.T_world_node)}});
  }
  json edges = json::array();
  for (const auto& e : m.edges) {
    edges.push_back({{"from_id", e.from_id},
                     {"to_id", e.to_id},
                     {"kind", enum_name(e.kind, kAllEdgeKind)},
                     {"T_from_to", pose_json(e.T_from_to)}});
  }
  return {{"revision", m.revision},
          {"timestamp_us", m.timestamp_us},
          {"stage", enum_name(m.stage, kAllGraphStage)},
          {"nodes", nodes},
          {"edges", edges}};
}
json fields_of(const FloorMap& m) {
  return {{"revision", m.revision},
          {"timestamp_us", m.timestamp_us},
          {"resolution_m", m.resolution_m},
          {"origin_x_m", m.origin_x_m},
          {"origin_y_m", m.origin_y_m},
          {"width_cells", m.width_cells},
          {"height_cells", m.height_cells},
          {"cell_format", enum_name(m.cell_format, kAllCellFormat)},
          {"cells", to_hex(m.cells.data(), m.cells.size())}};
}

// The view's fields back into a message, one function per message family of the spec (the
// stream link's authentication and its frames; the SLAM link's frames and its map). Each returns
// nullopt for a type outside its family.

std::optional<Message> stream_auth_from(const std::string& type, const json& f) {
  if (type == "Handshake") {
    Handshake m;
    m.protocol_version = num<std::uint16_t>(f, "protocol_version");
    m.schema_hash = num<std::uint64_t>(f, "schema_hash");
    m.stream_kind = enum_from(at(f, "stream_kind"), kAllStreamKind, "stream_kind");
    m.width = num<std::uint16_t>(f, "width");
    m.height = num<std::uint16_t>(f, "height");
    m.pixel_format = enum_from(at(f, "pixel_format"), kAllPixelFormat, "pixel_format");
    m.encoding = enum_from(at(f, "encoding"), kAllEncoding, "encoding");
    m.intrinsics = intrinsics_from(at(f, "intrinsics"));
    m.depth_scale_units_per_m = num<double>(f, "depth_scale_units_per_m");
    m.device_id = str(f, "device_id");
    m.sender_nonce = byte_array<kStreamAuthNonceBytes>(f, "sender_nonce");
    m.mac = byte_array<kStreamAuthTagBytes>(f, "mac");
    return m;
  }
  if (type == "HandshakeAck") {
    HandshakeAck m;
    m.accepted = boolean(f, "accepted");
    m.reason = str(f, "reason");
    m.mac = byte_array<kStreamAuthTagBytes>(f, "mac");
    return m;
  }
  if (type == "StreamChallenge") {
    StreamChallenge m;
    m.receiver_nonce = byte_array<kStreamAuthNonceBytes>(f, "receiver_nonce");
    return m;
  }
  return std::nullopt;
}

std::optional<Message> stream_frames_from(const std::string& type, const json& f) {
  if (type == "Frame") {
    Frame m;
    m.image = image_from(at(f, "image"));
    m.accel = accel_from(f);
    return m;
  }
  if (type == "FrameRequest") {
    FrameRequest m;
    m.credits = num<std::uint16_t>(f, "credits");
    m.last_received_sequence = num<std::uint32_t>(f, "last_received_sequence");
    return m;
  }
  return std::nullopt;
}

std::optional<Message> slam_frames_from(const std::string& type, const json& f) {
  if (type == "SlamHello") {
    SlamHello m;
    m.protocol_version = num<std::uint16_t>(f, "protocol_version");
    m.schema_hash = num<std::uint64_t>(f, "schema_hash");
    m.peer_name = str(f, "peer_name");
    m.session_id = num<std::uint64_t>(f, "session_id");
    m.resumed = boolean(f, "resumed");
    m.session_frames = num<std::uint32_t>(f, "session_frames");
    m.refusal = str(f, "refusal");
    return m;
  }
  if (type == "RgbdFrame") {
    RgbdFrame m;
    m.pair_sequence = num<std::uint32_t>(f, "pair_sequence");
    m.intrinsics = intrinsics_from(at(f, "intrinsics"));
    m.depth_scale_units_per_m = num<double>(f, "depth_scale_units_per_m");
    m.attitude = attitude_from(at(f, "attitude"));
    m.rgb = image_from(at(f, "rgb"));
    m.depth = image_from(at(f, "depth"));
    m.accel = accel_from(f);
    return m;
  }
  if (type == "PoseUpdate") {
    PoseUpdate m;
    m.pair_sequence = num<std::uint32_t>(f, "pair_sequence");
    m.timestamp_us = num<std::uint64_t>(f, "timestamp_us");
    m.tracking_state = enum_from(at(f, "tracking_state"), kAllTrackingState, "tracking_state");
    m.T_world_cam = pose_from(at(f, "T_world_cam"));
    m.T_prev_cur = pose_from(at(f, "T_prev_cur"));
    m.is_keyframe = boolean(f, "is_keyframe");
    m.inlier_count = num<std::uint32_t>(f, "inlier_count");
    m.map_correction_count = num<std::uint32_t>(f, "map_correction_count");
    return m;
  }
  return std::nullopt;
}

PoseGraphNode graph_node_from(const json& n) {
  PoseGraphNode node;
  node.node_id = num<std::uint32_t>(n, "node_id");
  node.timestamp_us = num<std::uint64_t>(n, "timestamp_us");
  node.T_world_node = pose_from(at(n, "T_world_node"));
  return node;
}
PoseGraphEdge graph_edge_from(const json& e) {
  PoseGraphEdge edge;
  edge.from_id = num<std::uint32_t>(e, "from_id");
  edge.to_id = num<std::uint32_t>(e, "to_id");
  edge.kind = enum_from(at(e, "kind"), kAllEdgeKind, "kind");
  edge.T_from_to = pose_from(at(e, "T_from_to"));
  return edge;
}

std::optional<Message> slam_map_from(const std::string& type, const json& f) {
  if (type == "PoseGraph") {
    PoseGraph m;
    m.revision = num<std::uint32_t>(f, "revision");
    m.timestamp_us = num<std::uint64_t>(f, "timestamp_us");
    m.stage = enum_from(at(f, "stage"), kAllGraphStage, "stage");
    for (const json& n : at(f, "nodes")) m.nodes.push_back(graph_node_from(n));
    for (const json& e : at(f, "edges")) m.edges.push_back(graph_edge_from(e));
    return m;
  }
  if (type == "FloorMap") {
    FloorMap m;
    m.revision = num<std::uint32_t>(f, "revision");
    m.timestamp_us = num<std::uint64_t>(f, "timestamp_us");
    m.resolution_m = num<double>(f, "resolution_m");
    m.origin_x_m = num<double>(f, "origin_x_m");
    m.origin_y_m = num<double>(f, "origin_y_m");
    m.width_cells = num<std::uint16_t>(f, "width_cells");
    m.height_cells = num<std::uint16_t>(f, "height_cells");
    m.cell_format = enum_from(at(f, "cell_format"), kAllCellFormat, "cell_format");
    m.cells = from_hex(str(f, "cells"));
    return m;
  }
  return std::nullopt;
}

Message from_fields(const std::string& type, const json& f) {
  for (auto family : {stream_auth_from, stream_frames_from, slam_frames_from, slam_map_from}) {
    if (std::optional<Message> m = family(type, f)) return *std::move(m);
  }
  throw std::invalid_argument("unknown message type " + type);
}

}  // namespace

nlohmann::json to_json(const Message& message) {
  const std::string type(to_string(message_type(message)));
  return {{"type", type},
          {"fields", std::visit([](const auto& m) { return fields_of(m); }, message)}};
}

Message message_from_json(const nlohmann::json& view) {
  if (!view.is_object() || !view.contains("type") || !view["type"].is_string())
    throw std::invalid_argument("expected {\"type\": <name>, \"fields\": {...}}");
  return from_fields(view["type"].get<std::string>(), at(view, "fields"));
}

std::string to_hex(const std::uint8_t* data, std::size_t size) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out(2 * size, '0');
  for (std::size_t i = 0; i < size; ++i) {
    out[2 * i] = kDigits[data[i] >> 4];
    out[2 * i + 1] = kDigits[data[i] & 0xF];
  }
  return out;
}

std::vector<std::uint8_t> from_hex(const std::string& hex) {
  if (hex.size() % 2 != 0) throw std::invalid_argument("hex string of odd length");
  auto nibble = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    throw std::invalid_argument("non-hex digit in hex string");
  };
  std::vector<std::uint8_t> out(hex.size() / 2);
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = static_cast<std::uint8_t>(nibble(hex[2 * i]) << 4 | nibble(hex[2 * i + 1]));
  }
  return out;
}

}  // namespace rgbdquad::protocol
