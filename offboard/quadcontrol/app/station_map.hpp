// The ground station's map of the floor as the dashboard and the recorder see it: the FloorMap fed
// with each tracked frame's depth points (coloured by the RGB pixel they project to), a revision
// counter, and its renderings (PNG, sub-sampled cloud JSON, PLY). Also the depth sub-sampling that
// turns a frame into camera points, shared with the floor search. Not thread-safe (the owner
// guards it).
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "app/frame_source.hpp"
#include "core/craft_pose_tracker.hpp"
#include "map/floor_map.hpp"

namespace rgbdquad::quadcontrol {

/// Camera points (metres, camera frame) of every `step`-th depth pixel in both directions that
/// has a reading within `max_depth_m`; empty when the depth image is not CV_16UC1.
std::vector<Eigen::Vector3d> camera_points(const CameraFrame& frame, int step, double max_depth_m);

/// The map's points of one frame: camera points (m) into the floor frame, coloured by the RGB
/// pixel they project to (grey where the projection leaves the image or the image is not BGR).
std::vector<ColouredPoint> coloured_floor_points(const CameraFrame& frame,
                                                 const std::vector<Eigen::Vector3d>& cam_points,
                                                 const Eigen::Isometry3d& T_floor_cam);

/// {"x_m", "y_m", "z_m", "yaw_deg"} of a pose, as /api/state and /api/cloud show it.
nlohmann::json pose_json(const CraftPose& pose);

class StationMap {
 public:
  explicit StationMap(FloorMapOptions options) : map_(options) {}

  /// Adds a tracked frame's camera points seen from `T_floor_cam` (maps camera points to the
  /// floor frame) and bumps the revision.
  void add_frame(const CameraFrame& frame, const std::vector<Eigen::Vector3d>& cam_points,
                 const Eigen::Isometry3d& T_floor_cam);
  const FloorMap& map() const { return map_; }
  /// +1 per added frame; the dashboard reloads the map image when it changes.
  std::int64_t revision() const { return revision_; }
  /// The 2D map as a PNG (north up).
  std::string png() const { return png_of_render(map_.render_rgb(), map_.width_cells()); }
  /// PNG of a FloorMap::render_rgb() image `cells` wide and high (the owner renders under its lock
  /// and encodes outside it).
  static std::string png_of_render(std::vector<std::uint8_t> rgb, int cells);
  /// At most about `max_points` cloud points ([x, y, z] rounded to mm, r, g, b), the total, and
  /// `pose` (null when absent).
  nlohmann::json cloud_json(std::size_t max_points, const std::optional<CraftPose>& pose) const;
  std::string ply() const { return map_.to_ply(); }

 private:
  FloorMap map_;
  std::int64_t revision_ = 0;
};

}  // namespace rgbdquad::quadcontrol
