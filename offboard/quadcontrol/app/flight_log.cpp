// Flight recorder: see flight_log.hpp.
#include "app/flight_log.hpp"

#include <cerrno>
#include <cstdarg>
#include <cstring>
#include <filesystem>

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kSPerUs = 1e-6;

std::FILE* open_with_header(const std::filesystem::path& path, const char* header,
                            std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    *error = "flight log: cannot create " + path.string() + ": " + std::strerror(errno);
    return nullptr;
  }
  std::fputs(header, f);
  std::fflush(f);
  return f;
}
}  // namespace

std::unique_ptr<FlightLog> FlightLog::open(const std::string& dir, std::string* error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    *error = "flight log: cannot create " + dir + ": " + ec.message();
    return nullptr;
  }
  const std::filesystem::path d(dir);
  std::FILE* frames = open_with_header(d / "frames.csv",
                                       "sequence,capture_us,received_us,link_latency_ms\n", error);
  std::FILE* poses =
      frames ? open_with_header(
                   d / "poses.csv",
                   "sequence,capture_us,received_us,pose_us,tracking,x_m,y_m,z_m,yaw_deg\n", error)
             : nullptr;
  std::FILE* trajectory =
      poses ? open_with_header(
                  d / "trajectory.tum",
                  "# quad-control SLAM trajectory: T_floor_cam at the frame's capture time (s)\n"
                  "# timestamp tx ty tz qx qy qz qw\n",
                  error)
            : nullptr;
  std::FILE* commands = trajectory
                            ? open_with_header(d / "commands.csv",
                                               "seq,send_us,state,armed,roll_us,pitch_us,throttle_"
                                               "us,yaw_us,pose_capture_us,pose_us\n",
                                               error)
                            : nullptr;
  if (commands == nullptr) {
    for (std::FILE* f : {frames, poses, trajectory}) {
      if (f) std::fclose(f);
    }
    return nullptr;
  }
  return std::unique_ptr<FlightLog>(new FlightLog(dir, frames, poses, trajectory, commands));
}

FlightLog::FlightLog(std::string dir, std::FILE* frames, std::FILE* poses, std::FILE* trajectory,
                     std::FILE* commands)
    : dir_(std::move(dir)),
      frames_(frames),
      poses_(poses),
      trajectory_(trajectory),
      commands_(commands) {}

FlightLog::~FlightLog() {
  for (std::FILE* f : {frames_, poses_, trajectory_, commands_}) std::fclose(f);
}

void FlightLog::write(std::FILE* f, const char* fmt, ...) {
  // Caller holds mutex_.
  va_list args;
  va_start(args, fmt);
  const int n = std::vfprintf(f, fmt, args);
  va_end(args);
  if (n < 0 || std::fflush(f) != 0) ++write_errors_;
}

void FlightLog::frame(std::int64_t sequence, std::int64_t capture_us, std::int64_t received_us,
                      double link_latency_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  write(frames_, "%lld,%lld,%lld,%.3f\n", static_cast<long long>(sequence),
        static_cast<long long>(capture_us), static_cast<long long>(received_us), link_latency_ms);
}

void FlightLog::pose(const LoggedPose& p) {
  const Eigen::Vector3d t = p.T_floor_cam.translation();
  const Eigen::Quaterniond q(p.T_floor_cam.linear());
  std::lock_guard<std::mutex> lock(mutex_);
  write(poses_, "%lld,%lld,%lld,%lld,%d,%.5f,%.5f,%.5f,%.3f\n", static_cast<long long>(p.sequence),
        static_cast<long long>(p.capture_us), static_cast<long long>(p.received_us),
        static_cast<long long>(p.pose_us), p.tracking ? 1 : 0, t.x(), t.y(), t.z(), p.yaw_deg);
  if (p.tracking) {
    write(trajectory_, "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n",
          static_cast<double>(p.capture_us) * kSPerUs, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(),
          q.w());
  }
}

void FlightLog::command(const LoggedCommand& c) {
  std::lock_guard<std::mutex> lock(mutex_);
  write(commands_, "%u,%lld,%s,%d,%d,%d,%d,%d,%lld,%lld\n", c.seq,
        static_cast<long long>(c.send_us), c.state.c_str(), c.pwm.armed ? 1 : 0, c.pwm.roll_us,
        c.pwm.pitch_us, c.pwm.throttle_us, c.pwm.yaw_us, static_cast<long long>(c.pose_capture_us),
        static_cast<long long>(c.pose_us));
}

std::uint64_t FlightLog::write_errors() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return write_errors_;
}

}  // namespace rgbdquad::quadcontrol
