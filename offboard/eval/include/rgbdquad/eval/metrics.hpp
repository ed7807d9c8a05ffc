// Trajectory scoring exactly as the TUM RGB-D benchmark tools and evo (1.38.1) define it:
// TUM-format trajectory I/O, timestamp association, absolute trajectory error (ATE) after a
// rigid SE(3) Horn/Umeyama alignment, and frame-to-frame relative pose error (RPE).
//
// Conventions: a pose `T_world_cam` maps points from the camera frame to the world frame
// (TUM files store its translation tx ty tz and its rotation as the unit quaternion
// qx qy qz qw, scalar LAST). Stamps are seconds. All functions are pure, thread-safe (no shared
// state) and never throw on bad input: they return std::nullopt / false and fill *error (when
// error is not null) with a message a person can act on.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace rgbdquad::eval {

struct StampedPose {
  double stamp_s;
  Eigen::Isometry3d T_world_cam;
};
using Trajectory = std::vector<StampedPose>;

/// Benchmark rule for matching stamps of two sensors/trajectories (TUM associate.py default
/// is 20 ms; evo's command-line default is 10 ms, so pass 0.02 to evo to compare).
constexpr double kDefaultMaxDtS = 0.02;

/// Reads a TUM trajectory (`stamp tx ty tz qx qy qz qw` per line; '#' lines and blank lines are
/// skipped; fields separated by spaces, tabs or commas, as TUM's tools accept). Quaternions are
/// normalised; a zero or non-finite quaternion, a non-finite value, a wrong field count or an
/// unparsable number is an error naming the 1-based line number. Poses keep file order.
std::optional<Trajectory> read_tum_trajectory(const std::string& path, std::string* error);

/// Writes `stamp tx ty tz qx qy qz qw` lines (stamps with 6 decimals = microseconds, positions
/// and quaternion with 9 significant decimals). Returns false (and sets *error) on I/O failure
/// or a non-finite pose.
bool write_tum_trajectory(const std::string& path, const Trajectory& trajectory,
                          std::string* error);

/// How estimated and ground-truth stamps are paired.
enum class Association {
  /// evo's `nearest_time` sync (evo.core.sync.associate_trajectories): for every stamp of the
  /// SHORTER trajectory (est when sizes are equal), the nearest stamp of the longer one if
  /// |dt| <= max_dt (ties go to the earlier stamp). A stamp of the longer trajectory may be used
  /// twice. Pairs follow the file order of the shorter trajectory. This is the default because
  /// the acceptance numbers are evo's.
  kEvoNearest,
  /// TUM associate.py: all candidate pairs with |dt| < max_dt, taken greedily by increasing |dt|,
  /// each stamp used at most once; pairs sorted by est stamp.
  kTumGreedy,
};

/// One associated pair: indices into the gt and est trajectories.
struct AssociatedPair {
  std::size_t gt_index;
  std::size_t est_index;
};

/// Associates est with gt by timestamp (see Association). Returns pairs in sequence order.
std::vector<AssociatedPair> associate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                      Association method = Association::kEvoNearest);

struct AteResult {
  double trans_rmse_m, trans_mean_m, trans_median_m, trans_max_m, rot_rmse_deg;
  std::size_t pairs;
  /// Rigid transform applied to the estimate: est_aligned = T_gt_est * est (least squares over
  /// the associated positions, Umeyama 1991 without scale = Horn 1987).
  Eigen::Isometry3d T_gt_est;
};

struct RpeResult {
  double trans_rmse_mm, trans_mean_mm, rot_rmse_deg, rot_mean_deg;
  std::size_t pairs;  ///< number of relative-pose errors (associated poses - 1)
};

/// Fewest associated poses accepted: three non-collinear points fix a rigid alignment.
constexpr std::size_t kMinAtePairs = 3;

/// ATE (evo_ape tum GT EST -a --t_max_diff max_dt): translation error |t_gt - t_aligned| over
/// associated pairs (RMSE/mean/median/max, metres) and rotation error angle(R_gt^-1 R_aligned)
/// (RMSE, degrees). Needs >= kMinAtePairs pairs and finite max_dt_s > 0.
std::optional<AteResult> compute_ate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     std::string* error);
std::optional<AteResult> compute_ate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     Association method, std::string* error);

/// RPE over consecutive associated poses (evo_rpe --delta 1 --delta_unit f): with Q = gt and
/// P = est, E_i = (Q_i^-1 Q_{i+1})^-1 (P_i^-1 P_{i+1}); translation |t(E_i)| in mm and rotation
/// angle(E_i) in degrees, RMSE and mean. Needs >= 2 associated pairs.
std::optional<RpeResult> compute_rpe(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     std::string* error);
std::optional<RpeResult> compute_rpe(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                     Association method, std::string* error);

/// Reads both files, scores est against gt with kDefaultMaxDtS and writes one JSON object to
/// `out` (`ate_rmse_m`, `ate_rot_rmse_deg`, `rpe_trans_rmse_mm`, `rpe_rot_rmse_deg`, `pairs`, ...).
/// Returns 0 on success, 1 on bad input (message on `err`).
int run_score_command(const std::string& gt_path, const std::string& est_path, std::ostream& out,
                      std::ostream& err);
/// Same with an explicit association window and method (the `tum-score` CLI options).
int run_score_command(const std::string& gt_path, const std::string& est_path, double max_dt_s,
                      Association method, std::ostream& out, std::ostream& err);

/// Rotation angle of R in degrees, in [0, 180] (robust near 0 and 180).
double rotation_angle_deg(const Eigen::Matrix3d& R);

}  // namespace rgbdquad::eval
