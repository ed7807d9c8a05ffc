// Feature stage: detector/descriptor factory (SIFT, SURF, ORB chosen by one config value) and the
// lifting of keypoints to 3D camera coordinates with the registered depth image.
//
// Thread safety: a FeatureExtractor is used by one thread at a time (the front-end).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <opencv2/features2d.hpp>
#include <optional>
#include <string>
#include <vector>

#include "slam/core/types.hpp"

namespace rgbdquad::slam {

enum class DetectorKind { kSift, kSurf, kOrb };

bool parse_detector_kind(const std::string& name, DetectorKind* out, std::string* error);
const char* to_string(DetectorKind kind);

struct FeatureOptions {
  DetectorKind kind = DetectorKind::kSift;
  // SIFT (thesis Table 4.1): 6 octaves, 3 scales per octave, first-octave sigma 0.8, contrast
  // threshold 0.035, edge threshold 15. OpenCV 4.6 derives the octave count from the image size (it
  // cannot be set) and applies `sift_sigma` on its internally upsampled octave -1, where 1.6
  // equals the thesis' 0.8 in input pixels.
  int sift_scales_per_octave = 3;
  double sift_contrast_threshold = 0.035;
  double sift_edge_threshold = 15.0;
  double sift_sigma = 1.6;
  int sift_max_features = 0;  ///< 0 = keep all (thesis)
  /// OpenCV 4.6 always starts SIFT at an upsampled octave -1 (4x the pixels of the input). With
  /// this off (default), SIFT runs on a half-size copy so that its octave -1 is the input
  /// resolution, i.e. the first octave is 0 as in SiftGPU (the thesis' CUDA SIFT): ~4x less work,
  /// keypoints scaled back to input pixels. Measured on fr1_xyz_first300 (VO+GLC): ATE 13.0 mm.
  bool sift_upsample_first_octave = false;
  // SURF (thesis Table 4.2): 4 octaves, 3 scales per octave, 128-element descriptor, Hessian 550.
  int surf_octaves = 4;
  int surf_scales_per_octave = 3;
  bool surf_extended = true;
  double surf_hessian_threshold = 550.0;
  // ORB (thesis Table 4.3): 1024 features, scale factor 2, 6 levels, edge threshold 31, patch 31.
  int orb_features = 1024;
  double orb_scale_factor = 2.0;
  int orb_levels = 6;
  int orb_edge_threshold = 31;
  int orb_patch_size = 31;
  /// Put ORB keypoints of pyramid level L > 0 where their corner is in the input image. cv::ORB
  /// reports a level-L keypoint at (level pixel) x s_L (orb.cpp: `keypoint->pt *= scale`), but it
  /// builds the level with cv::resize, whose pixel centres are aligned: level pixel i is input
  /// coordinate (i + 0.5) x R_L - 0.5 (R_L = input size / level size). Left as reported, every
  /// level-L keypoint sits (R_L - 1) / 2 px up and to the left of its corner - with the thesis'
  /// scale factor 2: 0.5 px at level 1, 1.5 at 2, 3.5 at 3, 7.5 at 4, 15.5 at 5 - always the same
  /// way, so a point seen at one level in a keyframe and at another in a later frame pulls the
  /// pose by the difference, and depth is read beside the corner. (The SIFT half-size path below
  /// corrects the same convention.) Off only to measure what it changes.
  bool orb_pixel_centres = true;
  /// Spread ORB keypoints over the image (spread_keypoints below): cv::ORB detects this many times
  /// `orb_features` corners, and each pyramid level keeps its share of `orb_features`, taken in
  /// rounds from cells of `orb_spread_cell_px` level pixels - the strongest corner of every cell,
  /// then the second, ... cv::ORB alone keeps the strongest corners of each level wherever they
  /// are, so they bunch on a few high-contrast patches, the more so when blur flattens the rest;
  /// ORB-SLAM2 spreads its corners (a quadtree over 30 px FAST cells) for the same reason: a pose
  /// fitted to points spread over the view is better conditioned. 0 or 1: cv::ORB's own choice.
  int orb_spread_oversample = 0;
  double orb_spread_cell_px = 30.0;  ///< ORB-SLAM2's FAST cell
  // Lifting to 3D. Kinect v1 depth is unreliable below ~0.4 m and its noise grows with z^2
  // (about 4 cm at 4 m), so readings outside [min_depth_m, max_depth_m] are not used: those
  // keypoints go to FrameFeatures::depthless.
  double min_depth_m = 0.3;
  double max_depth_m = 4.0;
  /// Undistort keypoint coordinates before back-projection (the TUM colour images are not
  /// rectified; fr1 k1 = 0.26). Measured on fr1_xyz_first300, SIFT VO+GLC: ATE 13.0 -> 12.0 mm,
  /// RPE 6.56 -> 6.40 mm.
  bool undistort = true;

  bool is_valid(std::string* error) const;
};

/// Features of one frame that have a valid depth reading (and, apart, those that have none). Row i
/// of `descriptors` belongs to
/// keypoints[i] and points_cam_m[i] (3D point in the camera frame, metres, z forward).
struct FrameFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  ///< CV_32F (SIFT/SURF) or CV_8U (ORB)
  std::vector<Eigen::Vector3d> points_cam_m;
  std::vector<cv::Vec3b> colours_bgr;  ///< pixel colour at each keypoint, for the map
  /// Depth slope at each keypoint's pixel, m per px: the larger central difference of the depth
  /// image along u and v (one-sided where a neighbour has no reading). How far the depth read moves
  /// when the keypoint's pixel is off by one: large at occluding edges and on oblique surfaces.
  std::vector<float> depth_slope_m_per_px;
  std::size_t detected = 0;  ///< keypoints found before the depth filter
  /// The keypoints the depth filter dropped (no reading, or outside [min_depth_m, max_depth_m]),
  /// as features of their own whose points_cam_m are bearings at z = 1 (undistorted): a map point
  /// matched to one still fixes the camera's rotation and its position across the view, only
  /// not along the ray (a far wall, a depth hole at an occluding edge). Null when none were
  /// dropped. Not saved with a map.
  std::shared_ptr<const FrameFeatures> depthless;
};

/// FrameFeatures::depth_slope_m_per_px at pixel (u, v) of a 16-bit depth image; 0 where the
/// pixel has no reading.
double depth_slope_m_per_px(const cv::Mat& depth, int u, int v, double units_per_m);

class FeatureExtractor {
 public:
  /// Returns std::nullopt with a message when the options are invalid or the detector is not
  /// available in this build (SURF before the slam_surf library exists).
  static std::optional<FeatureExtractor> create(const FeatureOptions& options,
                                                const Intrinsics& intrinsics, std::string* error);

  /// Detects, describes and lifts. Fails (nullopt + error) on empty or mis-typed images.
  std::optional<FrameFeatures> extract(const RgbdFrame& frame, std::string* error) const;

  /// True when descriptors compare with Hamming distance (ORB), else L2.
  bool binary_descriptors() const { return options_.kind == DetectorKind::kOrb; }
  const FeatureOptions& options() const { return options_; }

 private:
  FeatureExtractor(FeatureOptions options, Intrinsics intrinsics, cv::Ptr<cv::Feature2D> detector,
                   cv::Ptr<cv::Feature2D> wide_detector);
  /// Keypoints and descriptors of the detector, spread when FeatureOptions::orb_spread_oversample.
  void detect_and_describe(const cv::Mat& grey, std::vector<cv::KeyPoint>* kps,
                           cv::Mat* desc) const;
  /// FeatureOptions::orb_pixel_centres: level-L keypoints moved to their corner's input pixel.
  void orb_keypoints_to_pixel_centres(const cv::Size& input, std::vector<cv::KeyPoint>* kps) const;
  FeatureOptions options_;
  Intrinsics intrinsics_;
  cv::Ptr<cv::Feature2D> detector_;
  cv::Ptr<cv::Feature2D> wide_detector_;  ///< ORB with the oversampled count, or empty
};

/// Of `candidates` (keypoints of a pyramid with scale factor `scale_factor`, level in
/// `KeyPoint::octave`, positions in input pixels), the indices of `keep` spread over the image:
/// each level keeps its share of the candidates (so the scale distribution is unchanged), taken in
/// rounds over a grid of `cell_px` level pixels - in each round the strongest remaining corner of
/// every cell, strongest cells first. Deterministic (ties by position).
std::vector<std::size_t> spread_keypoints(const std::vector<cv::KeyPoint>& candidates,
                                          std::size_t keep, double scale_factor, double cell_px);

/// Back-projects pixel (u, v) with depth z_m to the camera frame.
inline Eigen::Vector3d back_project(const Intrinsics& k, double u_px, double v_px, double z_m) {
  return {(u_px - k.cx_px) * z_m / k.fx_px, (v_px - k.cy_px) * z_m / k.fy_px, z_m};
}

}  // namespace rgbdquad::slam
