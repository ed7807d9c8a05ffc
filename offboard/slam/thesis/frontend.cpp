// Front-end: features + frame-to-frame egomotion.
#include "slam/thesis/frontend.hpp"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <numeric>

namespace rgbdquad::slam {

bool FrontendOptions::is_valid(std::string* error) const {
  if (!features.is_valid(error) || !matching.is_valid(error) || !ransac.is_valid(error))
    return false;
  if (min_inliers < 3) {
    if (error) *error = "frontend: min_inliers must be >= 3";
    return false;
  }
  return true;
}

std::optional<MotionEstimate> estimate_between(const FrameFeatures& cur, const FrameFeatures& ref,
                                               const MatchOptions& mo, const RansacOptions& ro,
                                               std::uint64_t seed, std::size_t* matches_out,
                                               double* matching_ms, double* ransac_ms) {
  const std::int64_t t0 = steady_now_ns();
  const std::vector<Match> m = match_descriptors(cur.descriptors, ref.descriptors, mo);
  if (matching_ms) *matching_ms += ms_since(t0);
  if (matches_out) *matches_out = m.size();
  const std::int64_t t1 = steady_now_ns();
  std::vector<Eigen::Vector3d> src, dst;
  src.reserve(m.size());
  dst.reserve(m.size());
  for (const Match& x : m) {
    src.push_back(cur.points_cam_m[static_cast<std::size_t>(x.query)]);
    dst.push_back(ref.points_cam_m[static_cast<std::size_t>(x.train)]);
  }
  std::vector<int> order(m.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return m[static_cast<std::size_t>(a)].distance < m[static_cast<std::size_t>(b)].distance;
  });
  auto est = estimate_motion_ransac(src, dst, order, ro, seed, nullptr);
  if (ransac_ms) *ransac_ms += ms_since(t1);
  return est;
}

FrontEnd::FrontEnd(FrontendOptions options, FeatureExtractor extractor)
    : options_(std::move(options)), extractor_(std::move(extractor)) {}

std::optional<FrontEnd> FrontEnd::create(const FrontendOptions& o, const Intrinsics& k,
                                         std::string* error) {
  if (!o.is_valid(error)) return std::nullopt;
  auto ex = FeatureExtractor::create(o.features, k, error);
  if (!ex) return std::nullopt;
  return FrontEnd(o, std::move(*ex));
}

std::optional<FrontendOutput> FrontEnd::process(const RgbdFrame& frame, std::string* error) {
  const std::int64_t t0 = steady_now_ns();
  const std::int64_t c0 = thread_cpu_now_ns();
  FrontendOutput out;
  out.index = frame.index;
  out.stamp_s = frame.stamp_s;
  out.frame = frame;
  auto feats = extractor_.extract(frame, error);
  if (!feats) return std::nullopt;
  out.features = std::make_shared<const FrameFeatures>(std::move(*feats));
  out.features_ms = ms_since(t0);
  if (!prev_) {
    out.state = TrackingState::kInitialising;
  } else {
    const std::uint64_t seed =
        options_.seed ^ (static_cast<std::uint64_t>(frame.index) * 0x9E3779B97F4A7C15ull);
    auto est = estimate_between(*out.features, *prev_, options_.matching, options_.ransac, seed,
                                &out.matches, &out.matching_ms, &out.ransac_ms);
    if (est && est->inliers.size() >= options_.min_inliers) {
      out.T_prev_cur = est->T_dst_src;
      out.inliers = est->inliers.size();
      out.rms_error_m = est->rms_error_m;
      out.state = TrackingState::kTracking;
    } else {
      out.state = TrackingState::kLost;  // motion unknown: hold the pose
      out.inliers = est ? est->inliers.size() : 0;
    }
  }
  out.T_odom_cam = T_odom_prev_ * out.T_prev_cur;
  T_odom_prev_ = out.T_odom_cam;
  prev_ = out.features;
  out.total_ms = ms_since(t0);
  out.total_cpu_ms = (thread_cpu_now_ns() - c0) * 1e-6;
  return out;
}

}  // namespace rgbdquad::slam
