// Accelerometer gate: the checks in the order the header lists them, and the rotation into the
// colour camera's optical frame.
#include "slam/motion/accel_gate.hpp"

#include <Eigen/LU>
#include <cmath>
#include <numeric>

namespace rgbdquad::slam {

namespace {

/// Tolerance of the orthonormality check of R_cam_sensor: the rotations are written with at most
/// double rounding, so anything looser than 1e-9 is a typo, not rounding.
constexpr double kRotationTolerance = 1e-9;

Eigen::Matrix3d row_major(const std::array<double, 9>& r) {
  Eigen::Matrix3d m;
  m << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
  return m;
}

}  // namespace

const char* to_string(AccelVerdict v) {
  switch (v) {
    case AccelVerdict::kAccepted:
      return "accepted";
    case AccelVerdict::kMissing:
      return "missing";
    case AccelVerdict::kNonFinite:
      return "non_finite";
    case AccelVerdict::kStale:
      return "stale";
    case AccelVerdict::kSaturated:
      return "saturated";
    case AccelVerdict::kImplausible:
      return "implausible_magnitude";
  }
  return "unknown";
}

bool AccelGateOptions::is_valid(std::string* error) const {
  auto fail = [&](const char* why) {
    if (error) *error = std::string("accel gate: ") + why;
    return false;
  };
  if (!(std::isfinite(max_stamp_gap_s) && max_stamp_gap_s > 0))
    return fail("max_stamp_gap_s must be finite and > 0");
  if (!(std::isfinite(range_mps2) && range_mps2 > 0))
    return fail("range_mps2 must be finite and > 0");
  if (!(std::isfinite(min_magnitude_mps2) && std::isfinite(max_magnitude_mps2) &&
        min_magnitude_mps2 >= 0 && min_magnitude_mps2 < max_magnitude_mps2))
    return fail("need 0 <= min_magnitude_mps2 < max_magnitude_mps2, both finite");
  const Eigen::Matrix3d R = row_major(R_cam_sensor);
  if (!R.allFinite() ||
      !(R * R.transpose()).isApprox(Eigen::Matrix3d::Identity(), kRotationTolerance) ||
      std::abs(R.determinant() - 1.0) > kRotationTolerance)
    return fail("R_cam_sensor must be a rotation (orthonormal, determinant +1)");
  return true;
}

std::size_t AccelCounts::ignored() const {
  return std::accumulate(by_verdict.begin(), by_verdict.end(), std::size_t{0}) - accepted();
}

AccelGate::AccelGate(const AccelGateOptions& options) : options_(options) {
  if (!options_.is_valid(&options_error_)) options_ = AccelGateOptions{};
  R_cam_sensor_ = row_major(options_.R_cam_sensor);
}

AccelVerdict AccelGate::judge(double colour_stamp_s,
                              const std::optional<AccelSample>& sample) const {
  if (!sample) return AccelVerdict::kMissing;
  const Eigen::Vector3d& f = sample->f_sensor_mps2;
  if (!f.allFinite() || !std::isfinite(sample->stamp_s)) return AccelVerdict::kNonFinite;
  // A non-finite colour stamp cannot be compared with anything: the sample is as good as stale.
  if (!std::isfinite(colour_stamp_s) ||
      !(std::abs(sample->stamp_s - colour_stamp_s) <= options_.max_stamp_gap_s))
    return AccelVerdict::kStale;
  if (f.cwiseAbs().maxCoeff() >= options_.range_mps2) return AccelVerdict::kSaturated;
  const double magnitude = f.norm();
  if (magnitude < options_.min_magnitude_mps2 || magnitude > options_.max_magnitude_mps2)
    return AccelVerdict::kImplausible;
  return AccelVerdict::kAccepted;
}

AccelVerdict AccelGate::check(double colour_stamp_s, const std::optional<AccelSample>& sample) {
  const AccelVerdict v = judge(colour_stamp_s, sample);
  ++counts_.by_verdict[static_cast<std::size_t>(v)];
  return v;
}

AccelVerdict AccelGate::attach(double colour_stamp_s, const std::optional<AccelSample>& sample,
                               RgbdFrame* frame) {
  const AccelVerdict v = check(colour_stamp_s, sample);
  if (v == AccelVerdict::kAccepted) {
    frame->accel_cam_mps2 = to_camera(sample->f_sensor_mps2);
    frame->accel_stamp_s = sample->stamp_s;
  } else {
    frame->accel_cam_mps2.reset();
    frame->accel_stamp_s.reset();
  }
  return v;
}

Eigen::Vector3d AccelGate::to_camera(const Eigen::Vector3d& f_sensor_mps2) const {
  return R_cam_sensor_ * f_sensor_mps2;
}

}  // namespace rgbdquad::slam
