// Shipped data folders found relative to the executable: see data_paths.hpp.
#include "app/data_paths.hpp"

#include <system_error>

namespace rgbdquad::quadcontrol {

namespace fs = std::filesystem;

std::vector<fs::path> data_dir_candidates(const fs::path& exe_path, const DataDir& dir) {
  const fs::path exe_dir = exe_path.parent_path();
  std::vector<fs::path> candidates;
  candidates.push_back((exe_dir / ".." / kInstalledShareDir / dir.installed).lexically_normal());
  fs::path ancestor = exe_dir;
  for (int level = 1; level <= kSourceTreeMaxLevelsUp; ++level) {
    if (ancestor == ancestor.root_path() || ancestor.empty()) break;  // nothing above the root
    ancestor = ancestor.parent_path();
    candidates.push_back((ancestor / dir.source_tree).lexically_normal());
  }
  return candidates;
}

std::optional<fs::path> find_data_dir(const fs::path& exe_path, const DataDir& dir,
                                      const std::function<bool(const fs::path&)>& is_file,
                                      std::string* error) {
  const std::vector<fs::path> candidates = data_dir_candidates(exe_path, dir);
  for (const fs::path& candidate : candidates) {
    if (is_file(candidate / dir.marker)) return candidate;
  }
  std::string tried;
  for (const fs::path& candidate : candidates) tried += "\n  " + candidate.string();
  *error = std::string(dir.what) + " not found: no " + dir.marker + " in any of (relative to " +
           exe_path.string() + ")" + tried +
           "\nInstall them with quad-control (cmake --install) or set " + dir.override_with;
  return std::nullopt;
}

std::optional<fs::path> current_executable(std::string* error) {
  std::error_code ec;
  fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) {
    *error = "cannot read /proc/self/exe to find the installed data: " + ec.message();
    return std::nullopt;
  }
  return exe;
}

bool is_regular_file_noexcept(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

}  // namespace rgbdquad::quadcontrol
