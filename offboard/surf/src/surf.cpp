// The SURF cv::Feature2D: input checks, grey conversion, detection, orientation and
// descriptors (see rgbdquad/surf/surf.hpp and docs/surf.md).
#include "rgbdquad/surf/surf.hpp"

#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "descriptor.hpp"
#include "hessian.hpp"
#include "integral_image.hpp"

namespace rgbdquad::surf {
namespace {

/// Octaves beyond 8 would need filters of 9 * 2^8 = 2304 px, larger than any camera frame here.
constexpr int kMaxOctaves = 8;
/// More scales per octave than 8 give filters overlapping the next octave several times over.
constexpr int kMaxScalesPerOctave = 8;

class Surf final : public cv::Feature2D {
 public:
  explicit Surf(const SurfOptions& options) : options_(options) {}

  int descriptorSize() const override { return options_.extended ? 128 : 64; }
  int descriptorType() const override { return CV_32F; }
  int defaultNorm() const override { return cv::NORM_L2; }
  cv::String getDefaultName() const override { return "Feature2D.SLAM_SURF"; }
  bool empty() const override { return false; }

  void detectAndCompute(cv::InputArray image, cv::InputArray mask,
                        std::vector<cv::KeyPoint>& keypoints, cv::OutputArray descriptors,
                        bool use_provided_keypoints) override {
    const cv::Mat gray = to_gray(image);
    const bool want_descriptors = descriptors.needed();
    if (gray.empty()) {
      keypoints.clear();
      if (want_descriptors) descriptors.release();
      return;
    }
    const detail::IntegralImage integral(gray);
    if (!use_provided_keypoints) {
      keypoints = detail::detect_keypoints(
          integral, {options_.octaves, options_.scales_per_octave, options_.hessian_threshold});
      if (!mask.empty()) {
        const cv::Mat m = mask.getMat();
        CV_CheckTypeEQ(m.type(), CV_8UC1, "SURF: mask must be CV_8UC1");
        CV_CheckEQ(m.size(), gray.size(), "SURF: mask must have the image's size");
        cv::KeyPointsFilter::runByPixelsMask(keypoints, m);
      }
    } else {
      // Keypoints from elsewhere: drop what cannot be described (bad size or position).
      std::vector<cv::KeyPoint> usable;
      for (const auto& kp : keypoints) {
        if (std::isfinite(kp.pt.x) && std::isfinite(kp.pt.y) && std::isfinite(kp.size) &&
            kp.size > 0.f) {
          usable.push_back(kp);
        }
      }
      keypoints.swap(usable);
    }

    // Orientation (parallel; each keypoint is independent, so the result is deterministic).
    std::vector<char> keep(keypoints.size(), 1);
    cv::parallel_for_(cv::Range(0, static_cast<int>(keypoints.size())), [&](const cv::Range& r) {
      for (int i = r.start; i < r.end; ++i) {
        auto& kp = keypoints[static_cast<std::size_t>(i)];
        if (options_.upright) {
          kp.angle = 0.f;
          continue;
        }
        const float angle = detail::dominant_orientation_deg(integral, kp);
        if (angle < 0.f) {
          keep[static_cast<std::size_t>(i)] = 0;  // no gradient sample inside the image
        } else {
          kp.angle = angle;
        }
      }
    });
    std::vector<cv::KeyPoint> kept;
    kept.reserve(keypoints.size());
    for (std::size_t i = 0; i < keypoints.size(); ++i) {
      if (keep[i]) kept.push_back(keypoints[i]);
    }
    keypoints.swap(kept);

    if (!want_descriptors) return;
    descriptors.create(static_cast<int>(keypoints.size()), descriptorSize(), CV_32F);
    cv::Mat out = descriptors.getMat();
    cv::parallel_for_(cv::Range(0, static_cast<int>(keypoints.size())), [&](const cv::Range& r) {
      for (int i = r.start; i < r.end; ++i) {
        detail::compute_descriptor(integral, keypoints[static_cast<std::size_t>(i)],
                                   options_.extended, out.ptr<float>(i));
      }
    });
  }

 private:
  static cv::Mat to_gray(cv::InputArray image) {
    const cv::Mat img = image.getMat();
    if (img.empty()) return img;
    if (img.depth() != CV_8U) {
      CV_Error(cv::Error::StsUnsupportedFormat,
               "SURF: image must be 8-bit (CV_8UC1, CV_8UC3 BGR or CV_8UC4 BGRA), got " +
                   cv::typeToString(img.type()));
    }
    cv::Mat gray;
    switch (img.channels()) {
      case 1:
        return img;
      case 3:
        cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
        return gray;
      case 4:
        cv::cvtColor(img, gray, cv::COLOR_BGRA2GRAY);
        return gray;
      default:
        CV_Error(cv::Error::StsUnsupportedFormat,
                 "SURF: image must have 1, 3 or 4 channels, got " + cv::typeToString(img.type()));
    }
  }

  const SurfOptions options_;
};

}  // namespace

bool SurfOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (octaves < 1 || octaves > kMaxOctaves) {
    return fail("SurfOptions.octaves must be in [1, 8], got " + std::to_string(octaves));
  }
  if (scales_per_octave < 1 || scales_per_octave > kMaxScalesPerOctave) {
    return fail("SurfOptions.scales_per_octave must be in [1, 8], got " +
                std::to_string(scales_per_octave));
  }
  if (!std::isfinite(hessian_threshold) || hessian_threshold < 0.0) {
    return fail("SurfOptions.hessian_threshold must be finite and >= 0, got " +
                std::to_string(hessian_threshold));
  }
  return true;
}

std::ostream& operator<<(std::ostream& out, const SurfOptions& o) {
  return out << "SurfOptions{octaves=" << o.octaves << ", scales_per_octave=" << o.scales_per_octave
             << ", extended=" << (o.extended ? "true" : "false")
             << ", hessian_threshold=" << o.hessian_threshold
             << ", upright=" << (o.upright ? "true" : "false") << "}";
}

cv::Ptr<cv::Feature2D> create_surf(const SurfOptions& options) {
  std::string error;
  if (!options.is_valid(&error)) throw std::invalid_argument(error);
  return cv::makePtr<Surf>(options);
}

}  // namespace rgbdquad::surf
