// Real TUM frames shipped in tests/data (CC BY 4.0, see tests/data/README.md).
#pragma once

#include <opencv2/imgcodecs.hpp>
#include <string>

namespace rgbdquad::surf::testing {

/// First RGB frame of fr1/xyz and the first of fr1/desk (640x480).
inline const std::string kXyzFrame =
    std::string(SLAM_REPO_DIR) + "/tests/data/fr1_xyz_first30/rgb/1305031102.175304.png";
inline const std::string kDeskFrame =
    std::string(SLAM_REPO_DIR) + "/tests/data/fr1_desk_9frames/rgb/1305031453.359684.png";

inline cv::Mat load_gray(const std::string& path) { return cv::imread(path, cv::IMREAD_GRAYSCALE); }

}  // namespace rgbdquad::surf::testing
