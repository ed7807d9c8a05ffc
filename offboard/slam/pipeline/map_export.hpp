// Output writers: coloured point-cloud map from keyframes (binary little-endian PLY) and the pose
// graph as g2o text. Stateless; thread-safe for distinct paths.
#pragma once

#include <string>

#include "slam/core/types.hpp"
#include "slam/thesis/backend.hpp"
#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

struct MapExportOptions {
  int pixel_stride = 8;      ///< every 8th pixel in u and v: ~4800 points per keyframe
  double max_depth_m = 4.0;  ///< as FeatureOptions::max_depth_m (Kinect noise beyond)
};

/// Writes every keyframe's depth pixels, back-projected with `intrinsics`, transformed by the
/// keyframe's current (optimised) pose, coloured from its RGB image. Returns the point count, or
/// -1 with `error` set on I/O failure.
long write_keyframe_map_ply(const std::string& path, const BackEnd& backend,
                            const Intrinsics& intrinsics, const MapExportOptions& options,
                            std::string* error);

/// Writes the local map's points (world frame), coloured from the keypoint of their first living
/// observation. Locks `map.mutex`. Returns the point count, or -1 with `error` on I/O failure.
long write_map_points_ply(const std::string& path, SharedMap& map, std::string* error);

/// Writes `text` to `path`; false with `error` on failure.
bool write_text_file(const std::string& path, const std::string& text, std::string* error);

}  // namespace rgbdquad::slam
