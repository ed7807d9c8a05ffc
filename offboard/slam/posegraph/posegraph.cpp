// Ceres pose graph; the residual follows Ceres' examples/slam/pose_graph_3d.
#include "slam/posegraph/posegraph.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace rgbdquad::slam {

namespace {

// Residual of an edge a->b with measurement (p_ab, q_ab):
//   q_ab_est = q_a^-1 q_b,  p_ab_est = q_a^-1 (p_b - p_a)
//   r = S * [ p_ab_est - p_ab ; 2 vec(q_ab q_ab_est^-1) ],  S = diag(sqrt information)
/// Gravity factor on a node's rotation q (of T_world_cam): the predicted down direction in the
/// camera is q^-1 d_w.
struct NodeGravityError {
  explicit NodeGravityError(const PoseGraphGravity& g) : g_(g) {}
  template <typename T>
  bool operator()(const T* q_xyzw, T* residual) const {
    const Eigen::Quaternion<T> q_cam_world =
        Eigen::Map<const Eigen::Quaternion<T>>(q_xyzw).conjugate();
    const Eigen::Matrix<T, 3, 1> d_c = q_cam_world * g_.down_world.cast<T>();
    gravity_residual(d_c.data(), g_.observation, residual);
    return true;
  }
  PoseGraphGravity g_;
};

struct RelativePoseError {
  RelativePoseError(const Eigen::Isometry3d& T_ab, const Eigen::Matrix<double, 6, 1>& sqrt_info)
      : p_ab(T_ab.translation()),
        q_ab(Eigen::Quaterniond(T_ab.rotation()).normalized()),
        sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* pa, const T* qa, const T* pb, const T* qb, T* res) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(pa), p_b(pb);
    Eigen::Map<const Eigen::Quaternion<T>> q_a(qa), q_b(qb);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab_est = q_a_inv * q_b;
    const Eigen::Matrix<T, 3, 1> p_ab_est = q_a_inv * (p_b - p_a);
    const Eigen::Quaternion<T> dq = q_ab.template cast<T>() * q_ab_est.conjugate();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(res);
    r.template head<3>() = p_ab_est - p_ab.template cast<T>();
    r.template tail<3>() = T(2.0) * dq.vec();
    for (int i = 0; i < 6; ++i) r(i) *= T(sqrt_info(i));
    return true;
  }

  Eigen::Vector3d p_ab;
  Eigen::Quaterniond q_ab;
  Eigen::Matrix<double, 6, 1> sqrt_info;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

}  // namespace

bool PoseGraphOptions::is_valid(std::string* error) const {
  if (!(loop_cauchy_scale > 0) || max_iterations < 1) {
    if (error) *error = "posegraph: options out of range";
    return false;
  }
  return true;
}

Eigen::Matrix<double, 6, 1> edge_sqrt_information(std::size_t inliers, double rms_m,
                                                  double depth_m) {
  constexpr double kMinSigmaM = 0.005;  // Kinect depth noise floor near 1 m is a few mm
  // Inlier errors are correlated (depth calibration, shared pose of the frame), so information
  // stops growing after ~25 independent-looking pairs: sigma_t >= 1 mm.
  constexpr std::size_t kMaxEffectiveInliers = 25;
  const double n = static_cast<double>(std::clamp<std::size_t>(inliers, 3, kMaxEffectiveInliers));
  const double sigma_t =
      std::max(std::isfinite(rms_m) ? rms_m : kMinSigmaM, kMinSigmaM) / std::sqrt(n);
  const double sigma_r = sigma_t / std::max(std::isfinite(depth_m) ? depth_m : 1.0, 0.5);
  Eigen::Matrix<double, 6, 1> s;
  s << 1 / sigma_t, 1 / sigma_t, 1 / sigma_t, 1 / sigma_r, 1 / sigma_r, 1 / sigma_r;
  return s;
}

void PoseGraph::add_node(std::int64_t id, const Eigen::Isometry3d& T) {
  nodes_[id] = Node{T.translation(), Eigen::Quaterniond(T.rotation()).normalized()};
  if (first_ < 0) first_ = id;
}

bool PoseGraph::add_edge(const PoseGraphEdge& e) {
  if (!has_node(e.from) || !has_node(e.to) || e.from == e.to || !e.T_from_to.matrix().allFinite() ||
      !e.sqrt_information.allFinite())
    return false;
  edges_.push_back(e);
  return true;
}

bool PoseGraph::add_gravity(const PoseGraphGravity& g) {
  if (!nodes_.count(g.node) || !g.down_world.allFinite() || !g.observation.down_cam.allFinite() ||
      !(g.observation.sigma_rad > 0))
    return false;
  gravity_.push_back(g);
  return true;
}

Eigen::Isometry3d PoseGraph::pose(std::int64_t id) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  auto it = nodes_.find(id);
  if (it == nodes_.end()) return T;
  T.linear() = it->second.q.toRotationMatrix();
  T.translation() = it->second.p;
  return T;
}

void PoseGraph::set_pose(std::int64_t id, const Eigen::Isometry3d& T) {
  auto it = nodes_.find(id);
  if (it == nodes_.end()) return;
  it->second = Node{T.translation(), Eigen::Quaterniond(T.rotation()).normalized()};
}

std::vector<std::int64_t> PoseGraph::node_ids() const {
  std::vector<std::int64_t> ids;
  for (const auto& kv : nodes_) ids.push_back(kv.first);
  return ids;
}

double PoseGraph::optimize(const PoseGraphOptions& o, std::string* report) {
  if (!o.is_valid(report) || edges_.empty() || nodes_.size() < 2) return -1.0;
  ceres::Problem problem;
  ceres::Manifold* quat = new ceres::EigenQuaternionManifold;  // owned by the problem
  for (const auto& e : edges_) {
    Node& a = nodes_.at(e.from);
    Node& b = nodes_.at(e.to);
    auto* cost = new ceres::AutoDiffCostFunction<RelativePoseError, 6, 3, 4, 3, 4>(
        new RelativePoseError(e.T_from_to, e.sqrt_information));
    ceres::LossFunction* loss = e.loop ? new ceres::CauchyLoss(o.loop_cauchy_scale) : nullptr;
    problem.AddResidualBlock(cost, loss, a.p.data(), a.q.coeffs().data(), b.p.data(),
                             b.q.coeffs().data());
  }
  for (const PoseGraphGravity& g : gravity_) {
    Node& n = nodes_.at(g.node);
    if (problem.HasParameterBlock(n.q.coeffs().data()))
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<NodeGravityError, 3, 4>(new NodeGravityError(g)), nullptr,
          n.q.coeffs().data());
  }
  bool manifold_used = false;
  for (auto& kv : nodes_) {
    if (!problem.HasParameterBlock(kv.second.q.coeffs().data())) continue;
    problem.SetManifold(kv.second.q.coeffs().data(), quat);
    manifold_used = true;
  }
  if (!manifold_used) {
    delete quat;
    return -1.0;
  }
  Node& first = nodes_.at(first_);
  if (problem.HasParameterBlock(first.p.data())) {
    problem.SetParameterBlockConstant(first.p.data());
    problem.SetParameterBlockConstant(first.q.coeffs().data());
  }
  ceres::Solver::Options so;
  so.max_num_iterations = o.max_iterations;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  for (auto& kv : nodes_) kv.second.q.normalize();
  if (report) *report = summary.BriefReport();
  if (!summary.IsSolutionUsable()) return -1.0;
  return summary.final_cost;
}

std::string PoseGraph::to_g2o() const {
  std::ostringstream os;
  os << std::setprecision(10);
  for (const auto& kv : nodes_) {
    const Node& n = kv.second;
    os << "VERTEX_SE3:QUAT " << kv.first << ' ' << n.p.x() << ' ' << n.p.y() << ' ' << n.p.z()
       << ' ' << n.q.x() << ' ' << n.q.y() << ' ' << n.q.z() << ' ' << n.q.w() << '\n';
  }
  if (first_ >= 0) os << "FIX " << first_ << '\n';
  for (const auto& e : edges_) {
    const Eigen::Quaterniond q(e.T_from_to.rotation());
    const Eigen::Vector3d p = e.T_from_to.translation();
    os << "EDGE_SE3:QUAT " << e.from << ' ' << e.to << ' ' << p.x() << ' ' << p.y() << ' ' << p.z()
       << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w();
    for (int i = 0; i < 6; ++i)
      for (int j = i; j < 6; ++j)
        os << ' ' << (i == j ? e.sqrt_information(i) * e.sqrt_information(i) : 0.0);
    os << '\n';
  }
  return os.str();
}

}  // namespace rgbdquad::slam
