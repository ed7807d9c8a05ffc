// The per-frame, per-keyframe and memory tables of one pipeline run, as CSV files for long-run
// analysis (offboard/tools/longrun.py): frames.csv, mapping.csv, loops.csv, rss.csv. Pure writers
// of what the pipeline recorded; no clock, no threads.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "slam/localmap/local_mapper.hpp"
#include "slam/localmap/loop_closer.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace slam {

/// Memory use sampled during a run: (frame stamp s, resident set size MiB).
using RssSamples = std::vector<std::pair<double, double>>;

/// Writes the four tables into out_dir (which must exist); false with *error set when a file
/// cannot be written.
bool write_run_tables(const std::filesystem::path& out_dir, const std::vector<FrameRecord>& records,
                      const std::vector<MapperStats>& mapper_stats,
                      const std::vector<LoopStats>& loop_stats, const RssSamples& rss_samples,
                      std::string* error);

}  // namespace slam
