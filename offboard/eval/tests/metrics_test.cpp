// Tests of slam_metrics: TUM I/O and its error messages, association rules, ATE/RPE on
// synthetic trajectories with known answers, and the numbers evo 1.38.1 gives on the shipped
// RGBD-SLAM fr1/xyz trajectory (offboard/eval/testdata, see README there).
#include "rgbdquad/eval/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

namespace rgbdquad::eval {
namespace {

namespace fs = std::filesystem;

const std::string kTestData = SLAM_EVAL_TESTDATA_DIR;
/// The evo numbers below are printed to 1e-9; C++ and numpy differ only by rounding, so 1e-7 m
/// (0.1 um) and 1e-6 deg are generous while still catching any definitional difference.
constexpr double kEvoTolM = 1e-7;
constexpr double kEvoTolDeg = 1e-6;
/// Period of a 30 Hz camera, the rate of the synthetic estimates.
constexpr double kCameraPeriodS = 1.0 / 30.0;

Eigen::Isometry3d make_pose(double yaw_rad, double pitch_rad, double roll_rad,
                            const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}

// A smooth, non-planar hand-held-like path: 3 s at 30 Hz.
Trajectory make_path(std::size_t n = 90, double t0_s = 100.0) {
  Trajectory traj;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = static_cast<double>(i) * kCameraPeriodS;
    traj.push_back({t0_s + s, make_pose(0.3 * std::sin(s), 0.1 * s, 0.05 * std::cos(2 * s),
                                        {std::sin(s), 0.5 * std::cos(0.7 * s), 0.2 * s})});
  }
  return traj;
}

std::string temp_file(const std::string& name, const std::string& content) {
  const fs::path path = fs::path(::testing::TempDir()) / name;
  std::ofstream(path) << content;
  return path.string();
}

TEST(ReadTum, GivenCommentsBlankLinesAndCommasWhenReadThenPosesParsedAndNormalised) {
  const auto path = temp_file("ok.txt",
                              "# timestamp tx ty tz qx qy qz qw\n\n"
                              "1.0 1 2 3 0 0 0 2\n"
                              "2.5,4,5,6,0,0,0.7071068,0.7071068\n");
  std::string error;
  const auto traj = read_tum_trajectory(path, &error);
  ASSERT_TRUE(traj) << error;
  ASSERT_EQ(traj->size(), 2u);
  EXPECT_DOUBLE_EQ((*traj)[0].stamp_s, 1.0);
  EXPECT_TRUE((*traj)[0].T_world_cam.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_TRUE((*traj)[0].T_world_cam.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  // qz = qw = 1/sqrt(2): 90 deg about z (scalar-last order in the file).
  EXPECT_NEAR(rotation_angle_deg((*traj)[1].T_world_cam.linear()), 90.0, 1e-5);
  EXPECT_NEAR((*traj)[1].T_world_cam.linear()(1, 0), 1.0, 1e-6);
}

struct BadFileCase {
  std::string name, content, expected_fragment;
};

TEST(ReadTum, GivenBadInputWhenReadThenErrorNamesTheLine) {
  const BadFileCase cases[] = {
      {"fields", "# c\n1 2 3 4 5 6 7 1\n1 2 3\n", ":3: expected 8 fields"},
      {"number", "1 2 3 4 0 0 0 1\n2 2 x 4 0 0 0 1\n", ":2: field 3 'x' is not a finite number"},
      {"nan", "1 nan 3 4 0 0 0 1\n", ":1: field 2 'nan'"},
      {"trailing", "1 2 3 4 0 0 0 1abc\n", ":1: field 8"},
      {"zero_quat", "1 2 3 4 0 0 0 0\n", ":1: quaternion has (near) zero norm"},
  };
  for (const auto& c : cases) {
    std::string error;
    EXPECT_FALSE(read_tum_trajectory(temp_file(c.name + ".txt", c.content), &error)) << c.name;
    EXPECT_NE(error.find(c.expected_fragment), std::string::npos) << c.name << ": " << error;
  }
  std::string error;
  EXPECT_FALSE(read_tum_trajectory("/nonexistent/dir/traj.txt", &error));
  EXPECT_NE(error.find("cannot open"), std::string::npos);
}

TEST(WriteTum, GivenTrajectoryWhenWrittenAndReadBackThenPosesEqual) {
  const auto traj = make_path(20);
  const auto path = (fs::path(::testing::TempDir()) / "roundtrip.txt").string();
  std::string error;
  ASSERT_TRUE(write_tum_trajectory(path, traj, &error)) << error;
  const auto back = read_tum_trajectory(path, &error);
  ASSERT_TRUE(back) << error;
  ASSERT_EQ(back->size(), traj.size());
  for (std::size_t i = 0; i < traj.size(); ++i) {
    EXPECT_NEAR((*back)[i].stamp_s, traj[i].stamp_s, 1e-6);
    EXPECT_TRUE((*back)[i].T_world_cam.isApprox(traj[i].T_world_cam, 1e-8));
  }
  EXPECT_FALSE(write_tum_trajectory("/nonexistent/dir/t.txt", traj, &error));
  auto bad = traj;
  bad[3].T_world_cam.translation().x() = NAN;
  EXPECT_FALSE(write_tum_trajectory(path, bad, &error));
  EXPECT_NE(error.find("pose 3"), std::string::npos);
}

TEST(Associate, GivenDenserGroundTruthWhenEvoNearestThenEachEstimatePoseGetsItsNearestStamp) {
  Trajectory gt, est;
  const auto I = Eigen::Isometry3d::Identity();
  for (double s : {0.000, 0.010, 0.020, 0.030, 0.040, 0.100}) gt.push_back({s, I});
  // 0.014 -> 0.010; 0.016 -> 0.020; 0.015 is a tie -> the earlier stamp (evo's rule);
  // 0.070 is 30 ms from everything -> dropped.
  for (double s : {0.014, 0.015, 0.016, 0.070}) est.push_back({s, I});
  const auto pairs = associate(gt, est, 0.02, Association::kEvoNearest);
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[0].gt_index, 1u);
  EXPECT_EQ(pairs[1].gt_index, 1u);  // re-used: evo does not enforce uniqueness
  EXPECT_EQ(pairs[2].gt_index, 2u);
  EXPECT_EQ(pairs[2].est_index, 2u);
}

TEST(Associate, GivenCompetingStampsWhenTumGreedyThenEachStampUsedOnceSmallestDtFirst) {
  Trajectory gt, est;
  const auto I = Eigen::Isometry3d::Identity();
  for (double s : {0.000, 0.010, 0.030}) gt.push_back({s, I});
  for (double s : {0.009, 0.012}) est.push_back({s, I});
  // |dt|: (0.010,0.009)=1ms wins; 0.012 then takes 0.000 (12 ms) over 0.030 (18 ms).
  const auto pairs = associate(gt, est, 0.02, Association::kTumGreedy);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].gt_index, 1u);
  EXPECT_EQ(pairs[0].est_index, 0u);
  EXPECT_EQ(pairs[1].gt_index, 0u);
  EXPECT_EQ(pairs[1].est_index, 1u);
  EXPECT_TRUE(associate(gt, est, -1.0).empty());
}

TEST(Ate, GivenRigidlyMovedEstimateWhenScoredThenZeroErrorAndTransformRecovered) {
  const auto gt = make_path();
  const Eigen::Isometry3d T_est_gt = make_pose(1.0, -0.4, 0.3, {2.0, -1.0, 0.5});
  Trajectory est = gt;
  for (auto& p : est) p.T_world_cam = T_est_gt * p.T_world_cam;
  std::string error;
  const auto ate = compute_ate(gt, est, 0.02, &error);
  ASSERT_TRUE(ate) << error;
  EXPECT_EQ(ate->pairs, gt.size());
  EXPECT_LT(ate->trans_rmse_m, 1e-9);
  EXPECT_LT(ate->rot_rmse_deg, 1e-6);
  EXPECT_TRUE(ate->T_gt_est.isApprox(T_est_gt.inverse(), 1e-9));
}

TEST(Ate, GivenConstantOffsetAlongOneAxisOfAPlaneWhenScoredThenAlignmentRemovesIt) {
  // GIVEN est = gt shifted by 5 cm: a pure translation the alignment must absorb.
  const auto gt = make_path();
  Trajectory est = gt;
  for (auto& p : est) p.T_world_cam.translation() += Eigen::Vector3d(0.05, 0, 0);
  const auto ate = compute_ate(gt, est, 0.02, nullptr);
  ASSERT_TRUE(ate);
  EXPECT_LT(ate->trans_rmse_m, 1e-9);
  EXPECT_NEAR(ate->T_gt_est.translation().x(), -0.05, 1e-9);
}

TEST(Ate, GivenAlternatingPerpendicularNoiseWhenScoredThenStatisticsMatchClosedForm) {
  // GIVEN every gt position visited twice, est displaced +d then -d along z there: the
  // displacement has zero mean and zero cross-covariance with the positions, so the best
  // alignment is identity and every error is exactly d.
  constexpr double kD = 0.01;
  Trajectory gt, est;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector3d p(0.1 * (i / 2), 0.02 * ((i / 2) % 3), 0.01 * ((i / 2) % 4));
    gt.push_back({i * kCameraPeriodS, make_pose(0, 0, 0, p)});
    est.push_back(
        {i * kCameraPeriodS, make_pose(0, 0, 0, p + Eigen::Vector3d(0, 0, (i % 2 ? kD : -kD)))});
  }
  const auto ate = compute_ate(gt, est, 0.02, nullptr);
  ASSERT_TRUE(ate);
  EXPECT_NEAR(ate->trans_rmse_m, kD, 1e-6);
  EXPECT_NEAR(ate->trans_mean_m, kD, 1e-6);
  EXPECT_NEAR(ate->trans_median_m, kD, 1e-6);
  EXPECT_NEAR(ate->trans_max_m, kD, 1e-6);
}

TEST(Ate, GivenRotationOnlyErrorWhenScoredThenRotationRmseIsThatAngle) {
  const auto gt = make_path();
  Trajectory est = gt;
  // Rotating each camera about its own optical centre leaves positions (and so the alignment)
  // unchanged: the rotation error is exactly that angle.
  constexpr double kAngleDeg = 3.0;
  for (auto& p : est)
    p.T_world_cam.linear() =
        p.T_world_cam.linear() *
        Eigen::AngleAxisd(kAngleDeg * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const auto ate = compute_ate(gt, est, 0.02, nullptr);
  ASSERT_TRUE(ate);
  EXPECT_LT(ate->trans_rmse_m, 1e-9);
  EXPECT_NEAR(ate->rot_rmse_deg, kAngleDeg, 1e-9);
}

TEST(Ate, GivenTooFewPairsOrBadWindowWhenScoredThenClearError) {
  const auto gt = make_path(10, 0.0);
  const auto est = make_path(10, 50.0);  // no overlap in time
  std::string error;
  EXPECT_FALSE(compute_ate(gt, est, 0.02, &error));
  EXPECT_NE(error.find("only 0 pose pair(s)"), std::string::npos) << error;
  EXPECT_FALSE(compute_rpe(gt, est, 0.02, &error));
  EXPECT_FALSE(compute_ate(gt, gt, 0.0, &error));
  EXPECT_NE(error.find("max_dt_s"), std::string::npos);
  auto bad = gt;
  bad[2].T_world_cam.translation().y() = INFINITY;
  EXPECT_FALSE(compute_ate(gt, bad, 0.02, &error));
  EXPECT_NE(error.find("not finite"), std::string::npos);
}

TEST(Rpe, GivenOneTranslationJumpWhenScoredThenOnlyThatDeltaIsWrong) {
  // GIVEN est = gt except that from frame 10 on, est is shifted by 12 mm (a single bad step)
  const auto gt = make_path(31);
  Trajectory est = gt;
  constexpr double kJumpM = 0.012;
  for (std::size_t i = 10; i < est.size(); ++i) {
    est[i].T_world_cam.translation() += Eigen::Vector3d(kJumpM, 0, 0);
  }
  const auto rpe = compute_rpe(gt, est, 0.02, nullptr);
  ASSERT_TRUE(rpe);
  EXPECT_EQ(rpe->pairs, 30u);
  // THEN one of 30 deltas has error 12 mm: rmse = 12/sqrt(30), mean = 12/30.
  EXPECT_NEAR(rpe->trans_rmse_mm, 12.0 / std::sqrt(30.0), 1e-6);
  EXPECT_NEAR(rpe->trans_mean_mm, 12.0 / 30.0, 1e-6);
  EXPECT_NEAR(rpe->rot_rmse_deg, 0.0, 1e-6);
}

TEST(Rpe, GivenGlobalRigidTransformWhenScoredThenRpeIsZero) {
  const auto gt = make_path();
  Trajectory est = gt;
  const Eigen::Isometry3d T = make_pose(0.5, 0.2, -0.1, {1, 2, 3});
  for (auto& p : est) p.T_world_cam = T * p.T_world_cam;
  const auto rpe = compute_rpe(gt, est, 0.02, nullptr);
  ASSERT_TRUE(rpe);
  EXPECT_LT(rpe->trans_rmse_mm, 1e-6);
  EXPECT_LT(rpe->rot_rmse_deg, 1e-6);
}

TEST(Rpe, GivenSeededRotationNoisePerFrameWhenScoredThenRotationErrorsAppear) {
  std::mt19937 rng(42);
  std::normal_distribution<double> noise_rad(0.0, 0.01);
  const auto gt = make_path();
  Trajectory est = gt;
  for (auto& p : est) {
    p.T_world_cam.linear() =
        p.T_world_cam.linear() *
        make_pose(noise_rad(rng), noise_rad(rng), noise_rad(rng), Eigen::Vector3d::Zero()).linear();
  }
  const auto rpe = compute_rpe(gt, est, 0.02, nullptr);
  ASSERT_TRUE(rpe);
  // Difference of two independent 3-D rotations of 0.01 rad per axis: ~sqrt(6)*0.01 rad rms.
  EXPECT_NEAR(rpe->rot_rmse_deg, std::sqrt(6.0) * 0.01 * 180.0 / M_PI, 0.25);
  // The relative translation is expressed in the rotated camera frame, so it is off as well.
  EXPECT_GT(rpe->trans_rmse_mm, 0.0);
}

struct EvoReference {
  const char* est_file;
  std::size_t pairs;
  double ate_rmse_m, ate_mean_m, ate_median_m, ate_max_m, ate_rot_rmse_deg;
  double rpe_trans_rmse_m, rpe_trans_mean_m, rpe_rot_rmse_deg, rpe_rot_mean_deg;
};

// Printed by evo 1.38.1's Python API (sync.associate_trajectories max_diff=0.02, align without
// scale, APE/RPE delta=1 frame) on freiburg1_xyz-rgbdslam.txt vs the fr1/xyz ground truth; see
// offboard/eval/tests/test_against_evo.py which recomputes them. The acceptance numbers:
// ATE RMSE 0.0135 m (full sequence) and 0.0148 m (first-300-frame span).
const EvoReference kEvoReferences[] = {
    {"fr1_xyz_rgbdslam.txt", 786, 0.01347346776990678, 0.012029476392023605, 0.011175751133287705,
     0.03472720168113181, 2.0518937319212176, 0.00575924678223505, 0.004813800440653205,
     0.35282746125711173, 0.29999228722562343},
    {"fr1_xyz_rgbdslam_first300.txt", 288, 0.014822086996131214, 0.013619802251733518,
     0.01245214434572456, 0.03266453890822331, 1.6686351684319258, 0.006621337536723465,
     0.005690333662387975, 0.3818393518019666, 0.31157181417556384},
};

void expect_matches_evo(const Trajectory& gt, const Trajectory& est, const EvoReference& ref) {
  std::string error;
  const auto ate = compute_ate(gt, est, kDefaultMaxDtS, &error);
  ASSERT_TRUE(ate) << error;
  EXPECT_EQ(ate->pairs, ref.pairs);
  EXPECT_NEAR(ate->trans_rmse_m, ref.ate_rmse_m, kEvoTolM);
  EXPECT_NEAR(ate->trans_mean_m, ref.ate_mean_m, kEvoTolM);
  EXPECT_NEAR(ate->trans_median_m, ref.ate_median_m, kEvoTolM);
  EXPECT_NEAR(ate->trans_max_m, ref.ate_max_m, kEvoTolM);
  EXPECT_NEAR(ate->rot_rmse_deg, ref.ate_rot_rmse_deg, kEvoTolDeg);
  const auto rpe = compute_rpe(gt, est, kDefaultMaxDtS, &error);
  ASSERT_TRUE(rpe) << error;
  EXPECT_EQ(rpe->pairs, ref.pairs - 1);
  EXPECT_NEAR(rpe->trans_rmse_mm, ref.rpe_trans_rmse_m * 1000.0, kEvoTolM * 1000.0);
  EXPECT_NEAR(rpe->trans_mean_mm, ref.rpe_trans_mean_m * 1000.0, kEvoTolM * 1000.0);
  EXPECT_NEAR(rpe->rot_rmse_deg, ref.rpe_rot_rmse_deg, kEvoTolDeg);
  EXPECT_NEAR(rpe->rot_mean_deg, ref.rpe_rot_mean_deg, kEvoTolDeg);
}

TEST(EvoReference, GivenShippedRgbdslamTrajectoryWhenScoredThenMatchesEvo) {
  std::string error;
  const auto gt = read_tum_trajectory(kTestData + "/fr1_xyz_groundtruth.txt", &error);
  ASSERT_TRUE(gt) << error;
  for (const auto& ref : kEvoReferences) {
    SCOPED_TRACE(ref.est_file);
    const auto est = read_tum_trajectory(kTestData + "/" + ref.est_file, &error);
    ASSERT_TRUE(est) << error;
    expect_matches_evo(*gt, *est, ref);
    // TUM's associate.py finds the same pairs on this data (30 Hz est vs 100 Hz gt).
    EXPECT_EQ(associate(*gt, *est, kDefaultMaxDtS, Association::kTumGreedy).size(), ref.pairs);
  }
}

TEST(EvoReference, GivenSharedDataWhenScoredThenMatchesEvo) {
  const char* env = std::getenv("RGBD_DATA_DIR");
  const fs::path data_dir =
      env ? fs::path(env) : fs::path(SLAM_REPO_DIR) / ".." / "shared" / "data";
  const fs::path gt_path = data_dir / "fr1_xyz_first300" / "groundtruth.txt";
  const fs::path est_path = data_dir / "reference_trajectories" / "freiburg1_xyz-rgbdslam.txt";
  if (!fs::exists(gt_path) || !fs::exists(est_path)) {
    GTEST_SKIP() << "shared data not found at " << data_dir
                 << " (set RGBD_DATA_DIR); the shipped copy is tested above";
  }
  std::string error;
  const auto gt = read_tum_trajectory(gt_path.string(), &error);
  ASSERT_TRUE(gt) << error;
  const auto est = read_tum_trajectory(est_path.string(), &error);
  ASSERT_TRUE(est) << error;
  expect_matches_evo(*gt, *est, kEvoReferences[0]);
}

TEST(ScoreCommand, GivenGoodFilesWhenRunThenJsonWithRequiredKeys) {
  std::ostringstream out, err;
  const int rc = run_score_command(kTestData + "/fr1_xyz_groundtruth.txt",
                                   kTestData + "/fr1_xyz_rgbdslam_first300.txt", out, err);
  ASSERT_EQ(rc, 0) << err.str();
  for (const char* key :
       {"\"ate_rmse_m\": 0.014822087", "\"ate_rot_rmse_deg\"", "\"rpe_trans_rmse_mm\": 6.6213375",
        "\"rpe_rot_rmse_deg\"", "\"pairs\": 288"}) {
    EXPECT_NE(out.str().find(key), std::string::npos) << key << " in\n" << out.str();
  }
}

TEST(ScoreCommand, GivenBadInputWhenRunThenNonZeroAndMessage) {
  const auto far = temp_file("far.txt", "5000 0 0 0 0 0 0 1\n5001 0 0 0 0 0 0 1\n");
  const auto broken = temp_file("broken.txt", "1 0 0 0 0 0 0 1\n2 0 0\n");
  const std::string gt = kTestData + "/fr1_xyz_groundtruth.txt";
  const struct {
    std::string gt, est, fragment;
  } cases[] = {
      {"/nonexistent.txt", gt, "ground truth: cannot open"},
      {gt, broken, "broken.txt:2: expected 8 fields"},
      {gt, far, "only 0 pose pair(s)"},
  };
  for (const auto& c : cases) {
    std::ostringstream out, err;
    EXPECT_NE(run_score_command(c.gt, c.est, out, err), 0);
    EXPECT_NE(err.str().find(c.fragment), std::string::npos) << err.str();
    EXPECT_TRUE(out.str().empty());
  }
}

}  // namespace
}  // namespace rgbdquad::eval
