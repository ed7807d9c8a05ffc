// Motion-only RGB-D pose optimisation; see pose_optimizer.hpp.
//
// Residual of observation i: e_i = pi(T p_i) - z_i, pi = (fx x/z + cx, fy y/z + cy, bf/z), whitened
// by sigma_i. A left perturbation T <- exp(delta) T moves the camera point by
// d(p_c)/d(delta) = [ -[p_c]x  I ], so J_i = d(pi)/d(p_c) * [ -[p_c]x  I ].
#include "slam/tracking/pose_optimizer.hpp"

#include <Eigen/Cholesky>
#include <cmath>

namespace rgbdquad::slam {

Eigen::Isometry3d apply_left_increment(const Eigen::Matrix<double, 6, 1>& delta,
                                       const Eigen::Isometry3d& T) {
  const Eigen::Vector3d w = delta.head<3>();
  const double angle = w.norm();
  Eigen::Isometry3d inc = Eigen::Isometry3d::Identity();
  if (angle > 1e-12) inc.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  inc.translation() = delta.tail<3>();
  Eigen::Isometry3d out = inc * T;
  // Keep the rotation orthonormal over many updates.
  out.linear() = Eigen::Quaterniond(out.rotation()).normalized().toRotationMatrix();
  return out;
}

namespace {

// Gravity prior: e = (R_cw d_w - d_c) / sigma. Under T <- exp(delta) T the predicted direction
// v = R_cw d_w moves by -[v]x delta_rot, so J = [ -[v]x  0 ] / sigma (rank 2: a turn about
// gravity changes nothing). Added to the pose block of H and b (their first 6 rows).
template <int N>
void add_gravity_term(const GravityPrior& g, const Eigen::Isometry3d& T,
                      Eigen::Matrix<double, N, N>* H, Eigen::Matrix<double, N, 1>* b) {
  const Eigen::Vector3d v = T.linear() * g.down_world;
  const double inv_sigma = 1.0 / g.sigma_rad;
  const Eigen::Vector3d e = (v - g.down_cam) * inv_sigma;
  Eigen::Matrix<double, 3, 6> J = Eigen::Matrix<double, 3, 6>::Zero();
  J.leftCols<3>() << 0, v.z(), -v.y(), -v.z(), 0, v.x(), v.y(), -v.x(), 0;
  J *= inv_sigma;
  H->template topLeftCorner<6, 6>().noalias() += J.transpose() * J;
  b->template head<6>().noalias() += J.transpose() * e;
}

/// The pose fit with N = 6 unknowns (the pose) or N = 9 (the pose and, for a rolling shutter, the
/// angular velocity over the readout). With N = 9 observation i sees the camera point rotated
/// back over its row time t_i: q = R(-omega t_i) p_c, so dq/d(omega) = t_i [q]x (first order).
template <int N>
PoseOptimizerResult optimize(const Eigen::Isometry3d& T_init,
                             const std::vector<PoseObservation>& obs, const CameraModel& cam,
                             const PoseOptimizerOptions& o) {
  static_assert(N == 6 || N == 9, "pose, or pose and angular velocity");
  const RollingShutterModel* rs = N == 9 ? &*o.rolling_shutter : nullptr;
  PoseOptimizerResult r;
  r.T_cam_world = T_init;
  r.inlier.assign(obs.size(), true);
  if (obs.size() < 3) return r;
  // Outlier bound and Huber threshold per observation: a monocular one has two residuals.
  auto chi2_of = [&o](const PoseObservation& ob) {
    return ob.monocular ? o.chi2_outlier * (kChi2Mono95 / kChi2Rgbd95) : o.chi2_outlier;
  };
  Eigen::Isometry3d T = T_init;
  Eigen::Vector3d omega = rs ? rs->omega_prior_rad_per_s : Eigen::Vector3d::Zero();
  // The camera point observation i sees (its row's exposure, with a rolling shutter).
  auto seen = [&](std::size_t i, const Eigen::Vector3d& pc) -> Eigen::Vector3d {
    if (!rs) return pc;
    const Eigen::Vector3d a = -omega * rs->row_time_s[i];
    const double angle = a.norm();
    return angle > 0 ? Eigen::Vector3d(Eigen::AngleAxisd(angle, a / angle) * pc) : pc;
  };
  for (int round = 0; round < o.rounds; ++round) {
    for (int it = 0; it < o.iterations_per_round; ++it) {
      Eigen::Matrix<double, N, N> H = Eigen::Matrix<double, N, N>::Zero();
      Eigen::Matrix<double, N, 1> b = Eigen::Matrix<double, N, 1>::Zero();
      int used = 0;
      for (std::size_t i = 0; i < obs.size(); ++i) {
        if (!r.inlier[i]) continue;
        const Eigen::Vector3d pc = seen(i, T * obs[i].p_world_m);
        if (pc.z() <= 1e-3) continue;
        Eigen::Vector3d e = (cam.project(pc) - obs[i].measurement).cwiseQuotient(obs[i].sigma_px);
        Eigen::Matrix3d Jp = obs[i].sigma_px.cwiseInverse().asDiagonal() * cam.project_jacobian(pc);
        if (obs[i].monocular) {
          e.z() = 0;
          Jp.row(2).setZero();
        }
        Eigen::Matrix<double, 3, N> Jt;
        const Eigen::Matrix3d pc_x = skew(pc);
        Jt.template leftCols<3>() = -pc_x;
        Jt.template middleCols<3>(3) = Eigen::Matrix3d::Identity();
        if constexpr (N == 9) Jt.template rightCols<3>() = rs->row_time_s[i] * pc_x;
        const Eigen::Matrix<double, 3, N> J = Jp * Jt;
        const double norm = e.norm();
        const double huber = std::sqrt(chi2_of(obs[i]));
        const double w = norm <= huber ? 1.0 : huber / norm;
        H.noalias() += w * J.transpose() * J;
        b.noalias() += w * J.transpose() * e;
        ++used;
      }
      if (used < 3) return r;
      if (o.gravity) add_gravity_term<N>(*o.gravity, T, &H, &b);
      if constexpr (N == 9) {
        const double info = 1.0 / (rs->omega_sigma_rad_per_s * rs->omega_sigma_rad_per_s);
        H.template bottomRightCorner<3, 3>().diagonal().array() += info;
        b.template tail<3>() += info * (omega - rs->omega_prior_rad_per_s);
      }
      Eigen::LDLT<Eigen::Matrix<double, N, N>> ldlt(H);
      if (ldlt.info() != Eigen::Success) return r;
      const Eigen::Matrix<double, N, 1> delta = ldlt.solve(-b);
      if (!delta.allFinite()) return r;
      T = apply_left_increment(delta.template head<6>(), T);
      if constexpr (N == 9) omega += delta.template tail<3>();
      if (delta.norm() < 1e-9) break;
    }
    // Re-classify every observation (an outlier of one round may come back).
    r.inliers = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const Eigen::Vector3d pc = seen(i, T * obs[i].p_world_m);
      bool in = pc.z() > 1e-3;
      if (in) {
        Eigen::Vector3d e = (cam.project(pc) - obs[i].measurement).cwiseQuotient(obs[i].sigma_px);
        if (obs[i].monocular) e.z() = 0;
        in = e.squaredNorm() <= chi2_of(obs[i]);
      }
      r.inlier[i] = in;
      r.inliers += in ? 1 : 0;
    }
    if (r.inliers < 3) return r;
  }
  r.T_cam_world = T;
  r.omega_cam_rad_per_s = omega;
  r.ok = T.matrix().allFinite() && omega.allFinite();
  return r;
}

}  // namespace

PoseOptimizerResult optimize_pose(const Eigen::Isometry3d& T_init,
                                  const std::vector<PoseObservation>& obs, const CameraModel& cam,
                                  const PoseOptimizerOptions& o) {
  if (o.rolling_shutter && o.rolling_shutter->row_time_s.size() == obs.size())
    return optimize<9>(T_init, obs, cam, o);
  return optimize<6>(T_init, obs, cam, o);
}

}  // namespace rgbdquad::slam
