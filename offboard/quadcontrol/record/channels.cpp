// Channel definitions: see channels.hpp. One table row per channel (topic, schema name, fields);
// the JSON Schemas are generated from the rows. Foxglove's schemas are written from its published
// field lists (names, types, units); ours follow the house rule of units in names.
#include "record/channels.hpp"

#include <initializer_list>
#include <nlohmann/json.hpp>

namespace rgbdquad::quadcontrol::record {

namespace {
using nlohmann::json;

/// A field's JSON Schema type; the composite ones are the shared sub-objects below.
enum class Type {
  kNumber,
  kInteger,
  kString,
  kBool,
  kBytes,        ///< base64 string (Foxglove's JSON rule for bytes fields)
  kNumbers,      ///< array of numbers
  kTime,         ///< {sec, nsec}
  kVector3,      ///< {x, y, z}
  kQuaternion,   ///< {x, y, z, w}
  kPose,         ///< {position: Vector3, orientation: Quaternion}
  kCraftPose,    ///< {x_m, y_m, z_m, yaw_deg}
  kSticks,       ///< {roll, pitch, yaw, throttle} in % of deflection
  kPwm,          ///< {roll, pitch, throttle, yaw} in us
  kPackedFields  ///< array of foxglove.PackedElementField
};
struct Field {
  const char* name;
  Type type;
};
struct Row {
  const char* topic;
  const char* schema_name;
  std::initializer_list<Field> fields;
};

json object(const std::string& title, std::initializer_list<Field> fields);

json schema_of(Type t) {
  switch (t) {
    case Type::kNumber:
      return {{"type", "number"}};
    case Type::kInteger:
      return {{"type", "integer"}};
    case Type::kString:
      return {{"type", "string"}};
    case Type::kBool:
      return {{"type", "boolean"}};
    case Type::kBytes:
      return {{"type", "string"}, {"contentEncoding", "base64"}};
    case Type::kNumbers:
      return {{"type", "array"}, {"items", {{"type", "number"}}}};
    case Type::kTime:
      return object("time", {{"sec", Type::kInteger}, {"nsec", Type::kInteger}});
    case Type::kVector3:
      return object("Vector3", {{"x", Type::kNumber}, {"y", Type::kNumber}, {"z", Type::kNumber}});
    case Type::kQuaternion:
      return object(
          "Quaternion",
          {{"x", Type::kNumber}, {"y", Type::kNumber}, {"z", Type::kNumber}, {"w", Type::kNumber}});
    case Type::kPose:
      return object("Pose", {{"position", Type::kVector3}, {"orientation", Type::kQuaternion}});
    case Type::kCraftPose:
      return object("CraftPose", {{"x_m", Type::kNumber},
                                  {"y_m", Type::kNumber},
                                  {"z_m", Type::kNumber},
                                  {"yaw_deg", Type::kNumber}});
    case Type::kSticks:
      return object("Sticks", {{"roll", Type::kNumber},
                               {"pitch", Type::kNumber},
                               {"yaw", Type::kNumber},
                               {"throttle", Type::kNumber}});
    case Type::kPwm:
      return object("Pwm", {{"roll", Type::kInteger},
                            {"pitch", Type::kInteger},
                            {"throttle", Type::kInteger},
                            {"yaw", Type::kInteger}});
    case Type::kPackedFields:
      return {{"type", "array"},
              {"items", object("foxglove.PackedElementField", {{"name", Type::kString},
                                                               {"offset", Type::kInteger},
                                                               {"type", Type::kInteger}})}};
  }
  return {};
}

json object(const std::string& title, std::initializer_list<Field> fields) {
  json properties = json::object();
  for (const Field& f : fields) properties[f.name] = schema_of(f.type);
  return {{"title", title}, {"type", "object"}, {"properties", std::move(properties)}};
}

using T = Type;
// Channel id = row index + 1 (docs/recording.md lists them).
const Row kRows[] = {
    {kTopicRgb,
     "foxglove.CompressedImage",
     {{"timestamp", T::kTime},
      {"frame_id", T::kString},
      {"data", T::kBytes},
      {"format", T::kString}}},
    {kTopicDepthCompressed,
     "rgbdquad.CompressedDepth",
     {{"timestamp", T::kTime},
      {"frame_id", T::kString},
      {"width", T::kInteger},
      {"height", T::kInteger},
      {"encoding", T::kString},
      {"depth_units_per_m", T::kNumber},
      {"data", T::kBytes}}},
    {kTopicDepth,
     "foxglove.RawImage",
     {{"timestamp", T::kTime},
      {"frame_id", T::kString},
      {"width", T::kInteger},
      {"height", T::kInteger},
      {"encoding", T::kString},
      {"step", T::kInteger},
      {"data", T::kBytes}}},
    {kTopicCalibration,
     "foxglove.CameraCalibration",
     {{"timestamp", T::kTime},
      {"frame_id", T::kString},
      {"width", T::kInteger},
      {"height", T::kInteger},
      {"distortion_model", T::kString},
      {"D", T::kNumbers},
      {"K", T::kNumbers},
      {"R", T::kNumbers},
      {"P", T::kNumbers}}},
    {kTopicTf,
     "foxglove.FrameTransform",
     {{"timestamp", T::kTime},
      {"parent_frame_id", T::kString},
      {"child_frame_id", T::kString},
      {"translation", T::kVector3},
      {"rotation", T::kQuaternion}}},
    {kTopicPose,
     "foxglove.PoseInFrame",
     {{"timestamp", T::kTime}, {"frame_id", T::kString}, {"pose", T::kPose}}},
    {kTopicSetpoint,
     "foxglove.PoseInFrame",
     {{"timestamp", T::kTime}, {"frame_id", T::kString}, {"pose", T::kPose}}},
    {kTopicMap,
     "foxglove.PointCloud",
     {{"timestamp", T::kTime},
      {"frame_id", T::kString},
      {"pose", T::kPose},
      {"point_stride", T::kInteger},
      {"fields", T::kPackedFields},
      {"data", T::kBytes}}},
    {kTopicLog,
     "foxglove.Log",
     {{"timestamp", T::kTime},
      {"level", T::kInteger},
      {"message", T::kString},
      {"name", T::kString},
      {"file", T::kString},
      {"line", T::kInteger}}},
    {kTopicFrame,
     "rgbdquad.StreamFrame",
     {{"sequence", T::kInteger},
      {"capture_us", T::kInteger},
      {"received_us", T::kInteger},
      {"link_latency_ms", T::kNumber},
      {"fps", T::kNumber},
      {"images_recorded", T::kBool}}},
    {kTopicTracking,
     "rgbdquad.Tracking",
     {{"sequence", T::kInteger},
      {"capture_us", T::kInteger},
      {"pose_us", T::kInteger},
      {"tracking", T::kBool},
      {"slam_state", T::kString},
      {"inliers", T::kInteger},
      {"session", T::kInteger},
      {"flight_state", T::kString},
      {"pose", T::kCraftPose},
      {"setpoint", T::kCraftPose},
      {"position_error_m", T::kNumber},
      {"height_error_m", T::kNumber},
      {"q_ned_cam", T::kQuaternion}}},
    {kTopicLatency,
     "rgbdquad.StageLatency",
     {{"sequence", T::kInteger},
      {"capture_us", T::kInteger},
      {"link_ms", T::kNumber},
      {"capture_to_received_ms", T::kNumber},
      {"received_to_pose_ms", T::kNumber},
      {"slam_ms", T::kNumber}}},
    {kTopicCommand,
     "rgbdquad.Command",
     {{"seq", T::kInteger},
      {"send_us", T::kInteger},
      {"flight_state", T::kString},
      {"armed", T::kBool},
      {"stick_pct", T::kSticks},
      {"pwm_us", T::kPwm},
      {"pose_capture_us", T::kInteger},
      {"pose_us", T::kInteger},
      {"capture_to_command_ms", T::kNumber},
      {"pose_to_command_ms", T::kNumber}}},
    {kTopicReply,
     "rgbdquad.FirmwareReply",
     {{"received_us", T::kInteger},
      {"status", T::kInteger},
      {"seq", T::kInteger},
      {"state", T::kString},
      {"err", T::kString},
      {"out_us", T::kNumbers},
      {"clamped", T::kInteger},
      {"att_mrad", T::kNumbers},
      {"att_age_ms", T::kInteger},
      {"imu_raw", T::kNumbers},
      {"imu_age_ms", T::kInteger}}},
    {kTopicEvent,
     "rgbdquad.Event",
     {{"t_us", T::kInteger}, {"level", T::kInteger}, {"source", T::kString}, {"text", T::kString}}},
    {kTopicRecorder,
     "rgbdquad.RecorderStats",
     {{"messages", T::kInteger},
      {"bytes", T::kInteger},
      {"dropped_queue_full", T::kInteger},
      {"images_dropped", T::kInteger},
      {"frames_recorded", T::kInteger},
      {"encode_ms_per_frame", T::kNumber},
      {"queued", T::kInteger},
      {"queued_bytes", T::kInteger}}},
};

std::vector<ChannelSpec> make_specs() {
  std::vector<ChannelSpec> specs;
  for (const Row& row : kRows) {
    json schema = object(row.schema_name, row.fields);
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema";
    specs.push_back(ChannelSpec{row.topic, row.schema_name, schema.dump()});
  }
  return specs;
}
}  // namespace

const std::vector<ChannelSpec>& channel_specs() {
  static const std::vector<ChannelSpec> specs = make_specs();  // immutable table, built once
  return specs;
}

std::size_t channel_index(const char* topic) {
  const auto& specs = channel_specs();
  for (std::size_t i = 0; i < specs.size(); ++i) {
    if (specs[i].topic == topic) return i;
  }
  return specs.size();
}

}  // namespace rgbdquad::quadcontrol::record
