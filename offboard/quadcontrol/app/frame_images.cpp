// The dashboard's frame images: see frame_images.hpp.
#include "app/frame_images.hpp"

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <vector>

namespace rgbdquad::quadcontrol {

void FrameImages::invalidate_if_new_frame() {
  if (encoded_sequence_ == frame_->sequence) return;
  rgb_jpeg_.reset();
  depth_png_.reset();
  encoded_sequence_ = frame_->sequence;
}

std::optional<std::string> FrameImages::rgb_jpeg() {
  if (!frame_) return std::nullopt;
  invalidate_if_new_frame();
  if (!rgb_jpeg_) {
    std::vector<std::uint8_t> buf;
    if (!cv::imencode(".jpg", frame_->rgb, buf, {cv::IMWRITE_JPEG_QUALITY, kJpegQuality}))
      return std::nullopt;
    rgb_jpeg_ = std::string(buf.begin(), buf.end());
  }
  return rgb_jpeg_;
}

std::optional<std::string> FrameImages::depth_png() {
  if (!frame_) return std::nullopt;
  invalidate_if_new_frame();
  if (!depth_png_) {
    const cv::Mat& d = frame_->depth;
    cv::Mat grey(d.rows, d.cols, CV_8UC1);
    const double units_max = kDepthDisplayMaxM * frame_->intrinsics.depth_units_per_m;
    for (int v = 0; v < d.rows; ++v) {
      const auto* in = d.ptr<std::uint16_t>(v);
      auto* out = grey.ptr<std::uint8_t>(v);
      for (int u = 0; u < d.cols; ++u) {
        out[u] = in[u] == 0
                     ? 0
                     : static_cast<std::uint8_t>(255.0 - 235.0 * std::min(1.0, in[u] / units_max));
      }
    }
    std::vector<std::uint8_t> buf;
    if (!cv::imencode(".png", grey, buf)) return std::nullopt;
    depth_png_ = std::string(buf.begin(), buf.end());
  }
  return depth_png_;
}

}  // namespace rgbdquad::quadcontrol
