// surf-bench: speed and invariance of slam_surf (thesis parameters) next to OpenCV's SIFT on
// real TUM frames; prints a table (no assertions - the tests hold the bounds).
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <vector>

#include "../tests/invariance.hpp"
#include "../tests/rgbd_pair.hpp"
#include "rgbdquad/surf/surf.hpp"

namespace surf = rgbdquad::surf;

namespace {

constexpr const char* kUsage =
    "usage: surf-bench [--repeats N] [--sequence DIR] IMAGE...\n"
    "\n"
    "For each IMAGE (8-bit, e.g. a 640x480 TUM rgb/*.png): milliseconds per detectAndCompute\n"
    "(median of N runs, default 5; wall and process-CPU time; SURF also detect() alone) and\n"
    "keypoint count for SURF (thesis parameters: 4 octaves,\n"
    "3 scales, 128-d, Hessian threshold 550) and OpenCV SIFT (default parameters); then, on the\n"
    "first IMAGE, match precision (ratio 0.8, within 3 px) and repeatability (3 px) under\n"
    "rotations of 30/90 deg and scalings of 0.7x/1.5x.\n"
    "--sequence DIR: also match frame 0 of a TUM RGB-D folder (rgb.txt, depth.txt,\n"
    "groundtruth.txt; Freiburg 1 camera) against frames 1, 5, 10, 29 (and 60, 120 when present)\n"
    "and report the fraction of ratio-test matches that the ground-truth motion and depth put\n"
    "within 10 px.\n";

/// Matching tolerance of the invariance table in pixels of the warped image.
constexpr double kTolPx = 3.0;
/// Lowe's ratio test threshold used throughout the project's matcher.
constexpr double kRatio = 0.8;

/// CPU time of the whole process (all threads): robust to other load on the machine, unlike
/// wall time; equals the work done when OpenCV runs single-threaded (OPENCV_FOR_THREADS_NUM=1).
double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double median_ms(cv::Feature2D& f, const cv::Mat& gray, int repeats, std::size_t* count,
                 bool describe = true, double* median_cpu_ms = nullptr) {
  std::vector<double> ms, cpu;
  for (int i = 0; i < repeats; ++i) {
    std::vector<cv::KeyPoint> kp;
    cv::Mat desc;
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = process_cpu_ms();
    if (describe) {
      f.detectAndCompute(gray, cv::noArray(), kp, desc);
    } else {
      f.detect(gray, kp);
    }
    const auto t1 = std::chrono::steady_clock::now();
    cpu.push_back(process_cpu_ms() - c0);
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    *count = kp.size();
  }
  std::sort(ms.begin(), ms.end());
  std::sort(cpu.begin(), cpu.end());
  if (median_cpu_ms != nullptr) *median_cpu_ms = cpu[cpu.size() / 2];
  return ms[ms.size() / 2];
}

/// What the command line asks for.
struct BenchOptions {
  int repeats = 5;                  ///< timed runs per image and detector (the median is shown)
  std::string sequence;             ///< TUM RGB-D folder for the pair table; empty: no pair table
  std::vector<std::string> images;  ///< the speed table's images; the first one is warped
};

/// The command line, or nullopt with `exit_code`: 0 after --help, 2 (usage printed) when
/// malformed.
std::optional<BenchOptions> parse_command_line(int argc, char** argv, int* exit_code) {
  auto refuse = [exit_code](const char* why) {
    std::cerr << "surf-bench: " << why << "\n\n" << kUsage;
    *exit_code = 2;
    return std::nullopt;
  };
  BenchOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      std::cout << kUsage;
      *exit_code = 0;
      return std::nullopt;
    }
    if (arg == "--repeats") {
      if (i + 1 >= argc || (options.repeats = std::atoi(argv[++i])) < 1)
        return refuse("--repeats needs a positive integer");
      continue;
    }
    if (arg == "--sequence") {
      if (i + 1 >= argc) return refuse("--sequence needs a folder");
      options.sequence = argv[++i];
      continue;
    }
    options.images.push_back(arg);
  }
  if (options.images.empty()) return refuse("no IMAGE given");
  return options;
}

/// Times SURF (with and without descriptors) and SIFT on each image, one row per image; the
/// images read go to `grays`. False (the image named on stderr) for an unreadable image.
bool print_speed_table(cv::Feature2D& surf, cv::Feature2D& sift, const BenchOptions& options,
                       std::vector<cv::Mat>* grays) {
  std::cout << std::fixed << std::setprecision(1);
  std::cout << "image | size | SURF ms (cpu ms) | SURF detect-only ms (cpu ms) | SURF kp | "
               "SIFT ms (cpu ms) | SIFT kp\n";
  for (const auto& path : options.images) {
    const cv::Mat gray = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (gray.empty()) {
      std::cerr << "surf-bench: cannot read image '" << path << "'\n";
      return false;
    }
    grays->push_back(gray);
    std::size_t n_surf = 0, n_sift = 0;
    double c_surf = 0, c_detect = 0, c_sift = 0;
    const int repeats = options.repeats;
    const double t_surf = median_ms(surf, gray, repeats, &n_surf, true, &c_surf);
    const double t_detect = median_ms(surf, gray, repeats, &n_surf, false, &c_detect);
    const double t_sift = median_ms(sift, gray, repeats, &n_sift, true, &c_sift);
    std::cout << std::filesystem::path(path).filename().string() << " | " << gray.cols << "x"
              << gray.rows << " | " << t_surf << " (" << c_surf << ") | " << t_detect << " ("
              << c_detect << ") | " << n_surf << " | " << t_sift << " (" << c_sift << ") | "
              << n_sift << "\n";
  }
  return true;
}

/// Match precision, match count and repeatability of both detectors under rotations and
/// scalings of `gray`, one row per transform.
void print_invariance_table(cv::Feature2D& surf, cv::Feature2D& sift, const cv::Mat& gray) {
  std::cout << "\ntransform | SURF precision | SURF matches | SURF repeat | SIFT precision | "
               "SIFT matches | SIFT repeat\n";
  std::cout << std::setprecision(3);
  const struct {
    const char* name;
    double angle_deg, scale;
  } transforms[] = {{"rot 30", 30, 1.0},
                    {"rot 90", 90, 1.0},
                    {"scale 0.7", 0, 0.7},
                    {"scale 1.5", 0, 1.5},
                    {"rot 30 + scale 1.5", 30, 1.5}};
  for (const auto& t : transforms) {
    const auto a =
        surf::testing::evaluate_invariance(surf, gray, t.angle_deg, t.scale, kRatio, kTolPx);
    const auto b =
        surf::testing::evaluate_invariance(sift, gray, t.angle_deg, t.scale, kRatio, kTolPx);
    std::cout << t.name << " | " << a.match_precision << " | " << a.matches << " | "
              << a.repeatability << " | " << b.match_precision << " | " << b.matches << " | "
              << b.repeatability << "\n";
  }
}

/// Frame 0 of the TUM folder `sequence` matched against later frames by both detectors, scored
/// with the ground-truth motion and depth, one row per pair. False (said on stderr) when the
/// folder has fewer than two usable frames.
bool print_sequence_table(cv::Feature2D& surf, cv::Feature2D& sift, const std::string& sequence) {
  /// Ground-truth reprojection tolerance: on fr1/xyz the motion PnP recovers from the matches
  /// and the motion-capture ground truth differ by ~8 mm / 0.25 deg after 0.3-1 s (hand-eye
  /// calibration and time sync), i.e. ~5 px at 1 m, so even perfect matches scatter that much.
  constexpr double kPairTolPx = 10.0;
  const auto frames = surf::testing::load_rgbd_sequence(sequence, 121);
  if (frames.size() < 2) {
    std::cerr << "surf-bench: no usable rgb+depth+groundtruth frames in '" << sequence << "'\n";
    return false;
  }
  std::cout << "\npair | SURF consistent/with-depth | SURF precision | SURF median px | "
               "SIFT consistent/with-depth | SIFT precision | SIFT median px\n";
  for (std::size_t k : {1, 5, 10, 29, 60, 120}) {
    if (k >= frames.size()) break;
    const auto a =
        surf::testing::evaluate_rgbd_pair(surf, frames[0], frames[k], kRatio, kPairTolPx);
    const auto b =
        surf::testing::evaluate_rgbd_pair(sift, frames[0], frames[k], kRatio, kPairTolPx);
    std::cout << "0-" << k << " (" << std::setprecision(2) << frames[k].stamp_s - frames[0].stamp_s
              << " s) | " << a.consistent << "/" << a.with_depth << " | " << std::setprecision(3)
              << a.precision << " | " << a.median_error_px << " | " << b.consistent << "/"
              << b.with_depth << " | " << b.precision << " | " << b.median_error_px << "\n";
  }
  return true;
}

/// The three tables in turn; the exit code (1: an image or the sequence could not be read).
int run_bench(const BenchOptions& options) {
  const surf::SurfOptions surf_options;
  std::cout << "SURF " << surf_options << ", cv threads " << cv::getNumThreads() << "\n";
  auto surf = surf::create_surf(surf_options);
  auto sift = cv::SIFT::create();
  std::vector<cv::Mat> grays;
  if (!print_speed_table(*surf, *sift, options, &grays)) return 1;
  print_invariance_table(*surf, *sift, grays[0]);
  if (!options.sequence.empty() && !print_sequence_table(*surf, *sift, options.sequence)) return 1;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int exit_code = 0;
  const std::optional<BenchOptions> options = parse_command_line(argc, argv, &exit_code);
  if (!options) return exit_code;
  return run_bench(*options);
}
