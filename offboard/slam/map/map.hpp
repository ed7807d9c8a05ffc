// The local-map SLAM's map store: keyframes (pose, features, which map point each keypoint sees)
// and map points (world position, one descriptor, observations), with the covisibility queries
// tracking and mapping need. Plain data plus queries; the locking discipline lives with the owner
// (`LocalMapSlam` holds one mutex around every access).
//
// Frames and units: T_world_cam maps camera points (metres, z forward) into the world frame, the
// world being the first keyframe's camera. Keypoint observations are stored as undistorted pixels
// (u, v) plus the measured depth z (metres), i.e. what a pinhole projection of the point predicts.
//
// Not thread-safe (see above).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "slam/core/types.hpp"
#include "slam/features/features.hpp"

namespace rgbdquad::slam {

/// Observation model shared by tracking and bundle adjustment: a pinhole camera on undistorted
/// pixels plus a virtual-stereo disparity d = bf / z for the depth reading (ORB-SLAM2's RGB-D
/// model; bf = 40 px*m in its TUM settings: the Kinect's 7.5 cm IR baseline times fx ~ 517 px).
/// Pixel sigma per keypoint, `level_scale` px (1 at the finest detector level); the disparity's
/// sigma follows `depth_noise` (see DepthNoiseModel).
enum class DepthNoiseModel {
  /// ORB-SLAM2: the disparity gets the keypoint's pixel sigma, as a stereo match would. For a
  /// Kinect this says sigma_z = z^2 / bf per px: 25 mm at 1 m, 100 mm at 2 m - 10-20x the sensor's.
  kKeypointSigma,
  /// The Kinect's measured axial noise, sigma_z(z) = 1.2 mm + 1.9 mm/m^2 (z - 0.4 m)^2 (Nguyen,
  /// Izadi, Lovell, "Modeling Kinect Sensor Noise for Improved 3D Reconstruction and Tracking",
  /// 3DIMPVT 2012, Eq. 1, surfaces facing the camera), carried into disparity:
  /// sigma_d = bf sigma_z / z^2 (0.08 px at 1 m, 0.06 px at 2 m), never below
  /// `kMinDisparitySigmaPx`.
  kKinectAxial,
  /// kKinectAxial plus the depth image's slope at the keypoint times the keypoint's pixel sigma,
  /// in quadrature: sigma_z^2 = sigma_axial(z)^2 + (slope * sigma_px)^2. A keypoint on an occluding
  /// edge or an oblique surface reads a depth that moves by `slope` per pixel of position error, so
  /// its depth is as uncertain as its position (no constant of its own: both terms are measured).
  kKinectEdge,
};
bool parse_depth_noise_model(const std::string& name, DepthNoiseModel* out, std::string* error);
const char* to_string(DepthNoiseModel m);

struct CameraModel {
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  double bf_px_m = 40.0;
  int width_px = 640, height_px = 480;
  DepthNoiseModel depth_noise = DepthNoiseModel::kKeypointSigma;
  /// Floor of the disparity sigma: the Kinect reports disparity in 1/8 px steps (Khoshelham and
  /// Elberink 2012), whose quantisation alone is 1/8 / sqrt(12) = 0.036 px.
  static constexpr double kMinDisparitySigmaPx = 0.125 / 3.4641016151377544;
  /// Disparity sigma, px, of a depth reading `depth_m` at a keypoint of pixel sigma `kp_sigma_px`
  /// where the depth image's slope is `slope_m_per_px` (used by kKinectEdge only).
  double disparity_sigma_px(double depth_m, double kp_sigma_px, double slope_m_per_px = 0) const;
  static CameraModel from(const Intrinsics& k) {
    CameraModel c;
    c.fx_px = k.fx_px;
    c.fy_px = k.fy_px;
    c.cx_px = k.cx_px;
    c.cy_px = k.cy_px;
    return c;
  }
  /// (u, v, disparity) of a camera-frame point; z must be > 0.
  Eigen::Vector3d project(const Eigen::Vector3d& p_cam_m) const {
    const double iz = 1.0 / p_cam_m.z();
    return {fx_px * p_cam_m.x() * iz + cx_px, fy_px * p_cam_m.y() * iz + cy_px, bf_px_m * iz};
  }
  /// d project / d p_cam_m at a camera-frame point; z must be > 0.
  Eigen::Matrix3d project_jacobian(const Eigen::Vector3d& p_cam_m) const {
    const double iz = 1.0 / p_cam_m.z(), iz2 = iz * iz;
    Eigen::Matrix3d J;
    J << fx_px * iz, 0, -fx_px * p_cam_m.x() * iz2, 0, fy_px * iz, -fy_px * p_cam_m.y() * iz2, 0, 0,
        -bf_px_m * iz2;
    return J;
  }
  bool in_image(double u, double v) const {
    return u >= 0 && v >= 0 && u < width_px && v < height_px;
  }
};

/// The 95 % chi-square bound for 3 degrees of freedom (u, v, disparity): an observation beyond it
/// is an outlier (ORB-SLAM2 uses the same value for its RGB-D/stereo edges).
constexpr double kChi2Rgbd95 = 7.815;
/// The 95 % bound for 2 degrees of freedom (u, v), used when fusing by projection.
constexpr double kChi2Mono95 = 5.991;

/// Scale sigma of a keypoint, px: its size relative to the finest keypoint size the detector makes
/// (ORB: the patch size at level 0; SIFT/SURF: their smallest blob). 1 px at the finest level.
double keypoint_level_scale(const cv::KeyPoint& kp, const FeatureOptions& options);

/// Fixed-size grid over the image: keypoint indices per 16 x 16 px cell, for radius searches.
class KeypointGrid {
 public:
  KeypointGrid() = default;
  KeypointGrid(const std::vector<Eigen::Vector2d>& pixels, int width_px, int height_px);
  /// Indices of keypoints within `radius_px` of (u, v).
  void query(double u, double v, double radius_px, std::vector<int>* out) const;

 private:
  static constexpr int kCellPx = 16;
  int cols_ = 0, rows_ = 0;
  std::vector<std::vector<int>> cells_;
  std::vector<Eigen::Vector2d> pixels_;
};

/// Features of a frame in the form tracking and mapping use: undistorted pixels, depths, sigmas.
struct TrackedFeatures {
  std::shared_ptr<const FrameFeatures> features;
  std::vector<Eigen::Vector2d> pixels;  ///< undistorted pixel of each keypoint
  std::vector<double> depth_m;
  std::vector<double> sigma_px;  ///< pixel sigma of (u, v)
  std::vector<double>
      disparity_sigma_px;  ///< sigma of the disparity (CameraModel::disparity_sigma_px)
  KeypointGrid grid;
  static TrackedFeatures from(std::shared_ptr<const FrameFeatures> f, const CameraModel& cam,
                              const FeatureOptions& options);
  std::size_t size() const { return pixels.size(); }
  /// (u, v, disparity) measured for keypoint i.
  Eigen::Vector3d measurement(std::size_t i, const CameraModel& cam) const {
    return {pixels[i].x(), pixels[i].y(), cam.bf_px_m / depth_m[i]};
  }
  /// Sigmas of (u, v, disparity) for keypoint i, px.
  Eigen::Vector3d sigma(std::size_t i) const {
    return {sigma_px[i], sigma_px[i], disparity_sigma_px[i]};
  }
};

struct MapPoint {
  std::int64_t id = -1;
  Eigen::Vector3d p_world_m = Eigen::Vector3d::Zero();
  cv::Mat descriptor;                        ///< one row; replaced, never written in place
  std::map<std::int64_t, int> observations;  ///< keyframe id -> keypoint index
  std::int64_t first_keyframe = -1;
  std::int64_t first_keyframe_serial = 0;  ///< how many keyframes existed when it was made
  int visible = 0;                         ///< frames where it projected inside the image
  int found = 0;                           ///< frames where it was matched as an inlier
};

struct MapKeyframe {
  std::int64_t id = -1;  ///< index of the frame it was made from
  double stamp_s = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  TrackedFeatures features;
  /// Keypoints without a depth reading (TrackerOptions::depthless_map_points; empty otherwise):
  /// the mapper triangulates map points from them across keyframes, and they observe those points
  /// in (u, v) only. They are indexed after `features`: keypoint index features.size() + j is
  /// depthless keypoint j, in `point_ids` and in MapPoint::observations alike.
  TrackedFeatures depthless;
  std::vector<std::int64_t> point_ids;  ///< per keypoint (features, then depthless): point or -1
  cv::Mat thumbnail;                    ///< place-recognition thumbnail (CV_32F), see place_index
  /// The first keyframe of a new map segment (TrackerOptions::restart_when_lost): it and the
  /// keyframes after it share no points with the map before it until the segment is merged.
  /// Not saved with the map: it matters only to the mapper's culling of recent points.
  bool starts_segment = false;
  bool is_depthless(int kp) const { return static_cast<std::size_t>(kp) >= features.size(); }
  /// Whitened reprojection error, squared, of `p_world_m` at keypoint `kp`: (u, v, disparity) for a
  /// keypoint with depth, (u, v) for a depthless one (compare with kChi2Rgbd95 / kChi2Mono95, see
  /// chi2_bound). 1e9 behind the camera.
  double chi2(int kp, const Eigen::Vector3d& p_world_m, const CameraModel& cam) const;
  /// The 95 % chi-square bound of keypoint `kp`'s observation.
  double chi2_bound(int kp) const;
  /// Gravity measured when the keyframe was made (TrackerOptions::gravity): a roll/pitch factor in
  /// local BA and in the loop-closing graph. Not saved with the map (a loaded map has none).
  std::optional<GravityObservation> gravity;
};

/// Where a culled keyframe went: frames anchored to it follow T_parent_kf to a living keyframe.
struct CulledKeyframe {
  std::int64_t parent = -1;
  Eigen::Isometry3d T_parent_kf = Eigen::Isometry3d::Identity();
};

/// A verified loop closure between keyframes a and b: T_a_b maps points of camera b into camera a.
/// Kept for every later pose-graph optimisation; its keyframes are never culled.
struct LoopEdge {
  std::int64_t a = -1, b = -1;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
};

class SlamMap {
 public:
  // --- keyframes
  void add_keyframe(MapKeyframe kf);
  bool has_keyframe(std::int64_t id) const { return keyframes_.count(id) != 0; }
  const MapKeyframe* keyframe(std::int64_t id) const;
  MapKeyframe* keyframe(std::int64_t id);
  const std::map<std::int64_t, MapKeyframe>& keyframes() const { return keyframes_; }
  std::int64_t keyframes_created() const { return keyframes_created_; }
  /// Removes a keyframe and its observations; points left with no observation are removed too.
  /// Frames anchored to it resolve through `parent`.
  void cull_keyframe(std::int64_t id, std::int64_t parent);
  /// Pose of keyframe `id`, following culled keyframes to their living parents. nullopt: unknown.
  std::optional<Eigen::Isometry3d> resolve_pose(std::int64_t id) const;
  const std::map<std::int64_t, CulledKeyframe>& culled() const { return culled_; }

  // --- points
  /// Creates a point observed by keypoint `kp` of keyframe `kf_id`; returns its id.
  std::int64_t add_point(const Eigen::Vector3d& p_world_m, const cv::Mat& descriptor,
                         std::int64_t kf_id, int kp);
  bool has_point(std::int64_t id) const { return points_.count(id) != 0; }
  const MapPoint* point(std::int64_t id) const;
  MapPoint* point(std::int64_t id);
  const std::map<std::int64_t, MapPoint>& points() const { return points_; }
  /// Records that keypoint `kp` of keyframe `kf_id` sees point `pid` (replacing what it saw).
  void add_observation(std::int64_t pid, std::int64_t kf_id, int kp);
  void erase_observation(std::int64_t pid, std::int64_t kf_id);
  void erase_point(std::int64_t pid);
  /// Merges point `from` into `into` (observations moved unless the keyframe already sees `into`).
  void replace_point(std::int64_t from, std::int64_t into);

  // --- covisibility
  /// Keyframes sharing at least `min_shared` points with `kf_id`, most shared first.
  std::vector<std::pair<std::int64_t, int>> covisible(std::int64_t kf_id, int min_shared) const;
  /// Points of keyframe `kf_id` observed by at least `min_obs` keyframes.
  int tracked_points(std::int64_t kf_id, int min_obs) const;

  // --- loop closures
  void add_loop_edge(const LoopEdge& e) { loop_edges_.push_back(e); }
  const std::vector<LoopEdge>& loop_edges() const { return loop_edges_; }
  bool in_loop_edge(std::int64_t kf_id) const;

  // --- for tests and reporting
  std::int64_t next_point_id() const { return next_point_id_; }
  /// Replaces the whole content (map loading). Ids continue after the largest loaded one.
  void restore(std::map<std::int64_t, MapKeyframe> kfs, std::map<std::int64_t, MapPoint> pts,
               std::map<std::int64_t, CulledKeyframe> culled,
               std::vector<LoopEdge> loop_edges = {});

 private:
  std::map<std::int64_t, MapKeyframe> keyframes_;
  std::map<std::int64_t, MapPoint> points_;
  std::map<std::int64_t, CulledKeyframe> culled_;
  std::vector<LoopEdge> loop_edges_;
  std::int64_t next_point_id_ = 0;
  std::int64_t keyframes_created_ = 0;
};

}  // namespace rgbdquad::slam
