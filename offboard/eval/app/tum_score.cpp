// tum-score: scores an estimated TUM trajectory against ground truth and prints JSON
// (ATE after SE(3) alignment, frame-to-frame RPE), matching evo_ape/evo_rpe 1.38.1.
// Only main + argument parsing live here; the metrics are in slam_metrics.
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>

#include "rgbdquad/eval/metrics.hpp"

namespace eval = rgbdquad::eval;

namespace {

constexpr const char* kUsage =
    "usage: tum-score [--max-dt SECONDS] [--association evo|tum] GROUNDTRUTH ESTIMATE\n"
    "\n"
    "Scores ESTIMATE against GROUNDTRUTH (both TUM format: 'stamp tx ty tz qx qy qz qw' per line)\n"
    "and prints one JSON object: ate_rmse_m, ate_mean_m, ate_median_m, ate_max_m,\n"
    "ate_rot_rmse_deg, rpe_trans_rmse_mm, rpe_trans_mean_mm, rpe_rot_rmse_deg, rpe_rot_mean_deg,\n"
    "pairs, rpe_pairs, the alignment T_gt_est and the settings used.\n"
    "ATE: rigid SE(3) Umeyama alignment of the estimate to the ground truth (no scale), as\n"
    "`evo_ape tum GT EST -a --t_max_diff 0.02`. RPE: consecutive associated poses, as\n"
    "`evo_rpe tum GT EST --delta 1 --delta_unit f --t_max_diff 0.02`.\n"
    "\n"
    "options:\n"
    "  --max-dt SECONDS        association window (default 0.02, the TUM benchmark's rule)\n"
    "  --association evo|tum   evo: nearest stamp per pose of the shorter trajectory (evo's\n"
    "                          default, the default here); tum: greedy unique pairs by |dt|\n"
    "                          (TUM associate.py)\n"
    "  -h, --help              show this help\n"
    "\n"
    "exit status: 0 on success, 1 on bad input (unreadable file, unparsable line, too few\n"
    "associated pairs), 2 on bad usage.\n";

int usage_error(const std::string& message) {
  std::cerr << "tum-score: " << message << "\n\n" << kUsage;
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  double max_dt_s = eval::kDefaultMaxDtS;
  auto method = eval::Association::kEvoNearest;
  std::string positional[2];
  int positional_count = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      std::cout << kUsage;
      return 0;
    }
    if (arg == "--max-dt" || arg == "--association") {
      if (i + 1 >= argc) return usage_error(arg + " needs a value");
      const std::string value = argv[++i];
      if (arg == "--max-dt") {
        char* end = nullptr;
        max_dt_s = std::strtod(value.c_str(), &end);
        if (end == value.c_str() || *end != '\0' || !std::isfinite(max_dt_s) || max_dt_s <= 0.0) {
          return usage_error("--max-dt must be a positive number of seconds, got '" + value + "'");
        }
      } else if (value == "evo") {
        method = eval::Association::kEvoNearest;
      } else if (value == "tum") {
        method = eval::Association::kTumGreedy;
      } else {
        return usage_error("--association must be 'evo' or 'tum', got '" + value + "'");
      }
      continue;
    }
    if (!arg.empty() && arg[0] == '-') return usage_error("unknown option '" + arg + "'");
    if (positional_count == 2) return usage_error("too many arguments");
    positional[positional_count++] = arg;
  }
  if (positional_count != 2) return usage_error("need GROUNDTRUTH and ESTIMATE");
  return eval::run_score_command(positional[0], positional[1], max_dt_s, method, std::cout,
                                 std::cerr);
}
