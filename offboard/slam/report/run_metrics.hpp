// The measured part of a run's metrics.json: counts, per-stage timing statistics, mapping and
// loop-closing figures, frames until tracking, and the ATE/RPE score against the dataset's ground
// truth. The app adds the options it ran with. Pure: everything comes in as values (the wall time
// is measured by the caller).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/eval/metrics.hpp"
#include "slam/loopclosing/loop_closer.hpp"
#include "slam/mapping/local_mapper.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace rgbdquad::slam {

/// count, mean, median, p95 and max (ms) of a sample; only the count when it is empty.
nlohmann::json stage_stats(std::vector<double> v);

struct RunOutcome {
  std::vector<FrameRecord> records;
  PipelineSummary summary;
  std::vector<MapperStats> mapper_stats;
  std::vector<LoopStats> loop_stats;
  bool local_map = false;
  bool glc_backend = false;      ///< the thesis GLC back-end ran (its per-frame time is reported)
  long exported_map_points = 0;  ///< points written to map.ply by a thesis back-end
  double wall_s = 0;
  std::size_t frames_withheld = 0;
  /// Stream stall simulation: frames from first_stamp_s + withhold_from_s on were withheld for
  /// withhold_s (0: none).
  double first_stamp_s = -1, withhold_from_s = -1, withhold_s = 0;
  eval::Trajectory final_trajectory, online_trajectory;
};

/// What a finished pipeline recorded (records, summary, stage statistics, the final and online
/// trajectories); the caller adds the replay's figures (wall time, withheld frames, map export).
RunOutcome collect_run_outcome(const Pipeline& pipeline);

/// Adds the measured keys to *m. Scores against groundtruth_path when it is not empty (a file
/// that cannot be read sets "ground_truth": null and a message in *warning).
void add_run_metrics(const RunOutcome& run, const std::string& groundtruth_path, nlohmann::json* m,
                     std::string* warning);

}  // namespace rgbdquad::slam
