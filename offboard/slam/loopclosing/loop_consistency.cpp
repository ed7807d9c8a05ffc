// Loop-candidate consistency checks; see loop_consistency.hpp.
#include "slam/loopclosing/loop_consistency.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <utility>

namespace rgbdquad::slam {

std::vector<std::size_t> CovisibilityConsistency::update(
    const std::vector<std::set<std::int64_t>>& candidate_groups) {
  std::vector<Group> next;
  std::vector<bool> continued(groups_.size(), false);
  std::vector<std::size_t> enough;
  for (std::size_t c = 0; c < candidate_groups.size(); ++c) {
    const std::set<std::int64_t>& group = candidate_groups[c];
    bool consistent_with_some = false, counted = false;
    for (std::size_t g = 0; g < groups_.size(); ++g) {
      bool overlaps = false;
      for (std::int64_t kf : group)
        if (groups_[g].keyframes.count(kf)) {
          overlaps = true;
          break;
        }
      if (!overlaps) continue;
      consistent_with_some = true;
      const int consecutive = groups_[g].consecutive + 1;
      if (!continued[g]) {  // each previous chain is continued once
        next.push_back(Group{group, consecutive});
        continued[g] = true;
      }
      if (consecutive >= required_ && !counted) {
        enough.push_back(c);
        counted = true;
      }
    }
    if (!consistent_with_some) next.push_back(Group{group, 0});
  }
  groups_ = std::move(next);
  return enough;
}

int CovisibilityConsistency::longest_chain() const {
  int best = 0;
  for (const Group& g : groups_) best = std::max(best, g.consecutive);
  return best;
}

bool DriftModel::is_valid(std::string* error) const {
  const bool ok =
      std::isfinite(floor_sigma_m) && floor_sigma_m > 0 && std::isfinite(floor_sigma_rad) &&
      floor_sigma_rad > 0 && std::isfinite(translation_variance_m2_per_m) &&
      translation_variance_m2_per_m >= 0 && std::isfinite(rotation_variance_rad2_per_m) &&
      rotation_variance_rad2_per_m >= 0 && std::isfinite(chi2_bound) && chi2_bound > 0;
  if (!ok && error) *error = "drift model: sigmas and bound must be positive, rates >= 0";
  return ok;
}

OdometryConsistency check_odometry_consistency(const Eigen::Isometry3d& T_a_b_map,
                                               const Eigen::Isometry3d& T_a_b_loop, double path_m,
                                               const DriftModel& model) {
  OdometryConsistency out;
  out.path_m = std::max(0.0, path_m);
  // The disagreement expressed in camera b of the map: where the loop puts b, seen from where the
  // map has it.
  const Eigen::Isometry3d e = T_a_b_map.inverse() * T_a_b_loop;
  const Eigen::AngleAxisd aa(e.rotation());
  out.translation_m = e.translation().norm();
  out.rotation_deg = std::abs(aa.angle()) * 180.0 / M_PI;
  const double var_t =
      model.floor_sigma_m * model.floor_sigma_m + model.translation_variance_m2_per_m * out.path_m;
  const double var_r = model.floor_sigma_rad * model.floor_sigma_rad +
                       model.rotation_variance_rad2_per_m * out.path_m;
  const double angle = std::abs(aa.angle());
  out.chi2 = e.translation().squaredNorm() / var_t + angle * angle / var_r;
  out.consistent = std::isfinite(out.chi2) && out.chi2 <= model.chi2_bound;
  return out;
}

void KeyframeGraph::add_edge(std::int64_t a, std::int64_t b) {
  if (a == b) return;
  neighbours[a].push_back(b);
  neighbours[b].push_back(a);
}

std::optional<double> map_path_length_m(const KeyframeGraph& graph, std::int64_t a,
                                        std::int64_t b) {
  if (!graph.position_m.count(a) || !graph.position_m.count(b)) return std::nullopt;
  std::map<std::int64_t, double> dist{{a, 0.0}};
  using Item = std::pair<double, std::int64_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> open;
  open.push({0.0, a});
  while (!open.empty()) {
    const auto [d, k] = open.top();
    open.pop();
    if (k == b) return d;
    if (d > dist[k]) continue;
    const auto it = graph.neighbours.find(k);
    if (it == graph.neighbours.end()) continue;
    const Eigen::Vector3d& pk = graph.position_m.at(k);
    for (std::int64_t n : it->second) {
      const auto pn = graph.position_m.find(n);
      if (pn == graph.position_m.end()) continue;
      const double dn = d + (pn->second - pk).norm();
      const auto known = dist.find(n);
      if (known == dist.end() || dn < known->second) {
        dist[n] = dn;
        open.push({dn, n});
      }
    }
  }
  return std::nullopt;
}

}  // namespace rgbdquad::slam
