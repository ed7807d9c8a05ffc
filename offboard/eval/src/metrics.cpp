// Implementation of the TUM/evo trajectory metrics declared in rgbdquad/eval/metrics.hpp.
// The association, alignment and error definitions follow evo 1.38.1 (evo/core/sync.py,
// evo/core/geometry.py umeyama_alignment, evo/core/metrics.py APE/RPE); the pytest
// offboard/eval/tests/test_against_evo.py checks the numbers against evo itself.
#include "rgbdquad/eval/metrics.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <numeric>
#include <sstream>
#include <utility>

namespace rgbdquad::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kMetresToMm = 1000.0;
/// Fields of one TUM line: stamp, tx, ty, tz, qx, qy, qz, qw.
constexpr std::size_t kTumFieldCount = 8;
/// A quaternion shorter than this cannot be normalised meaningfully (files store ~1.0).
constexpr double kMinQuaternionNorm = 1e-6;

void set_error(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
}

bool is_finite_pose(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

// Splits on spaces, tabs and commas (TUM's associate.py replaces ',' and '\t' by ' ').
std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::string current;
  for (char c : line) {
    if (c == ' ' || c == '\t' || c == ',' || c == '\r') {
      if (!current.empty()) fields.push_back(std::move(current));
      current.clear();
    } else {
      current.push_back(c);
    }
  }
  if (!current.empty()) fields.push_back(std::move(current));
  return fields;
}

bool parse_double(const std::string& text, double* value) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || errno == ERANGE) return false;
  *value = v;
  return true;
}

double rms(const std::vector<double>& v) {
  double sum_sq = 0.0;
  for (double x : v) sum_sq += x * x;
  return std::sqrt(sum_sq / static_cast<double>(v.size()));
}

double mean(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// numpy.median: mean of the two middle values for an even count.
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return (n % 2 == 1) ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

bool check_inputs(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                  std::string* error) {
  if (!std::isfinite(max_dt_s) || max_dt_s <= 0.0) {
    set_error(error, "max_dt_s must be finite and > 0 (got " + std::to_string(max_dt_s) + ")");
    return false;
  }
  for (const auto* traj : {&gt, &est}) {
    for (std::size_t i = 0; i < traj->size(); ++i) {
      const auto& p = (*traj)[i];
      if (!std::isfinite(p.stamp_s) || !is_finite_pose(p.T_world_cam)) {
        set_error(error, std::string(traj == &gt ? "ground truth" : "estimate") + " pose " +
                             std::to_string(i) + " is not finite");
        return false;
      }
    }
  }
  return true;
}

std::vector<AssociatedPair> associate_evo_nearest(const Trajectory& gt, const Trajectory& est,
                                                  double max_dt_s) {
  // evo starts from the trajectory with fewer poses (est when equal) and looks each of its
  // stamps up in the other one.
  const bool gt_is_short = gt.size() < est.size();
  const Trajectory& shorter = gt_is_short ? gt : est;
  const Trajectory& longer = gt_is_short ? est : gt;
  std::vector<double> long_stamps(longer.size());
  for (std::size_t i = 0; i < longer.size(); ++i) long_stamps[i] = longer[i].stamp_s;
  const bool sorted = std::is_sorted(long_stamps.begin(), long_stamps.end());

  std::vector<AssociatedPair> pairs;
  if (long_stamps.empty()) return pairs;
  for (std::size_t i = 0; i < shorter.size(); ++i) {
    const double stamp = shorter[i].stamp_s;
    std::size_t best = 0;
    bool found = false;
    if (sorted) {
      // Mirrors evo's searchsorted(side="right") with its tie rule (earlier stamp wins).
      if (stamp < long_stamps.front() - max_dt_s || stamp > long_stamps.back() + max_dt_s) continue;
      std::size_t ub = static_cast<std::size_t>(
          std::upper_bound(long_stamps.begin(), long_stamps.end(), stamp) - long_stamps.begin());
      if (ub >= long_stamps.size()) ub = long_stamps.size() - 1;
      const double diff_ub = long_stamps[ub] - stamp;
      const double diff_lb = ub > 0 ? stamp - long_stamps[ub - 1] : INFINITY;
      if (diff_ub <= max_dt_s && diff_ub < diff_lb) {
        best = ub;
        found = true;
      } else if (diff_lb <= max_dt_s && diff_lb <= diff_ub) {
        best = ub - 1;
        found = true;
      }
    } else {
      // evo's linear fallback: argmin |dt| (first minimum).
      double best_diff = INFINITY;
      for (std::size_t j = 0; j < long_stamps.size(); ++j) {
        const double d = std::abs(long_stamps[j] - stamp);
        if (d < best_diff) {
          best_diff = d;
          best = j;
        }
      }
      found = best_diff <= max_dt_s;
    }
    if (!found) continue;
    pairs.push_back(gt_is_short ? AssociatedPair{i, best} : AssociatedPair{best, i});
  }
  return pairs;
}

std::vector<AssociatedPair> associate_tum_greedy(const Trajectory& gt, const Trajectory& est,
                                                 double max_dt_s) {
  struct Candidate {
    double dt_s;
    std::size_t gt_index, est_index;
  };
  // Sort gt stamps so candidate generation is O(n log n + candidates) instead of O(n*m).
  std::vector<std::size_t> gt_order(gt.size());
  std::iota(gt_order.begin(), gt_order.end(), 0);
  std::stable_sort(gt_order.begin(), gt_order.end(),
                   [&](std::size_t a, std::size_t b) { return gt[a].stamp_s < gt[b].stamp_s; });
  std::vector<double> gt_sorted(gt.size());
  for (std::size_t k = 0; k < gt.size(); ++k) gt_sorted[k] = gt[gt_order[k]].stamp_s;

  std::vector<Candidate> candidates;
  for (std::size_t e = 0; e < est.size(); ++e) {
    const double stamp = est[e].stamp_s;
    auto it = std::lower_bound(gt_sorted.begin(), gt_sorted.end(), stamp - max_dt_s);
    for (; it != gt_sorted.end() && *it <= stamp + max_dt_s; ++it) {
      const double dt = std::abs(*it - stamp);
      if (dt < max_dt_s) {  // associate.py uses a strict '<'
        candidates.push_back({dt, gt_order[static_cast<std::size_t>(it - gt_sorted.begin())], e});
      }
    }
  }
  // associate.py sorts tuples (dt, a, b): ties broken by the stamps themselves.
  std::sort(candidates.begin(), candidates.end(), [&](const Candidate& a, const Candidate& b) {
    if (a.dt_s != b.dt_s) return a.dt_s < b.dt_s;
    if (gt[a.gt_index].stamp_s != gt[b.gt_index].stamp_s)
      return gt[a.gt_index].stamp_s < gt[b.gt_index].stamp_s;
    return est[a.est_index].stamp_s < est[b.est_index].stamp_s;
  });
  std::vector<bool> gt_used(gt.size(), false), est_used(est.size(), false);
  std::vector<AssociatedPair> pairs;
  for (const auto& c : candidates) {
    if (gt_used[c.gt_index] || est_used[c.est_index]) continue;
    gt_used[c.gt_index] = true;
    est_used[c.est_index] = true;
    pairs.push_back({c.gt_index, c.est_index});
  }
  std::sort(pairs.begin(), pairs.end(), [&](const AssociatedPair& a, const AssociatedPair& b) {
    return est[a.est_index].stamp_s < est[b.est_index].stamp_s;
  });
  return pairs;
}

std::string format_json_number(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream s;
  s << std::setprecision(10) << v;
  return s.str();
}

std::string association_name(Association method) {
  return method == Association::kEvoNearest ? "evo_nearest" : "tum_greedy";
}

}  // namespace

double rotation_angle_deg(const Eigen::Matrix3d& R) {
  // atan2(|sin|, cos) is accurate over the whole [0, 180] deg range, unlike acos near 0.
  const double cos_angle = 0.5 * (R.trace() - 1.0);
  const Eigen::Vector3d axis_sin(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  const double sin_angle = 0.5 * axis_sin.norm();
  return std::atan2(sin_angle, cos_angle) * kRadToDeg;
}

std::optional<Trajectory> read_tum_trajectory(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    set_error(error, "cannot open trajectory file '" + path + "'");
    return std::nullopt;
  }
  Trajectory trajectory;
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const std::string content = trim(line);
    if (content.empty() || content[0] == '#') continue;
    const auto fields = split_fields(content);
    const std::string where = path + ":" + std::to_string(line_number) + ": ";
    if (fields.size() != kTumFieldCount) {
      set_error(error, where + "expected 8 fields 'timestamp tx ty tz qx qy qz qw', got " +
                           std::to_string(fields.size()));
      return std::nullopt;
    }
    double v[kTumFieldCount];
    for (std::size_t k = 0; k < kTumFieldCount; ++k) {
      if (!parse_double(fields[k], &v[k]) || !std::isfinite(v[k])) {
        set_error(error, where + "field " + std::to_string(k + 1) + " '" + fields[k] +
                             "' is not a finite number");
        return std::nullopt;
      }
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // Eigen order (w, x, y, z); file has w last
    if (q.norm() < kMinQuaternionNorm) {
      set_error(error, where + "quaternion has (near) zero norm");
      return std::nullopt;
    }
    q.normalize();
    StampedPose pose{v[0], Eigen::Isometry3d::Identity()};
    pose.T_world_cam.linear() = q.toRotationMatrix();
    pose.T_world_cam.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    trajectory.push_back(pose);
  }
  if (in.bad()) {
    set_error(error, "read error on '" + path + "'");
    return std::nullopt;
  }
  return trajectory;
}

bool write_tum_trajectory(const std::string& path, const Trajectory& trajectory,
                          std::string* error) {
  std::ofstream out(path);
  if (!out) {
    set_error(error, "cannot create trajectory file '" + path + "'");
    return false;
  }
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const auto& p = trajectory[i];
    if (!std::isfinite(p.stamp_s) || !is_finite_pose(p.T_world_cam)) {
      set_error(error, "pose " + std::to_string(i) + " is not finite; not written");
      return false;
    }
    const Eigen::Quaterniond q(p.T_world_cam.rotation());
    const Eigen::Vector3d t = p.T_world_cam.translation();
    out << std::fixed << std::setprecision(6) << p.stamp_s << std::setprecision(9) << ' ' << t.x()
        << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' '
        << q.w() << '\n';
  }
  out.flush();
  if (!out) {
    set_error(error, "write error on '" + path + "'");
    return false;
  }
  return true;
}

std::vector<AssociatedPair> associate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                      Association method) {
  if (!std::isfinite(max_dt_s) || max_dt_s <= 0.0) return {};
  return method == Association::kEvoNearest ? associate_evo_nearest(gt, est, max_dt_s)
                                            : associate_tum_greedy(gt, est, max_dt_s);
}

std::optional<AteResult> compute_ate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     std::string* error) {
  return compute_ate(gt, est, max_dt_s, Association::kEvoNearest, error);
}

std::optional<AteResult> compute_ate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     Association method, std::string* error) {
  if (!check_inputs(gt, est, max_dt_s, error)) return std::nullopt;
  const auto pairs = associate(gt, est, max_dt_s, method);
  if (pairs.size() < kMinAtePairs) {
    set_error(error, "only " + std::to_string(pairs.size()) + " pose pair(s) associated within " +
                         format_json_number(max_dt_s) + " s; ATE needs at least " +
                         std::to_string(kMinAtePairs));
    return std::nullopt;
  }
  const auto n = static_cast<Eigen::Index>(pairs.size());
  Eigen::Matrix3Xd est_points(3, n), gt_points(3, n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const auto& pair = pairs[static_cast<std::size_t>(k)];
    est_points.col(k) = est[pair.est_index].T_world_cam.translation();
    gt_points.col(k) = gt[pair.gt_index].T_world_cam.translation();
  }
  // Umeyama (1991) without scale: the same closed form evo's umeyama_alignment and TUM's
  // evaluate_ate.py (Horn 1987) compute, including the reflection guard.
  Eigen::Isometry3d T_gt_est(Eigen::umeyama(est_points, gt_points, /*with_scaling=*/false));
  if (!is_finite_pose(T_gt_est)) {
    set_error(error, "alignment failed (degenerate trajectory)");
    return std::nullopt;
  }

  std::vector<double> trans_err_m(pairs.size()), rot_err_deg(pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const Eigen::Isometry3d& Q = gt[pairs[k].gt_index].T_world_cam;
    const Eigen::Isometry3d P = T_gt_est * est[pairs[k].est_index].T_world_cam;
    trans_err_m[k] = (Q.translation() - P.translation()).norm();
    rot_err_deg[k] = rotation_angle_deg(Q.linear().transpose() * P.linear());
  }
  AteResult result{};
  result.trans_rmse_m = rms(trans_err_m);
  result.trans_mean_m = mean(trans_err_m);
  result.trans_median_m = median(trans_err_m);
  result.trans_max_m = *std::max_element(trans_err_m.begin(), trans_err_m.end());
  result.rot_rmse_deg = rms(rot_err_deg);
  result.pairs = pairs.size();
  result.T_gt_est = T_gt_est;
  return result;
}

std::optional<RpeResult> compute_rpe(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     std::string* error) {
  return compute_rpe(gt, est, max_dt_s, Association::kEvoNearest, error);
}

std::optional<RpeResult> compute_rpe(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     Association method, std::string* error) {
  if (!check_inputs(gt, est, max_dt_s, error)) return std::nullopt;
  const auto pairs = associate(gt, est, max_dt_s, method);
  if (pairs.size() < 2) {
    set_error(error, "only " + std::to_string(pairs.size()) + " pose pair(s) associated within " +
                         format_json_number(max_dt_s) + " s; RPE needs at least 2");
    return std::nullopt;
  }
  std::vector<double> trans_err_mm, rot_err_deg;
  for (std::size_t k = 0; k + 1 < pairs.size(); ++k) {
    const Eigen::Isometry3d& Q0 = gt[pairs[k].gt_index].T_world_cam;
    const Eigen::Isometry3d& Q1 = gt[pairs[k + 1].gt_index].T_world_cam;
    const Eigen::Isometry3d& P0 = est[pairs[k].est_index].T_world_cam;
    const Eigen::Isometry3d& P1 = est[pairs[k + 1].est_index].T_world_cam;
    const Eigen::Isometry3d E = (Q0.inverse() * Q1).inverse() * (P0.inverse() * P1);
    trans_err_mm.push_back(E.translation().norm() * kMetresToMm);
    rot_err_deg.push_back(rotation_angle_deg(E.linear()));
  }
  RpeResult result{};
  result.trans_rmse_mm = rms(trans_err_mm);
  result.trans_mean_mm = mean(trans_err_mm);
  result.rot_rmse_deg = rms(rot_err_deg);
  result.rot_mean_deg = mean(rot_err_deg);
  result.pairs = trans_err_mm.size();
  return result;
}

int run_score_command(const std::string& gt_path, const std::string& est_path, std::ostream& out,
                      std::ostream& err) {
  return run_score_command(gt_path, est_path, kDefaultMaxDtS, Association::kEvoNearest, out, err);
}

int run_score_command(const std::string& gt_path, const std::string& est_path, double max_dt_s,
                      Association method, std::ostream& out, std::ostream& err) {
  std::string error;
  const auto gt = read_tum_trajectory(gt_path, &error);
  if (!gt) {
    err << "error: ground truth: " << error << '\n';
    return 1;
  }
  const auto est = read_tum_trajectory(est_path, &error);
  if (!est) {
    err << "error: estimate: " << error << '\n';
    return 1;
  }
  const auto ate = compute_ate(*gt, *est, max_dt_s, method, &error);
  if (!ate) {
    err << "error: ATE: " << error << '\n';
    return 1;
  }
  const auto rpe = compute_rpe(*gt, *est, max_dt_s, method, &error);
  if (!rpe) {
    err << "error: RPE: " << error << '\n';
    return 1;
  }
  const Eigen::Quaterniond q(ate->T_gt_est.rotation());
  const Eigen::Vector3d t = ate->T_gt_est.translation();
  const auto num = format_json_number;
  out << "{\n"
      << "  \"ate_rmse_m\": " << num(ate->trans_rmse_m) << ",\n"
      << "  \"ate_mean_m\": " << num(ate->trans_mean_m) << ",\n"
      << "  \"ate_median_m\": " << num(ate->trans_median_m) << ",\n"
      << "  \"ate_max_m\": " << num(ate->trans_max_m) << ",\n"
      << "  \"ate_rot_rmse_deg\": " << num(ate->rot_rmse_deg) << ",\n"
      << "  \"rpe_trans_rmse_mm\": " << num(rpe->trans_rmse_mm) << ",\n"
      << "  \"rpe_trans_mean_mm\": " << num(rpe->trans_mean_mm) << ",\n"
      << "  \"rpe_rot_rmse_deg\": " << num(rpe->rot_rmse_deg) << ",\n"
      << "  \"rpe_rot_mean_deg\": " << num(rpe->rot_mean_deg) << ",\n"
      << "  \"pairs\": " << ate->pairs << ",\n"
      << "  \"rpe_pairs\": " << rpe->pairs << ",\n"
      << "  \"gt_poses\": " << gt->size() << ",\n"
      << "  \"est_poses\": " << est->size() << ",\n"
      << "  \"max_dt_s\": " << num(max_dt_s) << ",\n"
      << "  \"association\": \"" << association_name(method) << "\",\n"
      << "  \"T_gt_est_xyz_m\": [" << num(t.x()) << ", " << num(t.y()) << ", " << num(t.z())
      << "],\n"
      << "  \"T_gt_est_qxyzw\": [" << num(q.x()) << ", " << num(q.y()) << ", " << num(q.z()) << ", "
      << num(q.w()) << "]\n"
      << "}\n";
  return out ? 0 : 1;
}

}  // namespace rgbdquad::eval
