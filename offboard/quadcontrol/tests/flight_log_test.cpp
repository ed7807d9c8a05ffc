// FlightLog: rows land in the right files with the right columns, every row is on disk at once
// (a killed ground station keeps its log), and an unwritable folder is a clear error.
#include "app/flight_log.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace rgbdquad::quadcontrol {
namespace {

std::vector<std::string> lines_of(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

class FlightLogTest : public ::testing::Test {
 protected:
  std::filesystem::path dir_ =
      std::filesystem::temp_directory_path() /
      ("flight_log_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
       "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { std::filesystem::remove_all(dir_); }
};

TEST_F(FlightLogTest, RowsAreOnDiskAsSoonAsWritten) {
  std::string error;
  auto log = FlightLog::open((dir_ / "nested").string(), &error);
  ASSERT_TRUE(log) << error;
  log->frame(7, 1000000, 1012000, 3.5);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.5, -0.25, 1.7);
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  log->pose(LoggedPose{7, 1000000, 1012000, 1030000, true, T, 90.0});
  log->pose(LoggedPose{8, 1033333, 1045000, 1060000, false});
  log->command(LoggedCommand{42, 1070000, "hold", PwmCommand{1510, 1490, 1550, 1500, true}, 1000000,
                             1030000});

  // Checked while the log is still open: nothing waits for a buffer flush.
  const auto frames = lines_of(dir_ / "nested" / "frames.csv");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1], "7,1000000,1012000,3.500");
  const auto poses = lines_of(dir_ / "nested" / "poses.csv");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_EQ(poses[1], "7,1000000,1012000,1030000,1,0.50000,-0.25000,1.70000,90.000");
  EXPECT_EQ(poses[2].rfind("8,1033333,1045000,1060000,0,", 0), 0u);
  // Only the tracked pose reaches the TUM trajectory, at its capture time in seconds.
  const auto traj = lines_of(dir_ / "nested" / "trajectory.tum");
  ASSERT_EQ(traj.size(), 3u);  // two comment lines + one pose
  std::istringstream row(traj[2]);
  double t, x, y, z, qx, qy, qz, qw;
  row >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  EXPECT_DOUBLE_EQ(t, 1.0);
  EXPECT_DOUBLE_EQ(x, 0.5);
  EXPECT_DOUBLE_EQ(z, 1.7);
  EXPECT_NEAR(qz, std::sqrt(0.5), 1e-9);
  EXPECT_NEAR(qw, std::sqrt(0.5), 1e-9);
  const auto commands = lines_of(dir_ / "nested" / "commands.csv");
  ASSERT_EQ(commands.size(), 2u);
  EXPECT_EQ(commands[1], "42,1070000,hold,1,1510,1490,1550,1500,1000000,1030000");
  EXPECT_EQ(log->write_errors(), 0u);
}

TEST_F(FlightLogTest, UnwritableFolderIsAClearError) {
  std::filesystem::create_directories(dir_);
  std::ofstream(dir_ / "a_file") << "x";
  std::string error;
  auto log = FlightLog::open((dir_ / "a_file" / "log").string(), &error);
  EXPECT_FALSE(log);
  EXPECT_NE(error.find("flight log: cannot create"), std::string::npos) << error;
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
