// Map points from keypoints without depth: the triangulation's geometry and gates on synthetic
// keyframes, the map's bookkeeping of depthless observations, and what a saved map keeps of them.
#include "slam/mapping/depthless_triangulation.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "slam/map/map_io.hpp"
#include "synthetic_scene.hpp"

namespace rgbdquad::slam {
namespace {

using namespace synthetic;  // NOLINT(build/namespaces): the scene helpers

/// A far wall, 5-8 m ahead of the world camera: beyond the Kinect's depth range.
std::vector<Eigen::Vector3d> far_wall(int n, std::uint32_t seed) {
  std::vector<Eigen::Vector3d> pts = scene(n, seed);
  for (Eigen::Vector3d& p : pts) p = Eigen::Vector3d(2.5 * p.x(), 2.5 * p.y(), 3.0 + 1.5 * p.z());
  return pts;
}

/// Two keyframes that share `near` points (with depth: their covisibility) and see `far` points
/// only as depthless keypoints. Keyframe ids 1 and 2; map points 0.. are the near ones.
struct TwoKeyframes {
  SlamMap map;
  std::vector<Eigen::Vector3d> far;
};

MapKeyframe keyframe(std::int64_t id, const Eigen::Isometry3d& T_world_cam,
                     const std::vector<Eigen::Vector3d>& near, const cv::Mat& near_desc,
                     const std::vector<Eigen::Vector3d>& far, const cv::Mat& far_desc,
                     const CameraModel& cam) {
  MapKeyframe kf;
  kf.id = id;
  kf.T_world_cam = T_world_cam;
  kf.features = make_frame(near, T_world_cam.inverse(), near_desc, cam).tracked;
  SyntheticFrame d = make_frame(far, T_world_cam.inverse(), far_desc, cam);
  drop_depth(&d, cam);
  kf.depthless = d.tracked;
  return kf;
}

TwoKeyframes two_keyframes(const Eigen::Isometry3d& T_world_b, const cv::Mat& far_desc_b) {
  const CameraModel cam = fr1_camera();
  TwoKeyframes t;
  // Near points 2.5-3.5 m ahead and within 0.3 m of the axis: in view of both keyframes.
  std::vector<Eigen::Vector3d> near = scene(30, 41);
  for (Eigen::Vector3d& p : near) p = Eigen::Vector3d(0.3 * p.x(), 0.3 * p.y(), 2.0 + 0.5 * p.z());
  const cv::Mat near_desc = random_descriptors(30, 42);
  t.far = far_wall(120, 43);
  const cv::Mat far_desc = random_descriptors(120, 44);
  const Eigen::Isometry3d T_world_a = Eigen::Isometry3d::Identity();
  t.map.add_keyframe(keyframe(1, T_world_a, near, near_desc, t.far, far_desc, cam));
  t.map.add_keyframe(keyframe(2, T_world_b, near, near_desc, t.far, far_desc_b, cam));
  // Every near point is seen by both (make_frame keeps those in view, in order).
  const MapKeyframe* a = t.map.keyframe(1);
  const MapKeyframe* b = t.map.keyframe(2);
  EXPECT_EQ(a->features.size(), 30u);
  EXPECT_EQ(b->features.size(), 30u);
  for (int k = 0; k < 30; ++k) {
    const std::int64_t pid =
        t.map.add_point(near[static_cast<std::size_t>(k)], near_desc.row(k), 1, k);
    t.map.add_observation(pid, 2, k);
  }
  return t;
}

/// The far point whose projection in keyframe `id` is keypoint `kp` (depthless range).
std::size_t truth_of(const TwoKeyframes& t, std::int64_t id, int kp, const CameraModel& cam) {
  const MapKeyframe* kf = t.map.keyframe(id);
  const Eigen::Vector2d px =
      kf->depthless.pixels[static_cast<std::size_t>(kp) - kf->features.size()];
  std::size_t best = 0;
  double best_d = 1e300;
  for (std::size_t i = 0; i < t.far.size(); ++i) {
    const Eigen::Vector3d pc = kf->T_world_cam.inverse() * t.far[i];
    const double d = (cam.project(pc).head<2>() - px).norm();
    if (pc.z() > 0 && d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

TEST(TriangulateLinear, RecoversAPointSeenFromTwoCameras) {
  const Eigen::Vector3d p(0.4, -0.3, 6.0);
  const Eigen::Isometry3d a = pose(0.01, -0.02, 0.03, 0, 0, 0);
  const Eigen::Isometry3d b = pose(-0.02, 0.05, 0, 0.4, 0.05, 0.1);
  auto bearing = [&](const Eigen::Isometry3d& T) {
    const Eigen::Vector3d pc = T.inverse() * p;
    return Eigen::Vector2d(pc.x() / pc.z(), pc.y() / pc.z());
  };
  const auto got = triangulate_linear(a, bearing(a), b, bearing(b));
  ASSERT_TRUE(got.has_value());
  EXPECT_LT((*got - p).norm(), 1e-9);
}

TEST(TriangulateDepthless, AFarWallSeenFromTwoKeyframesBecomesPointsEachFromItsOwnKeypoints) {
  // GIVEN two keyframes 0.4 m apart, turned 3 deg, seeing a wall 5-8 m away without depth
  const CameraModel cam = fr1_camera();
  const TwoKeyframes t =
      two_keyframes(pose(0, 0.05, 0, 0.4, 0.02, 0.1), random_descriptors(120, 44));
  // WHEN the newer keyframe is triangulated against its covisible one
  const TriangulationOptions o;
  const TriangulationView view = triangulation_view(t.map, 2, o);
  ASSERT_EQ(view.neighbours.size(), 1u);
  const auto points = triangulate_depthless(view, cam, o);
  // THEN most wall points seen by both come back, at their place, each from one keypoint pair
  // whose keypoints are that point's projections
  const std::size_t in_both =
      std::min(t.map.keyframe(1)->depthless.size(), t.map.keyframe(2)->depthless.size());
  EXPECT_GE(points.size(), in_both * 3 / 4);
  std::set<int> used_a, used_b;
  for (const TriangulatedPoint& p : points) {
    EXPECT_EQ(p.kf_a, 2);
    EXPECT_EQ(p.kf_b, 1);
    EXPECT_TRUE(used_a.insert(p.kp_a).second);
    EXPECT_TRUE(used_b.insert(p.kp_b).second);
    const std::size_t i = truth_of(t, 2, p.kp_a, cam);
    EXPECT_EQ(truth_of(t, 1, p.kp_b, cam), i);
    EXPECT_LT((p.p_world_m - t.far[i]).norm(), 1e-6);
  }
}

TEST(TriangulateDepthless, NothingWithinTheStereoBaselineOrWithForeignDescriptors) {
  const CameraModel cam = fr1_camera();
  const TriangulationOptions o;
  // GIVEN keyframes 5 cm apart: less than the camera's own baseline (bf / fx = 7.7 cm). The
  // parallax gate is opened so that only the baseline can refuse them: 10 cm apart, the same
  // settings do triangulate.
  TriangulationOptions any_parallax;
  any_parallax.max_cos_parallax = 1 - 1e-12;
  const TwoKeyframes close =
      two_keyframes(pose(0, 0.05, 0, 0.05, 0, 0), random_descriptors(120, 44));
  EXPECT_TRUE(
      triangulate_depthless(triangulation_view(close.map, 2, any_parallax), cam, any_parallax)
          .empty());
  const TwoKeyframes apart =
      two_keyframes(pose(0, 0.05, 0, 0.10, 0, 0), random_descriptors(120, 44));
  EXPECT_FALSE(
      triangulate_depthless(triangulation_view(apart.map, 2, any_parallax), cam, any_parallax)
          .empty());
  // AND keyframes far enough apart whose depthless descriptors share nothing
  const TwoKeyframes foreign =
      two_keyframes(pose(0, 0.05, 0, 0.4, 0.02, 0.1), random_descriptors(120, 99));
  EXPECT_TRUE(triangulate_depthless(triangulation_view(foreign.map, 2, o), cam, o).empty());
}

TEST(MapKeyframe, ADepthlessObservationIsJudgedInTwoDegreesOfFreedom) {
  const CameraModel cam = fr1_camera();
  TwoKeyframes t = two_keyframes(pose(0, 0.05, 0, 0.4, 0.02, 0.1), random_descriptors(120, 44));
  const MapKeyframe* a = t.map.keyframe(1);
  const int kp = static_cast<int>(a->features.size());  // depthless keypoint 0
  ASSERT_TRUE(a->is_depthless(kp));
  ASSERT_FALSE(a->is_depthless(kp - 1));
  EXPECT_EQ(a->chi2_bound(kp), kChi2Mono95);
  EXPECT_EQ(a->chi2_bound(0), kChi2Rgbd95);
  // The wall point itself, and the same point at another depth along the ray: both fit exactly.
  const std::size_t i = truth_of(t, 1, kp, cam);
  EXPECT_LT(a->chi2(kp, t.far[i], cam), 1e-9);
  EXPECT_LT(a->chi2(kp, 0.5 * t.far[i], cam), 1e-9);
  EXPECT_EQ(a->chi2(kp, -t.far[i], cam), 1e9);
}

TEST(MapIo, DepthlessObservationsAndThePointsOnlyTheyHoldAreNotSaved) {
  // GIVEN the two keyframes, their near points, and one triangulated wall point
  const CameraModel cam = fr1_camera();
  TwoKeyframes t = two_keyframes(pose(0, 0.05, 0, 0.4, 0.02, 0.1), random_descriptors(120, 44));
  const TriangulationOptions o;
  const auto points = triangulate_depthless(triangulation_view(t.map, 2, o), cam, o);
  ASSERT_FALSE(points.empty());
  const TriangulatedPoint& w = points.front();
  const std::int64_t wall =
      t.map.add_point(w.p_world_m,
                      t.map.keyframe(2)->depthless.features->descriptors.row(
                          w.kp_a - static_cast<int>(t.map.keyframe(2)->features.size())),
                      w.kf_a, w.kp_a);
  t.map.add_observation(wall, w.kf_b, w.kp_b);
  ASSERT_EQ(t.map.keyframe(1)->point_ids[static_cast<std::size_t>(w.kp_b)], wall);
  ASSERT_EQ(t.map.points().size(), 31u);
  // WHEN saved and loaded
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  const std::string path =
      (std::filesystem::temp_directory_path() / ("depthless_map_" + std::to_string(::getpid())))
          .string();
  std::string err;
  ASSERT_TRUE(save_map(path, t.map, MapFileContext{cam, fo}, &err)) << err;
  const auto loaded = load_map(path, MapFileContext{cam, fo}, &err);
  std::filesystem::remove(path);
  // THEN the near points and their observations are whole; the wall point is gone
  ASSERT_TRUE(loaded.has_value()) << err;
  EXPECT_EQ(loaded->points().size(), 30u);
  EXPECT_FALSE(loaded->has_point(wall));
  for (const auto& [pid, p] : loaded->points()) EXPECT_EQ(p.observations.size(), 2u);
  EXPECT_EQ(loaded->keyframe(1)->point_ids.size(), loaded->keyframe(1)->features.size());
}

}  // namespace
}  // namespace rgbdquad::slam
