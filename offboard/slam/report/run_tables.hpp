// The per-frame, per-keyframe and memory tables of one pipeline run, as CSV files for long-run
// analysis (offboard/bench/tools/longrun.py): frames.csv, mapping.csv, loops.csv, rss.csv. Pure
// writers of what the pipeline recorded; no clock, no threads.
#pragma once

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "slam/loopclosing/loop_closer.hpp"
#include "slam/mapping/local_mapper.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace rgbdquad::slam {

/// Memory use sampled during a run: (frame stamp s, resident set size MiB).
using RssSamples = std::vector<std::pair<double, double>>;

/// frames.csv, row by row: slam-server appends a flight's rows as the pipeline retires them
/// (Pipeline::retire_records), so that the table, not memory, grows with the flight.
class FramesTable {
 public:
  /// Creates (truncates) `path` and writes the header; nullopt with `error` when it cannot.
  static std::optional<FramesTable> create(const std::filesystem::path& path, std::string* error);
  void append(const FrameRecord& r);
  /// Flushes and closes; false with `error` when any write failed.
  bool close(std::string* error);

 private:
  FramesTable(std::filesystem::path path, std::ofstream out)
      : path_(std::move(path)), out_(std::move(out)) {}
  std::filesystem::path path_;
  std::ofstream out_;
};

/// mapping.csv and loops.csv, and rss.csv when `rss_samples` is given (slam-server samples none),
/// into out_dir (which must exist); false with *error set when a file cannot be written.
bool write_keyframe_tables(const std::filesystem::path& out_dir,
                           const std::vector<MapperStats>& mapper_stats,
                           const std::vector<LoopStats>& loop_stats, const RssSamples* rss_samples,
                           std::string* error);

/// Writes the four tables (frames.csv and write_keyframe_tables) into out_dir (which must exist);
/// false with *error set when a file cannot be written.
bool write_run_tables(const std::filesystem::path& out_dir, const std::vector<FrameRecord>& records,
                      const std::vector<MapperStats>& mapper_stats,
                      const std::vector<LoopStats>& loop_stats, const RssSamples& rss_samples,
                      std::string* error);

}  // namespace rgbdquad::slam
