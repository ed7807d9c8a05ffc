// Unit tests of the local-map SLAM stages on synthetic data: motion-only pose optimisation,
// matching by projection, the map store (observations, fusion, culling chains), thumbnails.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "slam/features/features.hpp"
#include "slam/map/map.hpp"
#include "slam/map/place_index.hpp"
#include "slam/tracking/gravity_prior.hpp"
#include "slam/tracking/motion_bound.hpp"
#include "slam/tracking/pose_optimizer.hpp"
#include "slam/tracking/projection_search.hpp"
#include "slam/tracking/registration.hpp"
#include "synthetic_scene.hpp"

namespace rgbdquad::slam {
namespace {

using namespace synthetic;  // NOLINT(build/namespaces): the scene helpers

std::vector<PoseObservation> observe(const std::vector<Eigen::Vector3d>& pts,
                                     const Eigen::Isometry3d& T_cam_world, const CameraModel& cam,
                                     double noise_px, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise_px);
  std::vector<PoseObservation> obs;
  for (const auto& p : pts) {
    const Eigen::Vector3d z =
        cam.project(T_cam_world * p) + Eigen::Vector3d(n(rng), n(rng), 0.1 * n(rng));
    obs.push_back(PoseObservation{p, z, Eigen::Vector3d::Ones()});
  }
  return obs;
}

TEST(PoseOptimizer, RecoversThePoseFromAPerturbedStartWithNoiseFreeObservations) {
  // GIVEN 200 points seen exactly from a known pose
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(0.05, -0.1, 0.03, 0.1, -0.05, 0.2);
  const auto obs = observe(scene(200, 1), truth, cam, 0.0, 2);
  // WHEN the optimiser starts 5 cm and ~3 deg away
  const PoseOptimizerResult r = optimize_pose(pose(0.0, -0.05, 0.0, 0.15, -0.02, 0.17), obs, cam);
  // THEN it lands on the truth and keeps every observation
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.inliers, 200);
  EXPECT_LT((r.T_cam_world.translation() - truth.translation()).norm(), 1e-6);
  EXPECT_LT(Eigen::AngleAxisd(r.T_cam_world.rotation().transpose() * truth.rotation()).angle(),
            1e-6);
}

TEST(PoseOptimizer, RejectsGrossOutliersAndStaysAccurate) {
  // GIVEN 1 px noise and 30 % of the observations moved 40 px away
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(-0.02, 0.04, 0.01, -0.1, 0.02, 0.05);
  auto obs = observe(scene(300, 3), truth, cam, 1.0, 4);
  for (std::size_t i = 0; i < obs.size(); i += 3) obs[i].measurement.x() += 40.0;
  // WHEN
  const PoseOptimizerResult r = optimize_pose(truth * pose(0.01, 0.0, 0.0, 0.02, 0, 0), obs, cam);
  // THEN the moved ones are outliers and the pose is within a millimetre-level error
  ASSERT_TRUE(r.ok);
  int flagged = 0;
  for (std::size_t i = 0; i < obs.size(); i += 3) flagged += r.inlier[i] ? 0 : 1;
  EXPECT_EQ(flagged, 100);
  EXPECT_LT((r.T_cam_world.translation() - truth.translation()).norm(), 0.005);
}

/// What a rolling-shutter camera sees of `pts`: the camera is at `T_cam_world` when its middle
/// row is exposed and turns at `omega` (camera frame); row r is exposed (r - mid) * row_s later.
/// Returns the observations and, per observation, its row time.
std::pair<std::vector<PoseObservation>, std::vector<double>> observe_rolling(
    const std::vector<Eigen::Vector3d>& pts, const Eigen::Isometry3d& T_cam_world,
    const Eigen::Vector3d& omega, double readout_s, const CameraModel& cam, double noise_px,
    std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise_px);
  const double row_s = readout_s / cam.height_px, mid = 0.5 * (cam.height_px - 1);
  std::vector<PoseObservation> obs;
  std::vector<double> row_time;
  for (const auto& p : pts) {
    const Eigen::Vector3d pc = T_cam_world * p;
    Eigen::Vector3d uvd = cam.project(pc);
    double t = 0;
    for (int it = 0; it < 5; ++it) {  // the row a point lands on depends on when it was exposed
      t = (uvd.y() - mid) * row_s;
      uvd = cam.project(Eigen::AngleAxisd(-omega.norm() * t, omega.normalized()) * pc);
    }
    uvd += Eigen::Vector3d(n(rng), n(rng), 0.1 * n(rng));
    obs.push_back(PoseObservation{p, uvd, Eigen::Vector3d::Ones()});
    row_time.push_back((uvd.y() - mid) * row_s);
  }
  return {obs, row_time};
}

double rotation_error_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.rotation().transpose() * b.rotation()).angle();
}

TEST(PoseOptimizer, GivenARollingShutterFrameThenTheRateIsEstimatedAndThePoseIsUnbiased) {
  // GIVEN a camera turning at ~75 deg/s with a 24 ms readout (the Kinect v1's colour camera), 300
  // points seen with 0.5 px noise, and a motion model whose rate is 0.5 rad/s off
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(0.05, -0.1, 0.03, 0.1, -0.05, 0.2);
  const Eigen::Vector3d omega(0.3, 1.2, -0.2);
  const auto [obs, row_time] = observe_rolling(scene(300, 5), truth, omega, 0.024, cam, 0.5, 6);
  // WHEN fitted as a global shutter, and with the rate over the readout as unknowns
  const PoseOptimizerResult global = optimize_pose(truth, obs, cam);
  PoseOptimizerOptions o;
  o.rolling_shutter = RollingShutterModel{row_time, omega + Eigen::Vector3d(0.5, 0.0, -0.3), 1.0};
  const PoseOptimizerResult rolling = optimize_pose(truth, obs, cam, o);
  // THEN the global-shutter fit is biased (the skew of the rows read as a turn and a shift) ...
  ASSERT_TRUE(global.ok);
  ASSERT_TRUE(rolling.ok);
  const double global_m = (global.T_cam_world.translation() - truth.translation()).norm();
  EXPECT_GT(global_m, 0.003);
  // ... the rolling-shutter fit finds the rate from the rows, not from its prior ...
  EXPECT_LT((rolling.omega_cam_rad_per_s - omega).norm(), 0.1);
  // ... keeps every observation, and lands several times closer to the truth
  EXPECT_EQ(rolling.inliers, 300);
  EXPECT_LT((rolling.T_cam_world.translation() - truth.translation()).norm(), 0.2 * global_m);
  EXPECT_LT(rotation_error_rad(rolling.T_cam_world, truth),
            0.2 * rotation_error_rad(global.T_cam_world, truth));
}

TEST(PoseOptimizer, GivenAGlobalShutterFrameThenTheRollingShutterFitFindsNoRate) {
  // GIVEN exact observations of a still camera and a motion model that predicts 1 rad/s
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(-0.02, 0.04, 0.01, -0.1, 0.02, 0.05);
  const auto [obs, row_time] =
      observe_rolling(scene(200, 7), truth, Eigen::Vector3d(0, 1e-12, 0), 0.024, cam, 0.0, 8);
  PoseOptimizerOptions o;
  o.rolling_shutter = RollingShutterModel{row_time, Eigen::Vector3d(0.0, 1.0, 0.0), 1.0};
  // WHEN fitted with the rate as unknowns
  const PoseOptimizerResult r = optimize_pose(truth, obs, cam, o);
  // THEN the rows say the camera did not turn (the prior moves it by what 200 rows outweigh), and
  // the pose is the truth to well under a millimetre
  ASSERT_TRUE(r.ok);
  EXPECT_LT(r.omega_cam_rad_per_s.norm(), 1e-2);
  EXPECT_LT((r.T_cam_world.translation() - truth.translation()).norm(), 1e-4);
}

TEST(CameraModel, DisparitySigmaFollowsTheChosenDepthNoiseModel) {
  CameraModel cam = fr1_camera();
  // ORB-SLAM2's virtual stereo: the keypoint's own sigma, whatever the depth
  cam.depth_noise = DepthNoiseModel::kKeypointSigma;
  EXPECT_DOUBLE_EQ(cam.disparity_sigma_px(1.0, 1.0), 1.0);
  EXPECT_DOUBLE_EQ(cam.disparity_sigma_px(3.0, 2.0), 2.0);
  // Kinect axial noise (Nguyen et al. 2012): sigma_z(1 m) = 1.2 + 1.9 * 0.36 mm = 1.884 mm,
  // sigma_d = 40 px m * 1.884 mm / 1 m^2
  cam.depth_noise = DepthNoiseModel::kKinectAxial;
  EXPECT_NEAR(cam.disparity_sigma_px(1.0, 1.0), 40.0 * 0.001884, 1e-12);
  // sigma_z(3 m) = 1.2 + 1.9 * 6.76 mm = 14.044 mm: the disparity sigma is nearly flat in depth
  EXPECT_NEAR(cam.disparity_sigma_px(3.0, 1.0), 40.0 * 0.014044 / 9.0, 1e-12);
  // never below the quantisation of 1/8 px steps, and far tighter than a keypoint's pixel sigma
  for (double z = 0.5; z <= 4.0; z += 0.1) {  // 0.5-4 m: the sensor's working range
    EXPECT_GE(cam.disparity_sigma_px(z, 1.0), CameraModel::kMinDisparitySigmaPx);
    EXPECT_LT(cam.disparity_sigma_px(z, 1.0), 0.5);
  }
  DepthNoiseModel m;
  std::string err;
  EXPECT_TRUE(parse_depth_noise_model("kinect", &m, &err));
  EXPECT_EQ(m, DepthNoiseModel::kKinectAxial);
  EXPECT_FALSE(parse_depth_noise_model("sonar", &m, &err));
}

TEST(CameraModel, GivenTheEdgeModelThenTheDepthSlopeTimesThePixelSigmaAddsInQuadrature) {
  CameraModel cam = fr1_camera();
  cam.depth_noise = DepthNoiseModel::kKinectEdge;
  // a flat patch: the axial noise alone (as kKinectAxial)
  EXPECT_NEAR(cam.disparity_sigma_px(1.0, 1.0, 0.0), 40.0 * 0.001884, 1e-12);
  // 5 mm per px at a keypoint of sigma 2 px: sigma_z = hypot(1.884, 10) mm at 1 m
  EXPECT_NEAR(cam.disparity_sigma_px(1.0, 2.0, 0.005), 40.0 * std::hypot(0.001884, 0.010), 1e-12);
  // the slope does nothing under the other models
  cam.depth_noise = DepthNoiseModel::kKinectAxial;
  EXPECT_NEAR(cam.disparity_sigma_px(1.0, 2.0, 0.005), 40.0 * 0.001884, 1e-12);
  DepthNoiseModel m;
  std::string err;
  EXPECT_TRUE(parse_depth_noise_model("kinect-edge", &m, &err));
  EXPECT_EQ(m, DepthNoiseModel::kKinectEdge);
  EXPECT_STREQ(to_string(m), "kinect-edge");
}

TEST(DepthSlope, GivenAStepARampAndHolesThenTheSlopeIsTheLargerNeighbourDifference) {
  // 5000 units per metre (TUM); a ramp along u of 2 mm per px, a 0.5 m step along v at row 3
  cv::Mat depth(6, 6, CV_16UC1);
  for (int v = 0; v < 6; ++v)
    for (int u = 0; u < 6; ++u)
      depth.at<std::uint16_t>(v, u) =
          static_cast<std::uint16_t>(5000 + 10 * u + (v >= 3 ? 2500 : 0));
  EXPECT_NEAR(depth_slope_m_per_px(depth, 2, 1, 5000.0), 0.002, 1e-9);  // the ramp (central)
  EXPECT_NEAR(depth_slope_m_per_px(depth, 2, 3, 5000.0), 0.25,
              1e-9);                  // the step: central, 0.5 m / 2 px
  depth.at<std::uint16_t>(1, 1) = 0;  // a hole left of (2, 1): one-sided along u
  EXPECT_NEAR(depth_slope_m_per_px(depth, 2, 1, 5000.0), 0.002, 1e-9);
  EXPECT_EQ(depth_slope_m_per_px(depth, 1, 1, 5000.0), 0.0);            // no reading: no slope
  EXPECT_NEAR(depth_slope_m_per_px(depth, 0, 0, 5000.0), 0.002, 1e-9);  // image border: one-sided
}

TEST(MotionBound, ExtrapolatesTheMeanVelocityOverTheBaselineAndBoundsTheDeviation) {
  MotionBound b;  // margin 0.05 m, 5 m/s^2, baseline 0.1 s
  // GIVEN fewer than two positions THEN nothing is checked (and anything is within)
  EXPECT_FALSE(b.check(0.0, Eigen::Vector3d::Zero()).checked);
  b.add(0.0, Eigen::Vector3d::Zero());
  EXPECT_TRUE(b.check(1.0, Eigen::Vector3d(100, 0, 0)).within());
  // GIVEN positions at 1 m/s along x every 33 ms, the last at t = 0.198 s, with 1 cm of noise on
  // the one 33 ms before the last (a one-interval velocity would be off by 0.3 m/s)
  for (int k = 1; k <= 6; ++k)
    b.add(0.033 * k, Eigen::Vector3d(0.033 * k + (k == 5 ? 0.01 : 0.0), 0, 0));
  // WHEN checked 0.1 s later on the path THEN the deviation is zero (the velocity is taken over
  // 0.132 s back to the newest position at least 0.1 s old, not over the noisy last interval)
  const MotionBoundCheck on = b.check(0.298, Eigen::Vector3d(0.298, 0, 0));
  ASSERT_TRUE(on.checked);
  EXPECT_NEAR(on.deviation_m, 0.0, 1e-9);
  EXPECT_NEAR(on.bound_m, 0.05 + 0.5 * 5.0 * 0.1 * (0.1 + 0.132), 1e-9);
  // WHEN 0.2 m off the path THEN it is beyond the 0.108 m bound
  const MotionBoundCheck off = b.check(0.298, Eigen::Vector3d(0.298, 0.2, 0));
  EXPECT_NEAR(off.deviation_m, 0.2, 1e-9);
  EXPECT_FALSE(off.within());
  // WHEN a stamp does not increase THEN the history restarts from it
  b.add(0.1, Eigen::Vector3d::Zero());
  EXPECT_FALSE(b.check(0.2, Eigen::Vector3d::Zero()).checked);
  // WHEN reset THEN nothing is checked
  b.add(0.2, Eigen::Vector3d::Zero());
  EXPECT_TRUE(b.check(0.3, Eigen::Vector3d::Zero()).checked);
  b.reset();
  EXPECT_FALSE(b.check(0.3, Eigen::Vector3d::Zero()).checked);
}

TEST(MotionBound, KeepsABoundedHistory) {
  MotionBoundOptions o;
  o.capacity = 4;
  o.baseline_s = 10.0;  // longer than the history: the oldest kept position is used
  MotionBound b(o);
  for (int k = 0; k < 100; ++k) b.add(0.1 * k, Eigen::Vector3d(k < 96 ? 5.0 : 0.1 * k, 0, 0));
  // only the last 4 (t 9.6-9.9 s, x = t) are kept: 1 m/s, so 10.0 s extrapolates to x = 10 m
  // (with the older positions at x = 5 m the mean velocity would be far lower)
  EXPECT_NEAR(b.check(10.0, Eigen::Vector3d(10.0, 0, 0)).deviation_m, 0.0, 1e-9);
}

/// Angle between the camera's true and estimated gravity direction (its roll/pitch error), rad.
double tilt_error_rad(const Eigen::Isometry3d& est, const Eigen::Isometry3d& truth,
                      const Eigen::Vector3d& down_world) {
  const Eigen::Vector3d a = est.linear() * down_world, b = truth.linear() * down_world;
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

TEST(PoseOptimizer, GravityPriorPullsRollAndPitchTowardsTheMeasuredGravity) {
  // GIVEN 12 points seen with 2 px noise (a weak fit: blur, a bare wall) and gravity measured
  // exactly in the camera frame, trusted to 1e-4 rad
  const CameraModel cam = fr1_camera();
  const Eigen::Vector3d down_world = Eigen::Vector3d(0.1, 0.98, 0.05).normalized();
  double without = 0, with = 0;
  for (std::uint32_t seed = 0; seed < 20; ++seed) {
    const Eigen::Isometry3d truth = pose(0.05, -0.1, 0.03, 0.1, -0.05, 0.2);
    const auto obs = observe(scene(12, 100 + seed), truth, cam, 2.0, 200 + seed);
    PoseOptimizerOptions o;
    without += tilt_error_rad(optimize_pose(truth, obs, cam, o).T_cam_world, truth, down_world);
    o.gravity = GravityPrior{down_world, truth.linear() * down_world, 1e-4};
    const PoseOptimizerResult r = optimize_pose(truth, obs, cam, o);
    ASSERT_TRUE(r.ok);
    with += tilt_error_rad(r.T_cam_world, truth, down_world);
  }
  // THEN the prior removes the tilt error the points leave (summed over 20 scenes)
  EXPECT_GT(without, 20 * 1e-3);
  EXPECT_LT(with, 0.1 * without);
}

TEST(PoseOptimizer, GravityPriorLeavesTheTurnAboutGravityFree) {
  // GIVEN exact observations of a camera and a gravity prior that agrees with them
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(0.02, 0.3, -0.01, 0.05, 0.0, 0.1);
  const auto obs = observe(scene(100, 7), truth, cam, 0.0, 8);
  PoseOptimizerOptions o;
  const Eigen::Vector3d down_world = Eigen::Vector3d::UnitY();
  o.gravity = GravityPrior{down_world, truth.linear() * down_world, 1.0 * M_PI / 180.0};
  // WHEN it starts 0.1 rad off about gravity (yaw)
  Eigen::Isometry3d start = truth;
  start.linear() = truth.linear() * Eigen::AngleAxisd(0.1, down_world).toRotationMatrix();
  const PoseOptimizerResult r = optimize_pose(start, obs, cam, o);
  // THEN the points bring the yaw back: the prior neither holds it nor biases the pose
  ASSERT_TRUE(r.ok);
  EXPECT_LT(Eigen::AngleAxisd(r.T_cam_world.rotation().transpose() * truth.rotation()).angle(),
            1e-6);
}

TEST(GravityPrior, ObservedFromTheAttitudeFirstThenTheAccelerometerWhenAskedFor) {
  GravityOptions o;
  RgbdFrame f;
  EXPECT_FALSE(observe_gravity(f, o).has_value());
  // The Kinect at rest, level: the specific force points up, -y in the optical frame
  f.accel_cam_mps2 = Eigen::Vector3d(0, -9.80665, 0);
  // By default the accelerometer is no source: it measures the camera's acceleration too
  EXPECT_FALSE(observe_gravity(f, o).has_value());
  o.from_accelerometer = true;
  auto g = observe_gravity(f, o);
  ASSERT_TRUE(g);
  EXPECT_TRUE(g->down_cam.isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_DOUBLE_EQ(g->sigma_rad, o.accel_base_sigma_rad);
  // 2 m/s^2 beyond g: trusted less, by the departure in radians
  f.accel_cam_mps2 = Eigen::Vector3d(0, -11.80665, 0);
  EXPECT_NEAR(observe_gravity(f, o)->sigma_rad, o.accel_base_sigma_rad + 2.0 / 9.80665, 1e-12);
  // An attitude in NED wins: identity = camera axes along NED, gravity along the camera's +z
  f.q_nav_cam = Eigen::Quaterniond::Identity();
  g = observe_gravity(f, o);
  ASSERT_TRUE(g);
  EXPECT_TRUE(g->down_cam.isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_DOUBLE_EQ(g->sigma_rad, o.attitude_sigma_rad);
}

TEST(GravityPrior, ReferenceIsTheWeightedMeanOfTheFirstKeyframesThenHeld) {
  GravityReference ref(2);
  EXPECT_FALSE(ref.down_world().has_value());
  ref.add(Eigen::Matrix3d::Identity(), GravityObservation{Eigen::Vector3d::UnitY(), 0.1});
  ref.add(Eigen::Matrix3d::Identity(), GravityObservation{Eigen::Vector3d::UnitX(), 0.1});
  ASSERT_TRUE(ref.held());
  EXPECT_TRUE(ref.down_world()->isApprox(Eigen::Vector3d(1, 1, 0).normalized(), 1e-12));
  ref.add(Eigen::Matrix3d::Identity(), GravityObservation{Eigen::Vector3d::UnitZ(), 0.1});
  EXPECT_TRUE(ref.down_world()->isApprox(Eigen::Vector3d(1, 1, 0).normalized(), 1e-12));
}

TEST(PoseOptimizer, MonocularObservationsFixThePoseWithoutTheirDisparity) {
  // GIVEN 100 points seen exactly, but as keypoints without depth whose disparity is nonsense
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(0.05, -0.1, 0.03, 0.1, -0.05, 0.2);
  auto obs = observe(scene(100, 21), truth, cam, 0.0, 22);
  for (PoseObservation& o : obs) o.measurement.z() = 99.0;
  const Eigen::Isometry3d start = pose(0.0, -0.05, 0.0, 0.12, -0.03, 0.18);
  auto as_rgbd = obs;
  for (PoseObservation& o : obs) o.monocular = true;
  // WHEN fitted as monocular observations
  const PoseOptimizerResult r = optimize_pose(start, obs, cam);
  // THEN their pixels alone give the pose, every one an inlier
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.inliers, 100);
  EXPECT_LT((r.T_cam_world.translation() - truth.translation()).norm(), 1e-6);
  EXPECT_LT(Eigen::AngleAxisd(r.T_cam_world.rotation().transpose() * truth.rotation()).angle(),
            1e-6);
  // AND read as RGB-D the same disparities reject them all (the flag is what ignores them)
  EXPECT_LT(optimize_pose(start, as_rgbd, cam).inliers, 10);
}

TEST(PoseOptimizer, AMonocularObservationIsJudgedAtTheTwoDegreeOfFreedomBound) {
  // GIVEN 60 exact observations and one whose pixel is off by a whitened squared error of 6.9:
  // past the 2-dof 95 % bound (5.99), within the 3-dof one (7.81)
  const CameraModel cam = fr1_camera();
  const Eigen::Isometry3d truth = pose(0.0, 0.02, 0.0, 0.0, 0.0, 0.1);
  for (const bool monocular : {false, true}) {
    auto obs = observe(scene(61, 23), truth, cam, 0.0, 24);
    obs.back().measurement.head<2>() += Eigen::Vector2d(1.86, 1.86);
    for (PoseObservation& o : obs) o.monocular = monocular;
    // WHEN fitted from the truth
    const PoseOptimizerResult r = optimize_pose(truth, obs, cam);
    // THEN it is an inlier as an RGB-D observation and an outlier as a monocular one
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.inlier.back(), !monocular) << (monocular ? "monocular" : "rgb-d");
    EXPECT_EQ(r.inliers, monocular ? 60 : 61);
  }
}

TEST(PoseOptimizer, TooFewObservationsIsNotOk) {
  const CameraModel cam = fr1_camera();
  const auto obs = observe(scene(2, 5), Eigen::Isometry3d::Identity(), cam, 0.0, 6);
  EXPECT_FALSE(optimize_pose(Eigen::Isometry3d::Identity(), obs, cam).ok);
}

/// A frame whose keypoints are exact projections of `pts` with distinct binary descriptors.
TEST(ProjectionSearch, MatchesEachPointToItsOwnKeypointUnderASmallPoseError) {
  // GIVEN map points with descriptors, and a frame seeing them from a pose 1 cm off the prediction
  const CameraModel cam = fr1_camera();
  const auto pts = scene(150, 7);
  const cv::Mat desc = random_descriptors(150, 8);
  const Eigen::Isometry3d truth = pose(0, 0.02, 0, 0.05, 0, 0);
  const SyntheticFrame f = make_frame(pts, truth, desc, cam);
  std::vector<LocalPoint> local;
  for (int i = 0; i < 150; ++i)
    local.push_back(LocalPoint{i, pts[static_cast<std::size_t>(i)], desc.row(i)});
  // WHEN searched from the predicted pose
  const ProjectionMatches m = search_by_projection(local, truth * pose(0, 0, 0, 0.01, 0, 0),
                                                   f.tracked, cam, ProjectionSearchOptions{});
  // THEN every visible keypoint finds its own point and nothing else
  ASSERT_EQ(m.matches, static_cast<int>(f.tracked.size()));
  for (std::size_t k = 0; k < f.tracked.size(); ++k) {
    const int p = m.point_of_keypoint[k];
    ASSERT_GE(p, 0);
    EXPECT_LT(
        (cam.project(truth * pts[static_cast<std::size_t>(p)]).head<2>() - f.tracked.pixels[k])
            .norm(),
        1e-6);
  }
}

TEST(ProjectionSearch, ADescriptorTooFarAwayIsNotMatched) {
  const CameraModel cam = fr1_camera();
  const auto pts = scene(20, 9);
  const cv::Mat desc = random_descriptors(20, 10);
  const SyntheticFrame f = make_frame(pts, Eigen::Isometry3d::Identity(), desc, cam);
  std::vector<LocalPoint> local;
  for (int i = 0; i < 20; ++i) {
    cv::Mat other = desc.row(i).clone();
    cv::bitwise_not(other, other);  // 256 bits away
    local.push_back(LocalPoint{i, pts[static_cast<std::size_t>(i)], other});
  }
  EXPECT_EQ(search_by_projection(local, Eigen::Isometry3d::Identity(), f.tracked, cam, {}).matches,
            0);
}

TEST(FitByProjection, DepthlessKeypointsJoinTheFitAndEachPointIsMatchedOnce) {
  // GIVEN 200 map points; the frame reads depth for those nearer than 2 m and none for the rest,
  // whose keypoints are depthless features (bearings)
  const CameraModel cam = fr1_camera();
  const auto pts = scene(200, 25);
  const cv::Mat desc = random_descriptors(200, 26);
  const Eigen::Isometry3d truth = pose(0.01, 0.02, 0, 0.05, 0, 0);
  std::vector<Eigen::Vector3d> near, far;
  cv::Mat near_desc, far_desc;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const bool is_near = (truth * pts[i]).z() < 2.0;
    (is_near ? near : far).push_back(pts[i]);
    (is_near ? near_desc : far_desc).push_back(desc.row(static_cast<int>(i)));
  }
  const SyntheticFrame with_depth = make_frame(near, truth, near_desc, cam);
  SyntheticFrame depthless = make_frame(far, truth, far_desc, cam);
  drop_depth(&depthless, cam);
  std::vector<LocalPoint> local;
  for (int i = 0; i < 200; ++i)
    local.push_back(LocalPoint{i, pts[static_cast<std::size_t>(i)], desc.row(i)});
  const Eigen::Isometry3d guess = truth * pose(0.005, 0, 0, 0.01, 0, 0);
  // WHEN fitted from a guess 1 cm and 0.3 deg off, with and without the depthless keypoints
  const ProjectionFit fit =
      fit_by_projection(local, with_depth.tracked, cam, guess, 15.0, {}, &depthless.tracked);
  const ProjectionFit rgbd_only =
      fit_by_projection(local, with_depth.tracked, cam, guess, 15.0, {});
  // THEN every keypoint finds its own point, the depthless ones counted apart, and no point is
  // matched twice
  ASSERT_TRUE(fit.ok);
  EXPECT_EQ(fit.inliers, with_depth.tracked.size());
  EXPECT_EQ(fit.depthless_inliers, depthless.tracked.size());
  ASSERT_GE(fit.depthless_inliers, 20u);
  std::vector<int> seen(200, 0);
  for (int p : fit.point_of_keypoint) seen[static_cast<std::size_t>(p)] += p >= 0 ? 1 : 0;
  for (std::size_t k = 0; k < fit.point_of_depthless.size(); ++k) {
    const int p = fit.point_of_depthless[k];
    ASSERT_GE(p, 0);
    ++seen[static_cast<std::size_t>(p)];
    EXPECT_LT((cam.project(truth * pts[static_cast<std::size_t>(p)]).head<2>() -
               depthless.tracked.pixels[k])
                  .norm(),
              1e-6);
  }
  for (int n : seen) EXPECT_LE(n, 1);
  EXPECT_LT((fit.T_cam_world.translation() - truth.translation()).norm(), 1e-6);
  // AND without them the fit has the same RGB-D matches and none of theirs
  ASSERT_TRUE(rgbd_only.ok);
  EXPECT_EQ(rgbd_only.inliers, fit.inliers);
  EXPECT_EQ(rgbd_only.depthless_inliers, 0u);
  EXPECT_TRUE(rgbd_only.point_of_depthless.empty());
}

TEST(SlamMap, ObservationsPointsAndCulledKeyframeChains) {
  // GIVEN two keyframes sharing one point
  const CameraModel cam = fr1_camera();
  const auto pts = scene(10, 11);
  const cv::Mat desc = random_descriptors(10, 12);
  SlamMap map;
  for (std::int64_t id : {0, 5}) {
    MapKeyframe kf;
    kf.id = id;
    kf.T_world_cam = pose(0, 0, 0, 0.1 * static_cast<double>(id), 0, 0);
    kf.features = make_frame(pts, kf.T_world_cam.inverse(), desc, cam).tracked;
    map.add_keyframe(std::move(kf));
  }
  const std::int64_t a = map.add_point(pts[0], desc.row(0), 0, 0);
  const std::int64_t b = map.add_point(pts[0], desc.row(0), 5, 0);
  EXPECT_EQ(map.covisible(0, 1).size(), 0u);
  // WHEN the duplicate is merged
  map.replace_point(b, a);
  // THEN one point sees both keyframes, which are now covisible
  EXPECT_FALSE(map.has_point(b));
  EXPECT_EQ(map.point(a)->observations.size(), 2u);
  ASSERT_EQ(map.covisible(0, 1).size(), 1u);
  EXPECT_EQ(map.keyframe(5)->point_ids[0], a);
  // WHEN keyframe 5 is culled into 0
  const Eigen::Isometry3d T5 = map.keyframe(5)->T_world_cam;
  map.cull_keyframe(5, 0);
  // THEN its pose still resolves through the parent and follows the parent's corrections
  ASSERT_TRUE(map.resolve_pose(5).has_value());
  EXPECT_TRUE(map.resolve_pose(5)->isApprox(T5, 1e-12));
  map.keyframe(0)->T_world_cam = pose(0, 0, 0, 0, 0.5, 0);
  EXPECT_NEAR(map.resolve_pose(5)->translation().y(), 0.5, 1e-12);
  EXPECT_EQ(map.point(a)->observations.size(), 1u);
  EXPECT_FALSE(map.resolve_pose(99).has_value());
}

TEST(PlaceIndex, ThumbnailsRankTheSameViewFirst) {
  cv::Mat a(480, 640, CV_8UC3), b(480, 640, CV_8UC3);
  cv::RNG rng(13);
  rng.fill(a, cv::RNG::UNIFORM, 0, 256);
  rng.fill(b, cv::RNG::UNIFORM, 0, 256);
  cv::Mat a_noisy = a.clone();
  cv::Mat noise(480, 640, CV_8UC3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 20);
  a_noisy += noise;
  const cv::Mat ta = make_thumbnail(a), tb = make_thumbnail(b), tn = make_thumbnail(a_noisy);
  EXPECT_LT(thumbnail_distance(tn, ta), thumbnail_distance(tn, tb));
  EXPECT_EQ(thumbnail_distance(ta, cv::Mat()), 4.0);
  EXPECT_TRUE(make_thumbnail(cv::Mat()).empty());
}

}  // namespace
}  // namespace rgbdquad::slam
