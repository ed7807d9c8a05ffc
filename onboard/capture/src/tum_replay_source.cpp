// TUM RGB-D folder replay.
#include "rgbdquad/capture/tum_replay_source.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "rgbdquad/capture/png_file.h"

namespace rgbdquad::capture {
namespace {

struct IndexLine {
  std::int64_t timestamp_us;
  std::string file;
};

// Parses "timestamp filename" lines, skipping '#' comments. Throws on malformed lines.
std::vector<IndexLine> read_index(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("TUM replay: cannot open " + path);
  std::vector<IndexLine> lines;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double timestamp_s = 0;
    std::string file;
    if (!(fields >> timestamp_s >> file) || !std::isfinite(timestamp_s) || timestamp_s < 0) {
      throw std::runtime_error("TUM replay: " + path + ":" + std::to_string(number) +
                               ": expected 'timestamp filename'");
    }
    lines.push_back({static_cast<std::int64_t>(std::llround(timestamp_s * 1e6)), file});
  }
  return lines;
}

// Parses TUM accelerometer.txt ("timestamp ax ay az", m/s^2, '#' comments), sorted by time; an
// absent file is no readings. Throws on malformed lines, as the image lists.
std::vector<AccelReading> read_accelerometer(const std::string& path) {
  std::vector<AccelReading> out;
  std::ifstream in(path);
  if (!in) return out;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t = 0;
    AccelReading r;
    if (!(fields >> t >> r.f_mps2[0] >> r.f_mps2[1] >> r.f_mps2[2]) || !std::isfinite(t) || t < 0) {
      throw std::runtime_error("TUM replay: " + path + ":" + std::to_string(number) +
                               ": expected 'timestamp ax ay az'");
    }
    r.capture_timestamp_us = static_cast<std::int64_t>(std::llround(t * 1e6));
    out.push_back(r);
  }
  std::stable_sort(out.begin(), out.end(), [](const AccelReading& a, const AccelReading& b) {
    return a.capture_timestamp_us < b.capture_timestamp_us;
  });
  return out;
}

// The reading nearest t_us (however far: the ground station's gate judges staleness).
std::optional<AccelReading> nearest_reading(const std::vector<AccelReading>& sorted,
                                            std::int64_t t_us) {
  if (sorted.empty()) return std::nullopt;
  auto it = std::lower_bound(
      sorted.begin(), sorted.end(), t_us,
      [](const AccelReading& r, std::int64_t t) { return r.capture_timestamp_us < t; });
  if (it == sorted.end()) return sorted.back();
  if (it != sorted.begin() &&
      t_us - std::prev(it)->capture_timestamp_us <= it->capture_timestamp_us - t_us)
    return *std::prev(it);
  return *it;
}

}  // namespace

bool TumReplayOptions::is_valid(std::string* error) const {
  if (directory.empty()) {
    *error = "tum.directory is empty";
    return false;
  }
  if (!std::isfinite(fps) || fps > 1000.0) {
    *error = "tum.fps must be finite and <= 1000 (0 = original timing, < 0 = unpaced)";
    return false;
  }
  return true;
}

TumReplaySource::TumReplaySource(const TumReplayOptions& options, Clock* clock)
    : options_(options), clock_(clock) {
  std::string why;
  if (!options_.is_valid(&why)) throw std::runtime_error("TUM replay: " + why);
  const auto rgb = read_index(options_.directory + "/rgb.txt");
  const auto depth = read_index(options_.directory + "/depth.txt");
  if (rgb.empty() || depth.empty()) {
    throw std::runtime_error("TUM replay: " + options_.directory +
                             " lists no rgb or no depth frames");
  }
  const auto accel = read_accelerometer(options_.directory + "/accelerometer.txt");
  accel_count_ = accel.size();
  for (const auto& l : rgb)
    entries_.push_back({l.timestamp_us, false, options_.directory + "/" + l.file,
                        nearest_reading(accel, l.timestamp_us)});
  for (const auto& l : depth)
    entries_.push_back({l.timestamp_us, true, options_.directory + "/" + l.file, std::nullopt});
  std::stable_sort(entries_.begin(), entries_.end(),
                   [](const Entry& a, const Entry& b) { return a.timestamp_us < b.timestamp_us; });
  const double rgb_period_us =
      rgb.size() > 1 ? static_cast<double>(rgb.back().timestamp_us - rgb.front().timestamp_us) /
                           static_cast<double>(rgb.size() - 1)
                     : 1e6 / 30.0;
  span_us_ = entries_.back().timestamp_us - entries_.front().timestamp_us +
             static_cast<std::int64_t>(rgb_period_us);
  if (options_.fps > 0) time_scale_ = (1e6 / options_.fps) / rgb_period_us;
  if (options_.preload) {
    for (const auto& e : entries_) {
      auto frame = load(e, e.timestamp_us);
      if (!frame) throw std::runtime_error("TUM replay: " + error_);
      preloaded_.push_back(std::move(*frame));
    }
  }
}

TumReplaySource::~TumReplaySource() = default;

std::size_t TumReplaySource::rgb_count() const {
  return static_cast<std::size_t>(
      std::count_if(entries_.begin(), entries_.end(), [](const Entry& e) { return !e.is_depth; }));
}
std::size_t TumReplaySource::depth_count() const { return entries_.size() - rgb_count(); }

std::string TumReplaySource::describe() const {
  std::string pacing = options_.fps == 0  ? "original timing"
                       : options_.fps < 0 ? "unpaced"
                                          : std::to_string(options_.fps) + " fps";
  return "tum:" + options_.directory + " (" + pacing + (options_.loop ? ", loop" : "") + ")";
}

std::optional<SourceFrame> TumReplaySource::load(const Entry& entry, std::int64_t timestamp_us) {
  if (entry.is_depth) {
    std::string why;
    auto png = read_png_gray16(entry.path, &why);
    if (!png) {
      error_ = "cannot read 16-bit depth PNG " + why;
      return std::nullopt;
    }
    DepthFrame f;
    f.capture_timestamp_us = timestamp_us;
    f.width = png->width;
    f.height = png->height;
    f.units_per_m = kTumDepthUnitsPerM;
    f.registered_to_rgb = true;  // the benchmark's depth is registered to the colour camera
    f.depth = std::move(png->pixels);
    return SourceFrame(std::move(f));
  }
  std::string why;
  auto png = read_png_rgb8(entry.path, &why);
  if (!png) {
    error_ = "cannot read RGB PNG " + why;
    return std::nullopt;
  }
  RgbFrame f;
  f.capture_timestamp_us = timestamp_us;
  f.width = png->width;
  f.height = png->height;
  f.rgb = std::move(png->pixels);
  return SourceFrame(std::move(f));
}

std::optional<SourceFrame> TumReplaySource::next() {
  if (stopped_) return std::nullopt;
  if (options_.max_frames != 0 && delivered_ >= options_.max_frames) return std::nullopt;
  if (cursor_ == entries_.size()) {
    if (!options_.loop) return std::nullopt;
    cursor_ = 0;
    loop_offset_us_ += span_us_;
  }
  const std::size_t index = cursor_++;
  const Entry& entry = entries_[index];
  const std::int64_t timestamp_us = entry.timestamp_us + loop_offset_us_;
  if (options_.fps >= 0) {
    if (!start_wall_us_) start_wall_us_ = clock_->now_us();
    const double offset_us =
        static_cast<double>(timestamp_us - entries_.front().timestamp_us) * time_scale_;
    clock_->sleep_until_us(*start_wall_us_ + static_cast<std::int64_t>(offset_us));
    if (stopped_) return std::nullopt;
  }
  ++delivered_;
  std::optional<SourceFrame> frame;
  if (!preloaded_.empty()) {
    frame = preloaded_[index];
    std::visit([&](auto& f) { f.capture_timestamp_us = timestamp_us; }, *frame);
  } else {
    frame = load(entry, timestamp_us);
  }
  // The reading keeps its offset from the image across loops, on the same shifted clock.
  if (auto* rgb = frame ? std::get_if<RgbFrame>(&*frame) : nullptr; rgb && entry.accel) {
    rgb->accel = entry.accel;
    rgb->accel->capture_timestamp_us += loop_offset_us_;
  }
  return frame;
}

}  // namespace rgbdquad::capture
