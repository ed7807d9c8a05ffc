// Feature factory and 3D lifting. SURF comes from the slam_surf library (offboard/surf) when it is
// part of the build (SLAM_HAVE_SURF); otherwise asking for it fails with a clear message.
#include "slam/features/features.hpp"

#include <cmath>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#ifdef SLAM_HAVE_SURF
#include "rgbdquad/surf/surf.hpp"
#endif

namespace rgbdquad::slam {

double depth_slope_m_per_px(const cv::Mat& depth, int u, int v, double units_per_m) {
  const auto at = [&](int x, int y) -> double {
    if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return 0;
    return depth.at<std::uint16_t>(y, x) / units_per_m;
  };
  const double z = at(u, v);
  if (!(z > 0)) return 0;
  // Central difference where both neighbours have a reading, else one-sided, else none.
  const auto slope = [&](double a, double b) {
    if (a > 0 && b > 0) return std::abs(b - a) / 2;
    if (a > 0) return std::abs(z - a);
    if (b > 0) return std::abs(b - z);
    return 0.0;
  };
  return std::max(slope(at(u - 1, v), at(u + 1, v)), slope(at(u, v - 1), at(u, v + 1)));
}

bool parse_detector_kind(const std::string& name, DetectorKind* out, std::string* error) {
  if (name == "sift") {
    *out = DetectorKind::kSift;
    return true;
  }
  if (name == "surf") {
    *out = DetectorKind::kSurf;
    return true;
  }
  if (name == "orb") {
    *out = DetectorKind::kOrb;
    return true;
  }
  if (error) *error = "unknown feature detector '" + name + "' (expected sift, surf or orb)";
  return false;
}

const char* to_string(DetectorKind kind) {
  switch (kind) {
    case DetectorKind::kSift:
      return "sift";
    case DetectorKind::kSurf:
      return "surf";
    case DetectorKind::kOrb:
      return "orb";
  }
  return "?";
}

bool FeatureOptions::is_valid(std::string* error) const {
  auto fail = [&](const char* msg) {
    if (error) *error = msg;
    return false;
  };
  if (sift_scales_per_octave < 1 || !(sift_contrast_threshold > 0) || !(sift_edge_threshold > 0) ||
      !(sift_sigma > 0) || sift_max_features < 0)
    return fail("features: SIFT parameters must be positive");
  if (surf_octaves < 1 || surf_scales_per_octave < 1 || !(surf_hessian_threshold > 0))
    return fail("features: SURF parameters must be positive");
  if (orb_features < 1 || !(orb_scale_factor > 1.0) || orb_levels < 1 || orb_edge_threshold < 1 ||
      orb_patch_size < 2 || orb_spread_oversample < 0 || !(orb_spread_cell_px >= 4))
    return fail("features: ORB parameters out of range");
  if (!(min_depth_m >= 0) || !(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m))
    return fail("features: need 0 <= min_depth_m < max_depth_m < inf");
  return true;
}

FeatureExtractor::FeatureExtractor(FeatureOptions options, Intrinsics intrinsics,
                                   cv::Ptr<cv::Feature2D> detector,
                                   cv::Ptr<cv::Feature2D> wide_detector)
    : options_(options),
      intrinsics_(intrinsics),
      detector_(std::move(detector)),
      wide_detector_(std::move(wide_detector)) {}

std::optional<FeatureExtractor> FeatureExtractor::create(const FeatureOptions& o,
                                                         const Intrinsics& k, std::string* error) {
  if (!o.is_valid(error) || !k.is_valid(error)) return std::nullopt;
  cv::Ptr<cv::Feature2D> det, wide;
  switch (o.kind) {
    case DetectorKind::kSift:
      det = cv::SIFT::create(o.sift_max_features, o.sift_scales_per_octave,
                             o.sift_contrast_threshold, o.sift_edge_threshold, o.sift_sigma);
      break;
    case DetectorKind::kOrb:
      det = cv::ORB::create(o.orb_features, static_cast<float>(o.orb_scale_factor), o.orb_levels,
                            o.orb_edge_threshold, 0, 2, cv::ORB::HARRIS_SCORE, o.orb_patch_size);
      if (o.orb_spread_oversample > 1)
        wide = cv::ORB::create(o.orb_features * o.orb_spread_oversample,
                               static_cast<float>(o.orb_scale_factor), o.orb_levels,
                               o.orb_edge_threshold, 0, 2, cv::ORB::HARRIS_SCORE, o.orb_patch_size);
      break;
    case DetectorKind::kSurf: {
#ifdef SLAM_HAVE_SURF
      surf::SurfOptions so;
      so.octaves = o.surf_octaves;
      so.scales_per_octave = o.surf_scales_per_octave;
      so.extended = o.surf_extended;
      so.hessian_threshold = o.surf_hessian_threshold;
      det = surf::create_surf(so);
#else
      if (error)
        *error =
            "features: SURF is not available in this build (the slam_surf library in "
            "offboard/surf is missing); use sift or orb";
      return std::nullopt;
#endif
      break;
    }
  }
  if (det.empty()) {
    if (error) *error = "features: could not create the detector";
    return std::nullopt;
  }
  return FeatureExtractor(o, k, det, wide);
}

std::vector<std::size_t> spread_keypoints(const std::vector<cv::KeyPoint>& candidates,
                                          std::size_t keep, double scale_factor, double cell_px) {
  std::vector<std::size_t> out;
  if (candidates.size() <= keep) {
    for (std::size_t i = 0; i < candidates.size(); ++i) out.push_back(i);
    return out;
  }
  auto stronger = [&candidates](std::size_t ia, std::size_t ib) {
    const cv::KeyPoint &a = candidates[ia], &b = candidates[ib];
    if (a.response != b.response) return a.response > b.response;
    return a.pt.y != b.pt.y ? a.pt.y < b.pt.y : a.pt.x < b.pt.x;
  };
  std::map<int, std::vector<std::size_t>> by_level;
  for (std::size_t i = 0; i < candidates.size(); ++i)
    by_level[std::max(0, candidates[i].octave)].push_back(i);
  out.reserve(keep);
  const double fraction = static_cast<double>(keep) / static_cast<double>(candidates.size());
  for (const auto& [level, members] : by_level) {
    const auto share = static_cast<std::size_t>(std::lround(fraction * members.size()));
    const double cell = cell_px * std::pow(scale_factor, level);  // input pixels
    std::map<std::pair<int, int>, std::vector<std::size_t>> cells;
    for (std::size_t i : members) {
      const cv::Point2f& pt = candidates[i].pt;
      cells[{static_cast<int>(pt.y / cell), static_cast<int>(pt.x / cell)}].push_back(i);
    }
    for (auto& [c, v] : cells) std::sort(v.begin(), v.end(), stronger);
    std::size_t taken = 0;
    for (std::size_t round = 0; taken < share; ++round) {
      std::vector<std::size_t> layer;
      for (const auto& [c, v] : cells)
        if (round < v.size()) layer.push_back(v[round]);
      if (layer.empty()) break;
      std::sort(layer.begin(), layer.end(), stronger);
      for (std::size_t i = 0; i < layer.size() && taken < share; ++i, ++taken)
        out.push_back(layer[i]);
    }
  }
  return out;
}

void FeatureExtractor::detect_and_describe(const cv::Mat& grey, std::vector<cv::KeyPoint>* kps,
                                           cv::Mat* desc) const {
  if (!wide_detector_) {
    detector_->detectAndCompute(grey, cv::noArray(), *kps, *desc);
    return;
  }
  // One pyramid for detection and description: describing the few extra corners costs less than
  // building the pyramid again for the kept ones.
  std::vector<cv::KeyPoint> candidates;
  cv::Mat all;
  wide_detector_->detectAndCompute(grey, cv::noArray(), candidates, all);
  const std::vector<std::size_t> kept =
      spread_keypoints(candidates, static_cast<std::size_t>(options_.orb_features),
                       options_.orb_scale_factor, options_.orb_spread_cell_px);
  kps->clear();
  kps->reserve(kept.size());
  *desc = cv::Mat(static_cast<int>(kept.size()), all.cols, all.type());
  for (std::size_t r = 0; r < kept.size(); ++r) {
    kps->push_back(candidates[kept[r]]);
    all.row(static_cast<int>(kept[r])).copyTo(desc->row(static_cast<int>(r)));
  }
}

void FeatureExtractor::orb_keypoints_to_pixel_centres(const cv::Size& input,
                                                      std::vector<cv::KeyPoint>* kps) const {
  for (cv::KeyPoint& kp : *kps) {
    if (kp.octave <= 0) continue;
    // cv::ORB's level sizes (orb.cpp) and its keypoint scale s_L: pt = level pixel x s_L.
    const double s = std::pow(options_.orb_scale_factor, kp.octave);
    const double level_w = std::round(input.width / s), level_h = std::round(input.height / s);
    if (!(level_w > 0 && level_h > 0)) continue;
    const double rx = input.width / level_w, ry = input.height / level_h;
    kp.pt.x = static_cast<float>((kp.pt.x / s + 0.5) * rx - 0.5);
    kp.pt.y = static_cast<float>((kp.pt.y / s + 0.5) * ry - 0.5);
  }
}

std::optional<FrameFeatures> FeatureExtractor::extract(const RgbdFrame& frame,
                                                       std::string* error) const {
  if (frame.rgb.empty() || frame.depth.empty()) {
    if (error) *error = "features: empty colour or depth image";
    return std::nullopt;
  }
  if (frame.depth.type() != CV_16UC1 ||
      (frame.rgb.type() != CV_8UC3 && frame.rgb.type() != CV_8UC1)) {
    if (error) *error = "features: expected 8-bit colour and 16-bit depth images";
    return std::nullopt;
  }
  if (frame.rgb.size() != frame.depth.size()) {
    if (error) *error = "features: colour and depth images differ in size";
    return std::nullopt;
  }
  cv::Mat grey;
  if (frame.rgb.channels() == 3)
    cv::cvtColor(frame.rgb, grey, cv::COLOR_BGR2GRAY);
  else
    grey = frame.rgb;

  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  try {
    if (options_.kind == DetectorKind::kSift && !options_.sift_upsample_first_octave) {
      cv::Mat half;
      cv::resize(grey, half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
      detector_->detectAndCompute(half, cv::noArray(), kps, desc);
      for (auto& kp : kps) {
        // Pixel centres: input = 2 * half + 0.5 (INTER_AREA averages 2x2 blocks).
        kp.pt = cv::Point2f(2.0f * kp.pt.x + 0.5f, 2.0f * kp.pt.y + 0.5f);
        kp.size *= 2.0f;
      }
    } else {
      detect_and_describe(grey, &kps, &desc);
      if (options_.kind == DetectorKind::kOrb && options_.orb_pixel_centres)
        orb_keypoints_to_pixel_centres(grey.size(), &kps);
    }
  } catch (const cv::Exception& e) {
    if (error) *error = std::string("features: detector failed: ") + e.what();
    return std::nullopt;
  }
  FrameFeatures out;
  out.detected = kps.size();
  if (kps.empty()) return out;

  std::vector<cv::Point2f> pix(kps.size());
  for (std::size_t i = 0; i < kps.size(); ++i) pix[i] = kps[i].pt;
  std::vector<cv::Point2f> undist = pix;
  if (options_.undistort) {
    const cv::Matx33d K(intrinsics_.fx_px, 0, intrinsics_.cx_px, 0, intrinsics_.fy_px,
                        intrinsics_.cy_px, 0, 0, 1);
    cv::undistortPoints(pix, undist, K, cv::Mat(intrinsics_.distortion, false), cv::noArray(), K);
  }
  const int w = frame.depth.cols, h = frame.depth.rows;
  std::vector<int> keep;
  keep.reserve(kps.size());
  auto depthless = std::make_shared<FrameFeatures>();
  std::vector<int> keep_depthless;
  for (std::size_t i = 0; i < kps.size(); ++i) {
    const int u = static_cast<int>(std::lround(pix[i].x));
    const int v = static_cast<int>(std::lround(pix[i].y));
    if (u < 0 || v < 0 || u >= w || v >= h) continue;
    const std::uint16_t raw = frame.depth.at<std::uint16_t>(v, u);
    const double z = raw / intrinsics_.depth_units_per_m;
    if (raw == 0 || z < options_.min_depth_m || z > options_.max_depth_m) {
      keep_depthless.push_back(static_cast<int>(i));
      depthless->keypoints.push_back(kps[i]);
      depthless->points_cam_m.push_back(back_project(intrinsics_, undist[i].x, undist[i].y, 1.0));
      continue;
    }
    keep.push_back(static_cast<int>(i));
    out.keypoints.push_back(kps[i]);
    out.points_cam_m.push_back(back_project(intrinsics_, undist[i].x, undist[i].y, z));
    out.colours_bgr.push_back(frame.rgb.channels() == 3
                                  ? frame.rgb.at<cv::Vec3b>(v, u)
                                  : cv::Vec3b::all(grey.at<std::uint8_t>(v, u)));
    out.depth_slope_m_per_px.push_back(
        static_cast<float>(depth_slope_m_per_px(frame.depth, u, v, intrinsics_.depth_units_per_m)));
  }
  auto copy_rows = [&desc](const std::vector<int>& rows, cv::Mat* to) {
    to->create(static_cast<int>(rows.size()), desc.cols, desc.type());
    for (std::size_t r = 0; r < rows.size(); ++r)
      desc.row(rows[r]).copyTo(to->row(static_cast<int>(r)));
  };
  copy_rows(keep, &out.descriptors);
  if (!keep_depthless.empty()) {
    copy_rows(keep_depthless, &depthless->descriptors);
    depthless->detected = keep_depthless.size();
    out.depthless = std::move(depthless);
  }
  return out;
}

}  // namespace rgbdquad::slam
