// TUM folder reader and rgb/depth association.
#include "slam/dataset/tum_dataset.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "rgbdquad/encodings/jpeg_codec.h"

namespace rgbdquad::slam {

namespace fs = std::filesystem;

bool TumDatasetOptions::is_valid(std::string* error) const {
  if (!(max_dt_s > 0) || rate_divisor < 1 || max_frames < 0) {
    if (error) *error = "dataset: need max_dt_s > 0, rate_divisor >= 1, max_frames >= 0";
    return false;
  }
  return true;
}

namespace {

/// Calls `parse(line)` for each line of a TUM text file that is not blank or a '#' comment; a
/// false return stops with "<path>:<line>: expected '<format>'". False also when unreadable.
template <typename Parse>
bool for_each_tum_line(const std::string& path, const char* format, std::string* error,
                       Parse parse) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = "cannot open '" + path + "'";
    return false;
  }
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (!parse(line)) {
      if (error)
        *error = path + ":" + std::to_string(line_no) + ": expected '" + std::string(format) + "'";
      return false;
    }
  }
  return true;
}

/// The sample of `sorted` (by .stamp_s) nearest stamp_s, the earlier on a tie; null when empty.
template <typename Sample>
const Sample* nearest_by_stamp(const std::vector<Sample>& sorted, double stamp_s) {
  if (sorted.empty()) return nullptr;
  auto it = std::lower_bound(sorted.begin(), sorted.end(), stamp_s,
                             [](const Sample& a, double t) { return a.stamp_s < t; });
  if (it == sorted.end()) return &sorted.back();
  if (it == sorted.begin()) return &*it;
  const auto prev = std::prev(it);
  return (stamp_s - prev->stamp_s) <= (it->stamp_s - stamp_s) ? &*prev : &*it;
}

/// The attitude sample within max_dt_s of stamp_s nearest to it, if any.
std::optional<Eigen::Quaterniond> attitude_at(const std::vector<AttitudeSample>& sorted,
                                              double stamp_s, double max_dt_s) {
  const AttitudeSample* best = nearest_by_stamp(sorted, stamp_s);
  if (!best || std::abs(best->stamp_s - stamp_s) > max_dt_s) return std::nullopt;
  return best->q_nav_cam;
}

bool is_jpeg(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg";
}

/// A JPEG colour image decoded as the ground station decodes the stream's (encodings::JpegDecoder:
/// TurboJPEG with its fast integer IDCT), to BGR: OpenCV's decoder (the accurate IDCT) gives other
/// pixels, so a replayed flight's frames would not be the ones its SLAM saw. Empty on failure or
/// when the image is not `size` (the depth image's).
cv::Mat read_jpeg_as_ground_station(const std::string& path, cv::Size size) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  if (bytes.empty()) return {};
  std::string err;
  std::optional<std::vector<std::uint8_t>> rgb;
  try {
    encodings::JpegDecoder decoder;
    rgb = decoder.decode(bytes.data(), bytes.size(), size.width, size.height, &err);
  } catch (const std::exception&) {  // TurboJPEG could not be initialised: reported as unreadable
    return {};
  }
  if (!rgb) return {};
  cv::Mat bgr;
  cv::cvtColor(cv::Mat(size, CV_8UC3, const_cast<std::uint8_t*>(rgb->data())), bgr,
               cv::COLOR_RGB2BGR);  // copies
  return bgr;
}

/// |q|^2 - 1 within which a quaternion counts as unit: a few ulps of rounding in its printing.
constexpr double kUnitQuaternionTolerance = 1e-12;

}  // namespace

bool read_tum_list(const std::string& path, std::vector<std::pair<double, std::string>>* out,
                   std::string* error) {
  out->clear();
  const bool ok =
      for_each_tum_line(path, "timestamp filename", error, [&](const std::string& line) {
        std::istringstream ls(line);
        double t = 0;
        std::string name;
        if (!(ls >> t >> name) || !std::isfinite(t)) return false;
        out->emplace_back(t, name);
        return true;
      });
  if (!ok) return false;
  std::sort(out->begin(), out->end());
  return true;
}

bool read_tum_accelerometer(const std::string& path, std::vector<AccelSample>* out,
                            std::string* error) {
  out->clear();
  const bool ok =
      for_each_tum_line(path, "timestamp ax ay az", error, [&](const std::string& line) {
        // strtod rather than operator>>: it reads "nan" and "inf", which the gate then counts.
        double v[4];
        const char* p = line.c_str();
        for (double& x : v) {
          char* end = nullptr;
          x = std::strtod(p, &end);
          if (end == p) return false;
          p = end;
        }
        if (std::string(p).find_first_not_of(" \t\r") != std::string::npos) return false;
        if (!std::isfinite(v[0])) return false;
        out->push_back({v[0], Eigen::Vector3d(v[1], v[2], v[3])});
        return true;
      });
  if (!ok) return false;
  std::stable_sort(out->begin(), out->end(), [](const AccelSample& a, const AccelSample& b) {
    return a.stamp_s < b.stamp_s;
  });
  return true;
}

bool read_attitude_file(const std::string& path, std::vector<AttitudeSample>* out,
                        std::string* error) {
  out->clear();
  const bool ok =
      for_each_tum_line(path, "timestamp qx qy qz qw", error, [&](const std::string& line) {
        std::istringstream ls(line);
        double t, x, y, z, w;
        if (!(ls >> t >> x >> y >> z >> w)) return false;
        std::string rest;
        if (ls >> rest) return false;
        const Eigen::Quaterniond q(w, x, y, z);
        if (!std::isfinite(t) || !q.coeffs().allFinite() || q.norm() < 1e-6) return false;
        // A quaternion written unit (a replayed flight's, printed to round-trip) is taken as is:
        // normalising it again moves its last bits off the flight's.
        out->push_back(
            {t, std::abs(q.squaredNorm() - 1.0) < kUnitQuaternionTolerance ? q : q.normalized()});
        return true;
      });
  if (!ok) return false;
  std::stable_sort(out->begin(), out->end(), [](const AttitudeSample& a, const AttitudeSample& b) {
    return a.stamp_s < b.stamp_s;
  });
  return true;
}

std::optional<AccelSample> nearest_accel_sample(const std::vector<AccelSample>& sorted,
                                                double stamp_s) {
  if (const AccelSample* best = nearest_by_stamp(sorted, stamp_s)) return *best;
  return std::nullopt;
}

std::optional<TumDataset> TumDataset::open(const std::string& folder, const TumDatasetOptions& o,
                                           std::string* error) {
  if (!o.is_valid(error)) return std::nullopt;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    if (error) *error = "dataset folder '" + folder + "' does not exist or is not a directory";
    return std::nullopt;
  }
  std::vector<std::pair<double, std::string>> rgb, depth;
  std::string err;
  if (!read_tum_list((fs::path(folder) / "rgb.txt").string(), &rgb, &err) ||
      !read_tum_list((fs::path(folder) / "depth.txt").string(), &depth, &err)) {
    if (error) *error = "dataset: " + err + " (a TUM folder needs rgb.txt and depth.txt)";
    return std::nullopt;
  }
  if (rgb.empty() || depth.empty()) {
    if (error) *error = "dataset: rgb.txt or depth.txt in '" + folder + "' lists no frames";
    return std::nullopt;
  }
  TumDataset ds;
  ds.folder_ = folder;
  ds.stamp_from_depth_ = o.stamp_from_depth;
  const fs::path gt = fs::path(folder) / "groundtruth.txt";
  if (fs::is_regular_file(gt, ec)) ds.groundtruth_path_ = gt.string();
  std::vector<AccelSample> accel;
  const fs::path acc = fs::path(folder) / "accelerometer.txt";
  if (fs::is_regular_file(acc, ec)) {
    if (!read_tum_accelerometer(acc.string(), &accel, &err)) {
      if (error) *error = "dataset: " + err;
      return std::nullopt;
    }
    ds.accelerometer_path_ = acc.string();
    ds.accel_sample_count_ = accel.size();
  }
  std::vector<AttitudeSample> attitude;
  const fs::path att = fs::path(folder) / "attitude.txt";
  if (fs::is_regular_file(att, ec)) {
    if (!read_attitude_file(att.string(), &attitude, &err)) {
      if (error) *error = "dataset: " + err;
      return std::nullopt;
    }
    ds.attitude_path_ = att.string();
  }
  std::vector<TumEntry> all;
  for (const auto& [t, name] : rgb) {
    auto it = std::lower_bound(depth.begin(), depth.end(), std::make_pair(t, std::string()));
    const std::pair<double, std::string>* best = nullptr;
    if (it != depth.end()) best = &*it;
    if (it != depth.begin()) {
      auto prev = std::prev(it);
      if (!best || std::abs(prev->first - t) < std::abs(best->first - t)) best = &*prev;
    }
    if (!best || std::abs(best->first - t) > o.max_dt_s) continue;
    all.push_back({t, (fs::path(folder) / name).string(), best->first,
                   (fs::path(folder) / best->second).string(), nearest_accel_sample(accel, t),
                   attitude_at(attitude, t, o.max_dt_s)});
  }
  if (all.empty()) {
    if (error)
      *error = "dataset: no colour frame has a depth frame within " +
               std::to_string(o.max_dt_s * 1000) + " ms";
    return std::nullopt;
  }
  for (std::size_t i = 0; i < all.size(); i += static_cast<std::size_t>(o.rate_divisor)) {
    ds.entries_.push_back(all[i]);
    if (all[i].q_nav_cam) ++ds.attitude_frames_;
    if (o.max_frames > 0 && ds.entries_.size() >= static_cast<std::size_t>(o.max_frames)) break;
  }
  if (ds.entries_.size() >= 2) {
    std::vector<double> dts;
    for (std::size_t i = 1; i < ds.entries_.size(); ++i)
      dts.push_back(ds.entries_[i].rgb_stamp_s - ds.entries_[i - 1].rgb_stamp_s);
    std::nth_element(dts.begin(), dts.begin() + dts.size() / 2, dts.end());
    ds.frame_period_s_ = dts[dts.size() / 2];
  }
  return ds;
}

std::optional<RgbdFrame> TumDataset::load(std::size_t i, std::string* error,
                                          AccelGate* gate) const {
  if (i >= entries_.size()) {
    if (error) *error = "dataset: frame index out of range";
    return std::nullopt;
  }
  const TumEntry& e = entries_[i];
  RgbdFrame f;
  f.index = static_cast<std::int64_t>(i);
  f.stamp_s = stamp_from_depth_ ? e.depth_stamp_s : e.rgb_stamp_s;
  if (!stamp_from_depth_) f.depth_stamp_s = e.depth_stamp_s;
  f.depth = cv::imread(e.depth_path, cv::IMREAD_ANYDEPTH);
  if (f.depth.empty() || f.depth.type() != CV_16UC1) {
    if (error) *error = "cannot read 16-bit depth image '" + e.depth_path + "'";
    return std::nullopt;
  }
  f.rgb = is_jpeg(e.rgb_path) ? read_jpeg_as_ground_station(e.rgb_path, f.depth.size())
                              : cv::imread(e.rgb_path, cv::IMREAD_COLOR);
  if (f.rgb.empty()) {
    if (error) *error = "cannot read colour image '" + e.rgb_path + "'";
    return std::nullopt;
  }
  if (f.depth.size() != f.rgb.size()) {
    if (error) *error = "colour and depth sizes differ for '" + e.rgb_path + "'";
    return std::nullopt;
  }
  f.q_nav_cam = e.q_nav_cam;
  // The sample nearest the colour stamp, whichever stamp the frame carries (stamp_from_depth).
  if (gate) gate->attach(e.rgb_stamp_s, e.accel, &f);
  return f;
}

}  // namespace rgbdquad::slam
