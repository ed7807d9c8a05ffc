// The shipped data folders found relative to the executable (app/data_paths.hpp): candidate order,
// installed layout before the source tree, marker files, the error naming every path tried, and
// resolve_data_dirs filling only what the configuration leaves empty. Layouts are sets of files
// (pure) and, once, real folders in a temporary directory.
#include "app/data_paths.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "app/app_config.hpp"

namespace rgbdquad::quadcontrol {
namespace {

namespace fs = std::filesystem;

/// A filesystem that holds exactly `files`.
std::function<bool(const fs::path&)> layout(std::set<std::string> files) {
  return [files = std::move(files)](const fs::path& p) { return files.count(p.string()) > 0; };
}

TEST(DataPaths, CandidatesAreTheInstalledShareThenTheSourceTreeUpToThreeLevelsUp) {
  struct Row {
    const char* exe;
    std::vector<std::string> expected;
  };
  const Row table[] = {
      {"/opt/rq/bin/quad-control",
       {"/opt/rq/share/rgbdquad/dashboard", "/opt/rq/offboard/dashboard/static",
        "/opt/offboard/dashboard/static", "/offboard/dashboard/static"}},
      {"/src/build/x/bin/quad-control",
       {"/src/build/x/share/rgbdquad/dashboard", "/src/build/x/offboard/dashboard/static",
        "/src/build/offboard/dashboard/static", "/src/offboard/dashboard/static"}},
      {"/bin/quad-control", {"/share/rgbdquad/dashboard", "/offboard/dashboard/static"}},
      {"/quad-control", {"/share/rgbdquad/dashboard"}},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.exe);
    std::vector<std::string> got;
    for (const auto& p : data_dir_candidates(row.exe, kDashboardStaticDir))
      got.push_back(p.string());
    EXPECT_EQ(got, row.expected);
  }
}

TEST(DataPaths, GivenAnInstalledTreeThenItsShareFolderIsChosen) {
  std::string error;
  const auto dir =
      find_data_dir("/opt/rq/bin/quad-control", kDefaultReplayDir,
                    layout({"/opt/rq/share/rgbdquad/data/fr1_xyz_first30/rgb.txt"}), &error);
  ASSERT_TRUE(dir) << error;
  EXPECT_EQ(dir->string(), "/opt/rq/share/rgbdquad/data/fr1_xyz_first30");
}

TEST(DataPaths, GivenABuildTreeInsideTheSourceTreeThenTheSourceFolderIsChosen) {
  std::string error;
  const auto dir = find_data_dir("/src/build-qcp/bin/quad-control", kDashboardStaticDir,
                                 layout({"/src/offboard/dashboard/static/index.html"}), &error);
  ASSERT_TRUE(dir) << error;
  EXPECT_EQ(dir->string(), "/src/offboard/dashboard/static");
}

TEST(DataPaths, GivenBothLayoutsThenTheInstalledOneWins) {
  std::string error;
  const auto dir = find_data_dir("/src/build/bin/quad-control", kDashboardStaticDir,
                                 layout({"/src/offboard/dashboard/static/index.html",
                                         "/src/build/share/rgbdquad/dashboard/index.html"}),
                                 &error);
  ASSERT_TRUE(dir) << error;
  EXPECT_EQ(dir->string(), "/src/build/share/rgbdquad/dashboard");
}

TEST(DataPaths, GivenNoMarkerFileAnywhereThenTheErrorNamesEveryPathTriedAndTheOverride) {
  std::string error;
  // The folder exists but lacks its marker (e.g. an emptied install): not taken.
  const auto dir = find_data_dir("/opt/rq/bin/quad-control", kDashboardStaticDir,
                                 layout({"/opt/rq/share/rgbdquad/dashboard/app.js"}), &error);
  EXPECT_FALSE(dir);
  for (const auto& p : data_dir_candidates("/opt/rq/bin/quad-control", kDashboardStaticDir)) {
    EXPECT_NE(error.find(p.string()), std::string::npos) << p << " missing from: " << error;
  }
  EXPECT_NE(error.find("index.html"), std::string::npos) << error;
  EXPECT_NE(error.find("dashboard.static_dir"), std::string::npos) << error;
}

TEST(DataPaths, ResolveFillsOnlyTheFoldersTheConfigurationLeavesEmpty) {
  const auto files = layout(
      {"/p/share/rgbdquad/dashboard/index.html", "/p/share/rgbdquad/data/fr1_xyz_first30/rgb.txt"});
  struct Row {
    const char* name;
    std::string source, static_dir, folder;
    std::string expected_static_dir, expected_folder;
  };
  const Row table[] = {
      {"defaults, replay", "tum", "", "", "/p/share/rgbdquad/dashboard",
       "/p/share/rgbdquad/data/fr1_xyz_first30"},
      {"explicit folders kept", "tum", "/mine/static", "/mine/tum", "/mine/static", "/mine/tum"},
      {"live stream needs no replay", "receiver", "", "", "/p/share/rgbdquad/dashboard", ""},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    AppConfig c = default_app_config();
    c.stream_source = row.source;
    c.dashboard_static_dir = row.static_dir;
    c.replay.folder = row.folder;
    std::string error;
    ASSERT_TRUE(resolve_data_dirs(c, "/p/bin/quad-control", files, &error)) << error;
    EXPECT_EQ(c.dashboard_static_dir, row.expected_static_dir);
    EXPECT_EQ(c.replay.folder, row.expected_folder);
  }
}

TEST(DataPaths, GivenAMissingReplayExcerptThenResolveFailsOnlyForATumStream) {
  const auto files = layout({"/p/share/rgbdquad/dashboard/index.html"});
  AppConfig c = default_app_config();
  c.stream_source = "tum";
  std::string error;
  EXPECT_FALSE(resolve_data_dirs(c, "/p/bin/quad-control", files, &error));
  EXPECT_NE(error.find("/p/share/rgbdquad/data/fr1_xyz_first30"), std::string::npos) << error;
  EXPECT_NE(error.find("--tum"), std::string::npos) << error;
  c.stream_source = "receiver";
  EXPECT_TRUE(resolve_data_dirs(c, "/p/bin/quad-control", files, &error)) << error;
}

TEST(DataPaths, GivenRealFoldersThenTheFileTestFindsTheInstalledLayout) {
  std::string tmpl = (fs::temp_directory_path() / "qc_data_paths_XXXXXX").string();
  ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
  const fs::path root = tmpl;
  fs::create_directories(root / "bin");
  fs::create_directories(root / "share/rgbdquad/dashboard");
  std::ofstream(root / "share/rgbdquad/dashboard/index.html") << "<html></html>\n";
  fs::create_directories(root /
                         "share/rgbdquad/data/fr1_xyz_first30/rgb.txt");  // a folder, not a file
  std::string error;
  const auto dir = find_data_dir(root / "bin/quad-control", kDashboardStaticDir,
                                 is_regular_file_noexcept, &error);
  EXPECT_EQ(dir.value_or(fs::path{}), root / "share/rgbdquad/dashboard") << error;
  EXPECT_FALSE(find_data_dir(root / "bin/quad-control", kDefaultReplayDir, is_regular_file_noexcept,
                             &error));
  fs::remove_all(root);
}

TEST(DataPaths, TheCurrentExecutableIsThisTestBinary) {
  std::string error;
  const auto exe = current_executable(&error);
  ASSERT_TRUE(exe) << error;
  EXPECT_TRUE(exe->is_absolute());
  EXPECT_EQ(exe->filename(), "quadcontrol_app_tests");
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
