// Umeyama/Kabsch and RANSAC; see motion.hpp for the conventions.
#include "slam/motion/motion.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "slam/core/types.hpp"

namespace rgbdquad::slam {

std::optional<Eigen::Isometry3d> umeyama_rigid(const std::vector<Eigen::Vector3d>& src,
                                               const std::vector<Eigen::Vector3d>& dst,
                                               const std::vector<double>& weights) {
  const std::size_t n = src.size();
  if (n < 3 || dst.size() != n || (!weights.empty() && weights.size() != n)) return std::nullopt;
  double wsum = 0;
  Eigen::Vector3d ms = Eigen::Vector3d::Zero(), md = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    if (!(w > 0) || !src[i].allFinite() || !dst[i].allFinite()) return std::nullopt;
    wsum += w;
    ms += w * src[i];
    md += w * dst[i];
  }
  ms /= wsum;
  md /= wsum;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double var_src = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    const Eigen::Vector3d a = src[i] - ms, b = dst[i] - md;
    cov += w * b * a.transpose();
    var_src += w * a.squaredNorm();
  }
  if (!(var_src / wsum > 1e-12)) return std::nullopt;  // all source points coincide
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  // Rank < 2 (collinear points): the rotation about the line is undetermined.
  if (!(sv(1) > 1e-12 * std::max(1.0, sv(0)))) return std::nullopt;
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) S(2, 2) = -1;
  const Eigen::Matrix3d R = svd.matrixU() * S * svd.matrixV().transpose();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = md - R * ms;
  if (!T.matrix().allFinite()) return std::nullopt;
  return T;
}

bool RansacOptions::is_valid(std::string* error) const {
  if (!(inlier_threshold_m > 0) || !(accept_inlier_ratio > 0 && accept_inlier_ratio <= 1) ||
      thesis_sample_size < 3 || thesis_max_attempts < 1 || max_iterations < 1 ||
      min_iterations < 0 || !(confidence > 0 && confidence < 1) || refit_rounds < 0 ||
      min_pairs < 3 || reprojection_iterations < 0 || !(reprojection_huber_px > 0)) {
    if (error) *error = "ransac: options out of range";
    return false;
  }
  return true;
}

namespace {

struct Scored {
  std::vector<int> inliers;
  double sq_error_sum = 0;
};

Scored score(const Eigen::Isometry3d& T, const std::vector<Eigen::Vector3d>& src,
             const std::vector<Eigen::Vector3d>& dst, double threshold_m) {
  Scored s;
  const double t2 = threshold_m * threshold_m;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const double e2 = (T * src[i] - dst[i]).squaredNorm();
    if (e2 <= t2) {
      s.inliers.push_back(static_cast<int>(i));
      s.sq_error_sum += e2;
    }
  }
  return s;
}

bool better(const Scored& a, const Scored& b) {
  if (a.inliers.size() != b.inliers.size()) return a.inliers.size() > b.inliers.size();
  return a.sq_error_sum < b.sq_error_sum;
}

std::optional<Eigen::Isometry3d> fit_subset(const std::vector<int>& idx,
                                            const std::vector<Eigen::Vector3d>& src,
                                            const std::vector<Eigen::Vector3d>& dst,
                                            const std::vector<double>* weights = nullptr) {
  std::vector<Eigen::Vector3d> a, b;
  std::vector<double> w;
  a.reserve(idx.size());
  b.reserve(idx.size());
  for (int i : idx) {
    a.push_back(src[i]);
    b.push_back(dst[i]);
    if (weights) w.push_back((*weights)[i]);
  }
  return umeyama_rigid(a, b, w);
}

}  // namespace

namespace {

/// The best hypothesis so far and how many were tried.
struct Hypotheses {
  Eigen::Isometry3d best_T = Eigen::Isometry3d::Identity();
  Scored best;
  bool have = false;
  int iterations = 0;

  void consider(const std::vector<int>& sample, const std::vector<Eigen::Vector3d>& src,
                const std::vector<Eigen::Vector3d>& dst, double threshold_m) {
    ++iterations;
    auto T = fit_subset(sample, src, dst);
    if (!T) return;
    Scored s = score(*T, src, dst, threshold_m);
    if (!have || better(s, best)) {
      best = std::move(s);
      best_T = *T;
      have = true;
    }
  }
};

/// The thesis' sampling: consecutive blocks of `thesis_sample_size` pairs in `order` (best matches
/// first), until one reaches the acceptance ratio.
void sample_thesis(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                   const std::vector<int>& order, const RansacOptions& o, Hypotheses* h) {
  const std::size_t n = src.size();
  std::vector<int> ord = order;
  if (ord.size() != n) {
    ord.resize(n);
    std::iota(ord.begin(), ord.end(), 0);
  }
  const std::size_t k = static_cast<std::size_t>(o.thesis_sample_size);
  for (int attempt = 0; attempt < o.thesis_max_attempts; ++attempt) {
    const std::size_t start = static_cast<std::size_t>(attempt) * k;
    if (start + k > n) break;
    h->consider(std::vector<int>(ord.begin() + start, ord.begin() + start + k), src, dst,
                o.inlier_threshold_m);
    if (h->have && h->best.inliers.size() >= o.accept_inlier_ratio * n) break;
  }
}

/// Random minimal samples of 3 pairs, the iteration count adapted to the inlier ratio found so
/// far (`confidence`), within [min_iterations, max_iterations].
void sample_random(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                   const RansacOptions& o, std::uint64_t seed, Hypotheses* h) {
  const std::size_t n = src.size();
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(n) - 1);
  int needed = o.max_iterations;
  for (int it = 0; it < needed && it < o.max_iterations; ++it) {
    int a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c) continue;
    h->consider({a, b, c}, src, dst, o.inlier_threshold_m);
    if (h->have && !h->best.inliers.empty()) {
      const double w = static_cast<double>(h->best.inliers.size()) / n;
      const double p_good = std::pow(w, 3);
      if (p_good >= 1.0 - 1e-12) {
        needed = o.min_iterations;
      } else {
        const double est = std::log(1.0 - o.confidence) / std::log(1.0 - p_good);
        needed = std::max(o.min_iterations,
                          static_cast<int>(std::min<double>(o.max_iterations, std::ceil(est))));
      }
    }
  }
}

/// Least-squares refit on all inliers, re-classifying until the inlier set stops changing; then,
/// when asked, a refit weighted by the Kinect's depth noise.
void refit_on_inliers(const std::vector<Eigen::Vector3d>& src,
                      const std::vector<Eigen::Vector3d>& dst, const RansacOptions& o,
                      Hypotheses* h) {
  for (int r = 0; r < o.refit_rounds; ++r) {
    auto T = fit_subset(h->best.inliers, src, dst);
    if (!T) break;
    Scored s = score(*T, src, dst, o.inlier_threshold_m);
    if (s.inliers.size() < 3) break;
    const bool same = s.inliers == h->best.inliers;
    h->best = std::move(s);
    h->best_T = *T;
    if (same) break;
  }
  if (!o.depth_weighted_refine) return;
  // Kinect depth sigma ~ z^2 (Khoshelham & Elberink 2012): weight each pair by 1/(z_src^2
  // z_dst^2).
  const std::size_t n = src.size();
  std::vector<double> w(n, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double zs = std::max(0.3, std::abs(src[i].z())), zd = std::max(0.3, std::abs(dst[i].z()));
    w[i] = 1.0 / (zs * zs * zd * zd);
  }
  if (auto T = fit_subset(h->best.inliers, src, dst, &w)) {
    Scored s = score(*T, src, dst, o.inlier_threshold_m);
    if (s.inliers.size() >= h->best.inliers.size()) {
      h->best = std::move(s);
      h->best_T = *T;
    }
  }
}

}  // namespace

std::optional<MotionEstimate> estimate_motion_ransac(const std::vector<Eigen::Vector3d>& src,
                                                     const std::vector<Eigen::Vector3d>& dst,
                                                     const std::vector<int>& order,
                                                     const RansacOptions& o, std::uint64_t seed,
                                                     std::string* why) {
  if (!o.is_valid(why)) return std::nullopt;
  const std::size_t n = src.size();
  if (dst.size() != n) {
    if (why) *why = "ransac: src and dst differ in size";
    return std::nullopt;
  }
  if (n < o.min_pairs) {
    if (why) *why = "ransac: too few pairs (" + std::to_string(n) + ")";
    return std::nullopt;
  }
  Hypotheses h;
  if (o.sampling == RansacSampling::kThesis)
    sample_thesis(src, dst, order, o, &h);
  else
    sample_random(src, dst, o, seed, &h);
  if (!h.have || h.best.inliers.size() < 3) {
    if (why) *why = "ransac: no non-degenerate sample with >= 3 inliers";
    return std::nullopt;
  }
  refit_on_inliers(src, dst, o, &h);
  Eigen::Isometry3d& best_T = h.best_T;
  Scored& best = h.best;
  if (o.reprojection_camera.fx_px > 0 && o.reprojection_iterations > 0) {
    const Eigen::Isometry3d T =
        refine_reprojection(best_T, src, dst, best.inliers, o.reprojection_camera,
                            o.reprojection_iterations, o.reprojection_huber_px);
    Scored s = score(T, src, dst, o.inlier_threshold_m);
    if (s.inliers.size() >= 3) {
      best = std::move(s);
      best_T = T;
    }
  }
  MotionEstimate m;
  m.T_dst_src = best_T;
  m.inliers = best.inliers;
  m.inlier_ratio = static_cast<double>(best.inliers.size()) / n;
  m.rms_error_m = std::sqrt(best.sq_error_sum / best.inliers.size());
  m.accepted = m.inlier_ratio >= o.accept_inlier_ratio;
  m.iterations = h.iterations;
  return m;
}

namespace {

Eigen::Vector2d project(const Eigen::Vector3d& p, const RansacOptions::Pinhole& c) {
  return {c.fx_px * p.x() / p.z() + c.cx_px, c.fy_px * p.y() / p.z() + c.cy_px};
}

// Residual of point q (camera coords, already transformed) against pixel uv, with dq/ddelta = J_q.
ReprojectionTerm make_term(const Eigen::Vector3d& q, const Eigen::Vector2d& uv,
                           const Eigen::Matrix<double, 3, 6>& J_q,
                           const RansacOptions::Pinhole& c) {
  constexpr double kMinDepthM = 0.1;  // points behind or at the camera give no information
  ReprojectionTerm t;
  if (q.z() < kMinDepthM) return t;
  const double iz = 1.0 / q.z();
  t.residual_px = {c.fx_px * q.x() * iz + c.cx_px - uv.x(),
                   c.fy_px * q.y() * iz + c.cy_px - uv.y()};
  Eigen::Matrix<double, 2, 3> Jp;
  Jp << c.fx_px * iz, 0, -c.fx_px * q.x() * iz * iz, 0, c.fy_px * iz, -c.fy_px * q.y() * iz * iz;
  t.jacobian = Jp * J_q;
  t.valid = true;
  return t;
}

// Adds one term to the Gauss-Newton system with a Huber weight; returns its robust cost.
double accumulate(const ReprojectionTerm& t, double huber_px, Eigen::Matrix<double, 6, 6>* H,
                  Eigen::Matrix<double, 6, 1>* g) {
  if (!t.valid) return 0.0;
  const double n = t.residual_px.norm();
  const double w = n <= huber_px ? 1.0 : huber_px / n;
  *H += w * t.jacobian.transpose() * t.jacobian;
  *g += w * t.jacobian.transpose() * t.residual_px;
  return n <= huber_px ? 0.5 * n * n : huber_px * (n - 0.5 * huber_px);
}

}  // namespace

ReprojectionTerm forward_reprojection_term(const Eigen::Isometry3d& T, const Eigen::Vector3d& s,
                                           const Eigen::Vector3d& d,
                                           const RansacOptions::Pinhole& c) {
  // q = exp(delta) T s  ->  dq/ddelta = [I, -[q]x]
  const Eigen::Vector3d q = T * s;
  Eigen::Matrix<double, 3, 6> J;
  J << Eigen::Matrix3d::Identity(), -skew(q);
  return make_term(q, project(d, c), J, c);
}

ReprojectionTerm backward_reprojection_term(const Eigen::Isometry3d& T, const Eigen::Vector3d& s,
                                            const Eigen::Vector3d& d,
                                            const RansacOptions::Pinhole& c) {
  // b = T^-1 exp(-delta) d  ->  db/ddelta = R^T [-I, [d]x]
  const Eigen::Matrix3d Rt = T.rotation().transpose();
  const Eigen::Vector3d b = T.inverse() * d;
  Eigen::Matrix<double, 3, 6> J;
  J << -Rt, Rt * skew(d);
  return make_term(b, project(s, c), J, c);
}

Eigen::Isometry3d refine_reprojection(const Eigen::Isometry3d& T0,
                                      const std::vector<Eigen::Vector3d>& src,
                                      const std::vector<Eigen::Vector3d>& dst,
                                      const std::vector<int>& pairs,
                                      const RansacOptions::Pinhole& c, int iterations,
                                      double huber_px) {
  if (pairs.size() < 3 || !(c.fx_px > 0) || !(c.fy_px > 0) || !(huber_px > 0)) return T0;
  auto cost_and_system = [&](const Eigen::Isometry3d& T, Eigen::Matrix<double, 6, 6>* H,
                             Eigen::Matrix<double, 6, 1>* g) {
    H->setZero();
    g->setZero();
    double cost = 0;
    for (int i : pairs) {
      const Eigen::Vector3d& s = src[static_cast<std::size_t>(i)];
      const Eigen::Vector3d& d = dst[static_cast<std::size_t>(i)];
      if (s.z() <= 0 || d.z() <= 0) continue;
      cost += accumulate(forward_reprojection_term(T, s, d, c), huber_px, H, g);
      cost += accumulate(backward_reprojection_term(T, s, d, c), huber_px, H, g);
    }
    return cost;
  };
  Eigen::Isometry3d T = T0;
  Eigen::Matrix<double, 6, 6> H;
  Eigen::Matrix<double, 6, 1> g;
  double cost = cost_and_system(T, &H, &g);
  for (int it = 0; it < iterations; ++it) {
    const Eigen::Matrix<double, 6, 1> delta = H.ldlt().solve(-g);
    if (!delta.allFinite()) break;
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    const double angle = delta.tail<3>().norm();
    if (angle > 1e-12)
      step.linear() = Eigen::AngleAxisd(angle, delta.tail<3>() / angle).toRotationMatrix();
    step.translation() = delta.head<3>();
    const Eigen::Isometry3d T_new = step * T;
    Eigen::Matrix<double, 6, 6> H_new;
    Eigen::Matrix<double, 6, 1> g_new;
    const double cost_new = cost_and_system(T_new, &H_new, &g_new);
    if (!(cost_new < cost)) break;
    T = T_new;
    cost = cost_new;
    H = H_new;
    g = g_new;
    if (delta.norm() < 1e-10) break;
  }
  return T;
}

}  // namespace rgbdquad::slam
