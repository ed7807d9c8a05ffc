// Run tables; see run_tables.hpp. The column layouts are what slam-eval has always written.
#include "slam/report/run_tables.hpp"

#include <fstream>
#include <iomanip>

namespace rgbdquad::slam {

namespace fs = std::filesystem;

std::optional<FramesTable> FramesTable::create(const fs::path& path, std::string* error) {
  std::ofstream out(path);
  out << "index,stamp_s,state,keyframe,matches,inliers,frontend_ms,frontend_cpu_ms,map_keyframes,"
         "map_points,keyframe_wanted,ref_tracked,near_tracked,near_untracked,near_redundant,"
         "map_lock_wait_ms,relocalised,features_ms,matching_ms,relocalise_ms,prediction_stale,"
         "prediction_deviation_m,prediction_deviation_bound_m,attitude_predicted,cross_checked,"
         "cross_check_shift_m,cross_check_shift_deg,new_segment,segment_merged,off_path_"
         "confirmed,attitude_refused,rolling_shutter_rate_x,rolling_shutter_rate_y,"
         "rolling_shutter_rate_z,depthless_inliers\n";
  if (!out) {
    if (error) *error = "cannot write " + path.string();
    return std::nullopt;
  }
  return FramesTable(path, std::move(out));
}

void FramesTable::append(const FrameRecord& r) {
  out_ << r.index << "," << std::fixed << std::setprecision(6) << r.stamp_s << ","
       << to_string(r.state) << "," << (r.keyframe ? 1 : 0) << "," << r.matches << "," << r.inliers
       << "," << std::setprecision(3) << r.frontend_ms << "," << r.frontend_cpu_ms << ","
       << r.map_keyframes << "," << r.map_points << "," << to_string(r.keyframe_wanted) << ","
       << r.ref_tracked << "," << r.near_tracked << "," << r.near_untracked << ","
       << r.near_redundant << "," << r.map_lock_wait_ms << "," << (r.relocalised ? 1 : 0) << ","
       << r.features_ms << "," << r.matching_ms << "," << r.ransac_ms << ","
       << (r.prediction_stale ? 1 : 0) << "," << std::setprecision(4) << r.prediction_deviation_m
       << "," << r.prediction_deviation_bound_m << "," << (r.attitude_predicted ? 1 : 0) << ","
       << (r.cross_checked ? 1 : 0) << "," << r.cross_check_shift_m << ","
       << r.cross_check_shift_deg << "," << (r.new_segment ? 1 : 0) << ","
       << (r.segment_merged ? 1 : 0) << "," << (r.off_path_confirmed ? 1 : 0) << ","
       << (r.attitude_refused ? 1 : 0);
  // Empty when the frame had no rolling-shutter refit (a global shutter, an untracked frame).
  for (int i = 0; i < 3; ++i) {
    out_ << ",";
    if (r.rolling_shutter_rate_rad_per_s) out_ << (*r.rolling_shutter_rate_rad_per_s)[i];
  }
  out_ << "," << r.depthless_inliers;
  out_ << "\n";
}

bool FramesTable::close(std::string* error) {
  out_.close();
  if (out_) return true;
  if (error) *error = "cannot write " + path_.string();
  return false;
}

bool write_run_tables(const fs::path& out_dir, const std::vector<FrameRecord>& records,
                      const std::vector<MapperStats>& mapper_stats,
                      const std::vector<LoopStats>& loop_stats, const RssSamples& rss_samples,
                      std::string* error) {
  auto frames = FramesTable::create(out_dir / "frames.csv", error);
  if (!frames) return false;
  for (const auto& r : records) frames->append(r);
  return frames->close(error) &&
         write_keyframe_tables(out_dir, mapper_stats, loop_stats, &rss_samples, error);
}

bool write_keyframe_tables(const fs::path& out_dir, const std::vector<MapperStats>& mapper_stats,
                           const std::vector<LoopStats>& loop_stats, const RssSamples* rss_samples,
                           std::string* error) {
  std::ofstream mapping_csv(out_dir / "mapping.csv");
  mapping_csv << "keyframe,mapping_ms,mapping_cpu_ms,ba_ms,ba_points,points_culled,points_fused,"
                 "keyframes_culled,caught_up,ba_interrupted,points_triangulated\n";
  for (const auto& st : mapper_stats)
    mapping_csv << st.keyframe << "," << std::fixed << std::setprecision(3) << st.total_ms << ","
                << st.total_cpu_ms << "," << st.ba_ms << "," << st.ba_points << ","
                << st.points_culled << "," << st.points_fused << "," << st.keyframes_culled << ","
                << (st.caught_up ? 1 : 0) << "," << (st.ba_interrupted ? 1 : 0) << ","
                << st.points_triangulated << "\n";
  std::ofstream loops_csv(out_dir / "loops.csv");
  loops_csv
      << "keyframe,searched,candidates,verified_ransac,accepted,loop_keyframe,ransac_inliers,"
         "fit_inliers,correction_m,correction_deg,graph_keyframes,graph_edges,points_merged,"
         "points_attached,bow_ms,query_ms,verify_ms,posegraph_ms,snapshot_lock_ms,apply_lock_ms,"
         "fuse_lock_ms,total_ms,total_cpu_ms,consistent,verified_fit,refused_odometry,"
         "gate_keyframe,gate_path_m,gate_translation_m,gate_rotation_deg,gate_chi2\n";
  for (const auto& l : loop_stats)
    loops_csv << l.keyframe << "," << l.searched << "," << l.candidates << "," << l.verified_ransac
              << "," << l.accepted << "," << l.loop_keyframe << "," << l.ransac_inliers << ","
              << l.fit_inliers << "," << std::fixed << std::setprecision(4) << l.correction_m << ","
              << l.correction_deg << "," << l.graph_keyframes << "," << l.graph_edges << ","
              << l.points_merged << "," << l.points_attached << "," << l.bow_ms << "," << l.query_ms
              << "," << l.verify_ms << "," << l.posegraph_ms << "," << l.snapshot_lock_ms << ","
              << l.apply_lock_ms << "," << l.fuse_lock_ms << "," << l.total_ms << ","
              << l.total_cpu_ms << "," << l.consistent << "," << l.verified_fit << ","
              << l.refused_odometry << "," << l.gate_keyframe << "," << l.gate_path_m << ","
              << l.gate_translation_m << "," << l.gate_rotation_deg << "," << l.gate_chi2 << "\n";
  bool rss_ok = true;
  if (rss_samples) {
    std::ofstream rss_csv(out_dir / "rss.csv");
    rss_csv << "stamp_s,rss_mib\n";
    for (const auto& [t, mib] : *rss_samples)
      rss_csv << std::fixed << std::setprecision(6) << t << "," << mib << "\n";
    rss_ok = static_cast<bool>(rss_csv);
  }
  if (!mapping_csv || !loops_csv || !rss_ok) {
    if (error) *error = "cannot write the run tables in " + out_dir.string();
    return false;
  }
  return true;
}

}  // namespace rgbdquad::slam
