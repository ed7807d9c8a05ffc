// Accelerometer gate: one verdict per reason (table-driven), the counters, the rotation into the
// optical frame, the options check; and accelerometer.txt in the dataset reader (nearest sample to
// the colour stamp, missing file, malformed lines).
#include "slam/motion/accel_gate.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "slam/dataset/tum_dataset.hpp"

namespace rgbdquad::slam {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kColourStampS = 100.0;
constexpr double kG = kStandardGravityMps2;

/// A Kinect at rest, level: the specific force points up, along the accelerometer's +y.
AccelSample level_at(double stamp_s) { return {stamp_s, Eigen::Vector3d(0.0, kG, 0.0)}; }

struct GateCase {
  const char* name;
  std::optional<AccelSample> sample;
  double colour_stamp_s;
  AccelVerdict expected;
};

TEST(AccelGate, GivenEachKindOfSampleThenItsVerdict) {
  const std::vector<GateCase> cases = {
      {"level at rest", level_at(kColourStampS + 0.001), kColourStampS, AccelVerdict::kAccepted},
      {"gap just inside the bound", level_at(kColourStampS - 0.019), kColourStampS,
       AccelVerdict::kAccepted},
      {"no sample", std::nullopt, kColourStampS, AccelVerdict::kMissing},
      {"nan axis", AccelSample{kColourStampS, {kNan, kG, 0}}, kColourStampS,
       AccelVerdict::kNonFinite},
      {"inf axis", AccelSample{kColourStampS, {0, kInf, 0}}, kColourStampS,
       AccelVerdict::kNonFinite},
      {"nan stamp", AccelSample{kNan, {0, kG, 0}}, kColourStampS, AccelVerdict::kNonFinite},
      {"older than the bound", level_at(kColourStampS - 0.021), kColourStampS,
       AccelVerdict::kStale},
      {"newer than the bound", level_at(kColourStampS + 0.5), kColourStampS, AccelVerdict::kStale},
      {"nan colour stamp", level_at(kColourStampS), kNan, AccelVerdict::kStale},
      {"axis at +2 g", AccelSample{kColourStampS, {0, 2 * kG, 0}}, kColourStampS,
       AccelVerdict::kSaturated},
      {"axis beyond -2 g", AccelSample{kColourStampS, {-2.1 * kG, 0, 0}}, kColourStampS,
       AccelVerdict::kSaturated},
      {"free fall", AccelSample{kColourStampS, {0, 0.1, 0}}, kColourStampS,
       AccelVerdict::kImplausible},
      {"1.6 g spread over axes", AccelSample{kColourStampS, {0.92 * kG, 0.92 * kG, 0.92 * kG}},
       kColourStampS, AccelVerdict::kImplausible},
      {"1.4 g spread over axes", AccelSample{kColourStampS, {0.8 * kG, 0.8 * kG, 0.8 * kG}},
       kColourStampS, AccelVerdict::kAccepted},
  };
  for (const GateCase& c : cases) {
    AccelGate gate;
    EXPECT_EQ(gate.check(c.colour_stamp_s, c.sample), c.expected) << c.name;
    EXPECT_EQ(gate.counts().of(c.expected), 1u) << c.name;
    EXPECT_EQ(gate.counts().total(), 1u) << c.name;
  }
}

TEST(AccelGate, GivenMixedSamplesThenCountsPerReasonAndAcceptedVsIgnored) {
  // GIVEN a gate and five samples: two good, one missing, one stale, one saturated
  AccelGate gate;
  gate.check(kColourStampS, level_at(kColourStampS));
  gate.check(kColourStampS + 1, level_at(kColourStampS + 1));
  gate.check(kColourStampS, std::nullopt);
  gate.check(kColourStampS, level_at(kColourStampS - 1));
  gate.check(kColourStampS, AccelSample{kColourStampS, {0, 0, 3 * kG}});
  // THEN each is counted under its reason
  const AccelCounts& c = gate.counts();
  EXPECT_EQ(c.accepted(), 2u);
  EXPECT_EQ(c.ignored(), 3u);
  EXPECT_EQ(c.of(AccelVerdict::kMissing), 1u);
  EXPECT_EQ(c.of(AccelVerdict::kStale), 1u);
  EXPECT_EQ(c.of(AccelVerdict::kSaturated), 1u);
  EXPECT_EQ(c.of(AccelVerdict::kNonFinite), 0u);
  EXPECT_EQ(c.total(), 5u);
}

TEST(AccelGate, GivenAcceptedSampleThenFrameGetsItInTheOpticalFrame) {
  // GIVEN a level Kinect (accelerometer x left, y up, z forward) and a frame
  AccelGate gate;
  RgbdFrame frame;
  const AccelSample s{kColourStampS + 0.002, Eigen::Vector3d(1.0, 9.0, 2.0)};
  // WHEN the sample is attached
  ASSERT_EQ(gate.attach(kColourStampS, s, &frame), AccelVerdict::kAccepted);
  // THEN up (sensor +y) is optical -y, left (sensor +x) is optical -x, forward stays +z
  ASSERT_TRUE(frame.accel_cam_mps2 && frame.accel_stamp_s);
  EXPECT_TRUE(frame.accel_cam_mps2->isApprox(Eigen::Vector3d(-1.0, -9.0, 2.0)));
  EXPECT_DOUBLE_EQ(*frame.accel_stamp_s, s.stamp_s);
  // AND a refused sample clears what the frame held
  EXPECT_EQ(gate.attach(kColourStampS, level_at(kColourStampS - 1), &frame), AccelVerdict::kStale);
  EXPECT_FALSE(frame.accel_cam_mps2);
  EXPECT_FALSE(frame.accel_stamp_s);
}

TEST(AccelGate, GivenBadOptionsThenRefusedWithReason) {
  std::string err;
  EXPECT_TRUE(AccelGateOptions{}.is_valid(&err)) << err;
  AccelGateOptions o;
  o.max_stamp_gap_s = 0;
  EXPECT_FALSE(o.is_valid(&err));
  EXPECT_NE(err.find("max_stamp_gap_s"), std::string::npos);
  o = {};
  o.min_magnitude_mps2 = 20;
  EXPECT_FALSE(o.is_valid(&err));
  o = {};
  o.R_cam_sensor = {1, 0, 0, 0, 1, 0, 0, 0, -1};  // a reflection, not a rotation
  EXPECT_FALSE(o.is_valid(&err));
  EXPECT_NE(err.find("rotation"), std::string::npos);
  // A gate given bad options runs with the defaults and says why.
  AccelGate gate(o);
  EXPECT_FALSE(gate.options_error().empty());
  EXPECT_TRUE(gate.options().is_valid(nullptr));
}

/// A temporary TUM folder with two frames, unique per process (parallel test runs never share it).
class AccelDatasetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("slam_accel_dataset_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    std::ofstream(dir_ / "rgb.txt") << "# colour\n10.000 rgb/a.png\n10.033 rgb/b.png\n";
    std::ofstream(dir_ / "depth.txt") << "10.002 depth/a.png\n10.035 depth/b.png\n";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(AccelDatasetTest, GivenNoAccelerometerFileThenFramesHaveNoSample) {
  std::string err;
  auto ds = TumDataset::open(dir_.string(), TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  EXPECT_TRUE(ds->accelerometer_path().empty());
  EXPECT_EQ(ds->accel_sample_count(), 0u);
  EXPECT_FALSE(ds->entry(0).accel);
}

TEST_F(AccelDatasetTest, GivenAccelerometerFileThenNearestSampleToColourStamp) {
  // GIVEN samples around the first colour stamp only; the second frame's nearest is 31 ms away
  std::ofstream(dir_ / "accelerometer.txt") << "# accelerometer data\n# timestamp ax ay az\n"
                                            << "10.0040 0.5 8.0 -4.0\n"
                                            << "9.9990 0.1 9.0 -3.0\n"
                                            << "10.0020 nan 8.0 -4.0\n";
  std::string err;
  auto ds = TumDataset::open(dir_.string(), TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  EXPECT_EQ(ds->accel_sample_count(), 3u);
  // THEN the colour stamp's (not the depth stamp's) nearest sample is kept
  ASSERT_TRUE(ds->entry(0).accel);
  EXPECT_DOUBLE_EQ(ds->entry(0).accel->stamp_s, 9.999);
  EXPECT_DOUBLE_EQ(ds->entry(0).accel->f_sensor_mps2.y(), 9.0);
  ASSERT_TRUE(ds->entry(1).accel);
  EXPECT_DOUBLE_EQ(ds->entry(1).accel->stamp_s, 10.004);
  // AND the gate calls the second one stale
  AccelGate gate;
  EXPECT_EQ(gate.check(ds->entry(0).rgb_stamp_s, ds->entry(0).accel), AccelVerdict::kAccepted);
  EXPECT_EQ(gate.check(ds->entry(1).rgb_stamp_s, ds->entry(1).accel), AccelVerdict::kStale);
}

TEST_F(AccelDatasetTest, GivenMalformedAccelerometerLineThenOpenFailsNamingTheLine) {
  std::ofstream(dir_ / "accelerometer.txt") << "# header\n10.0 1 2 3\n10.1 1 two 3\n";
  std::string err;
  EXPECT_FALSE(TumDataset::open(dir_.string(), TumDatasetOptions{}, &err));
  EXPECT_NE(err.find("accelerometer.txt:3"), std::string::npos) << err;
  std::ofstream(dir_ / "accelerometer.txt") << "10.0 1 2 3 4\n";
  EXPECT_FALSE(TumDataset::open(dir_.string(), TumDatasetOptions{}, &err));
  std::ofstream(dir_ / "accelerometer.txt") << "nan 1 2 3\n";
  EXPECT_FALSE(TumDataset::open(dir_.string(), TumDatasetOptions{}, &err));
}

TEST_F(AccelDatasetTest, AUnitAttitudePrintedToRoundTripIsReadBitForBit) {
  // GIVEN a unit quaternion as a replayed flight writes it (the shortest round-trip text), whose
  // norm is not exactly 1 in double arithmetic
  const Eigen::Quaterniond q = Eigen::Quaterniond(0.8, 0.1, -0.3, 0.5).normalized();
  std::ostringstream line;
  line.precision(17);
  line << "10.000 " << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  std::ofstream(dir_ / "attitude.txt") << line.str();
  std::string err;
  auto ds = TumDataset::open(dir_.string(), TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  // THEN the frame carries exactly those doubles: normalising again would move their last bits
  // off the ones the flight's SLAM was given
  ASSERT_TRUE(ds->entry(0).q_nav_cam);
  EXPECT_EQ(ds->entry(0).q_nav_cam->coeffs(), q.coeffs());
}

TEST_F(AccelDatasetTest, GivenAnAttitudeFileThenEachFrameCarriesTheAttitudeAtItsColourStamp) {
  // GIVEN an attitude line at the first colour stamp (not normalised: written by hand) and none
  // within 20 ms of the second
  std::ofstream(dir_ / "attitude.txt") << "# timestamp qx qy qz qw\n"
                                       << "10.000 0 0 0.6 0.8\n"
                                       << "10.100 0 0 0 2\n";
  std::string err;
  auto ds = TumDataset::open(dir_.string(), TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  EXPECT_EQ(ds->attitude_frames(), 1u);
  // THEN the first frame carries it, normalised, as its q_nav_cam; the second carries none
  ASSERT_FALSE(ds->entry(1).q_nav_cam);
  ASSERT_TRUE(ds->entry(0).q_nav_cam);
  EXPECT_NEAR(ds->entry(0).q_nav_cam->z(), 0.6, 1e-12);
  EXPECT_NEAR(ds->entry(0).q_nav_cam->w(), 0.8, 1e-12);
}

TEST_F(AccelDatasetTest, GivenAMalformedAttitudeLineThenOpenFailsNamingTheLine) {
  for (const char* bad :
       {"10.0 0 0 0 0\n", "10.0 0 0 nan 1\n", "10.0 0 0 1\n", "10.0 0 0 0 1 5\n"}) {
    std::ofstream(dir_ / "attitude.txt") << "# header\n" << bad;
    std::string err;
    EXPECT_FALSE(TumDataset::open(dir_.string(), TumDatasetOptions{}, &err)) << bad;
    EXPECT_NE(err.find("attitude.txt:2"), std::string::npos) << err;
  }
}

TEST(NearestAccelSample, GivenSortedSamplesThenNearestEitherSide) {
  const std::vector<AccelSample> s = {level_at(1.0), level_at(2.0), level_at(3.0)};
  EXPECT_FALSE(nearest_accel_sample({}, 1.0));
  EXPECT_DOUBLE_EQ(nearest_accel_sample(s, 0.0)->stamp_s, 1.0);
  EXPECT_DOUBLE_EQ(nearest_accel_sample(s, 1.4)->stamp_s, 1.0);
  EXPECT_DOUBLE_EQ(nearest_accel_sample(s, 1.6)->stamp_s, 2.0);
  EXPECT_DOUBLE_EQ(nearest_accel_sample(s, 9.0)->stamp_s, 3.0);
}

}  // namespace
}  // namespace rgbdquad::slam
