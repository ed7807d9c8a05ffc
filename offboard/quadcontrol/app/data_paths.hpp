// Where quad-control finds the data it ships with (the dashboard's static files, the default TUM
// replay excerpt), relative to its own executable, so an installed quad-control runs from any
// working directory and no source-tree path is compiled in:
//   1. <exe dir>/../share/rgbdquad/<installed>  - installed (`cmake --install`, app/CMakeLists.txt
//                                                 install rules; docs/control.md "Installing")
//   2. <ancestor>/<source_tree> for the exe dir's 1st to 3rd ancestor - run from a build tree
//                                                 inside the source tree (build*/bin/quad-control)
// The first candidate holding the folder's marker file wins; none: an error naming every path
// tried. A config key (dashboard.static_dir, stream.tum_folder) or --tum overrides the search.
// Pure functions (the file test is passed in) except current_executable(); thread-safe.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rgbdquad::quadcontrol {

/// One shipped data folder.
struct DataDir {
  const char* what;         ///< for messages: "dashboard static files"
  const char* installed;    ///< below <prefix>/share/rgbdquad (kept equal to the install rules)
  const char* source_tree;  ///< below the source root
  const char* marker;       ///< a file the folder must hold (an empty or stale folder is not taken)
  const char* override_with;  ///< the setting that names the folder instead (for the error)
};

/// Install layout below the prefix; app/CMakeLists.txt installs into the same folders.
inline constexpr const char* kInstalledShareDir = "share/rgbdquad";
inline constexpr DataDir kDashboardStaticDir{"dashboard static files", "dashboard",
                                             "offboard/dashboard/static", "index.html",
                                             "dashboard.static_dir in the config"};
inline constexpr DataDir kDefaultReplayDir{"default TUM replay (fr1_xyz_first30)",
                                           "data/fr1_xyz_first30", "tests/data/fr1_xyz_first30",
                                           "rgb.txt", "--tum or stream.tum_folder in the config"};

/// How far up from the executable's folder the source tree is looked for: build/bin/ is 2 levels
/// below the source root, a nested build folder (build/x/bin) 3.
inline constexpr int kSourceTreeMaxLevelsUp = 3;

/// The folders tried for `dir`, in order, lexically normalised (no filesystem access).
std::vector<std::filesystem::path> data_dir_candidates(const std::filesystem::path& exe_path,
                                                       const DataDir& dir);

/// The first candidate whose marker file `is_file` reports; nullopt with `error` naming what was
/// looked for, every path tried and the config key that overrides the search.
std::optional<std::filesystem::path> find_data_dir(
    const std::filesystem::path& exe_path, const DataDir& dir,
    const std::function<bool(const std::filesystem::path&)>& is_file, std::string* error);

/// This process's executable (/proc/self/exe, symlinks resolved); nullopt with `error` when
/// unreadable (no /proc).
std::optional<std::filesystem::path> current_executable(std::string* error);

/// The real filesystem's file test for find_data_dir (false on any error).
bool is_regular_file_noexcept(const std::filesystem::path& p);

}  // namespace rgbdquad::quadcontrol
