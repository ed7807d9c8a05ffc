// rgbd-stream-bench: `make bench` figures for the onboard streamer on real TUM frames.
//  1. codecs: encode/decode ms per frame and compression ratio of every depth codec (bit-exact
//     checked) and of JPEG RGB (with PSNR);
//  2. end to end: frames/s delivered through a 120 Mbps token-bucket link (ShapedProxy) by the
//     real StreamerPipeline -> StreamSender -> StreamReceiver, per encoding mode, with the added
//     latency (capture -> decoded at the receiver).
// Prints tables; asserts nothing (figures depend on the machine).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <thread>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/capture/tum_replay_source.h"
#include "rgbdquad/encodings/depth_codec.h"
#include "rgbdquad/encodings/jpeg_codec.h"
#include "rgbdquad/receiver/stream_receiver.h"
#include "rgbdquad/stream/payload_encoder.h"
#include "rgbdquad/stream/pipeline.h"
#include "shaped_proxy.h"

namespace {

using namespace rgbdquad;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

struct Frames {
  std::vector<capture::RgbFrame> rgb;
  std::vector<capture::DepthFrame> depth;
};

Frames load(const std::string& dir) {
  capture::ManualClock clock;
  capture::TumReplayOptions o;
  o.directory = dir;
  o.fps = -1;
  capture::TumReplaySource source(o, &clock);
  Frames f;
  while (auto frame = source.next()) {
    if (auto* r = std::get_if<capture::RgbFrame>(&*frame))
      f.rgb.push_back(std::move(*r));
    else
      f.depth.push_back(std::get<capture::DepthFrame>(std::move(*frame)));
  }
  return f;
}

void codec_table(const Frames& f) {
  std::printf("\n## Codecs on %zu depth + %zu RGB frames (one core of this machine)\n",
              f.depth.size(), f.rgb.size());
  std::printf(
      "| stream | codec | encode ms/frame | decode ms/frame | bytes/frame | ratio | check "
      "|\n|---|---|---|---|---|---|---|\n");
  const double raw_depth = 640.0 * 480 * 2;
  for (auto codec : {encodings::DepthCodec::kRaw, encodings::DepthCodec::kRvl,
                     encodings::DepthCodec::kZstdDelta, encodings::DepthCodec::kLz4Delta}) {
    double enc_ms = 0, dec_ms = 0, bytes = 0;
    bool exact = true;
    for (const auto& d : f.depth) {
      auto t = Clock::now();
      auto payload = encodings::encode_depth(codec, d.depth.data(), d.width, d.height, 1);
      enc_ms += ms_since(t);
      bytes += static_cast<double>(payload.size());
      t = Clock::now();
      auto back = encodings::decode_depth(codec, payload.data(), payload.size(), d.width, d.height,
                                          nullptr);
      dec_ms += ms_since(t);
      exact = exact && back && *back == d.depth;
    }
    const double n = static_cast<double>(f.depth.size());
    std::printf("| depth | %s | %.2f | %.2f | %.0f | %.2f | %s |\n", encodings::to_string(codec),
                enc_ms / n, dec_ms / n, bytes / n, raw_depth / (bytes / n),
                exact ? "bit-exact" : "MISMATCH");
  }
  for (int quality : {90, 75}) {
    encodings::JpegEncoder enc(quality);
    encodings::JpegDecoder dec;
    double enc_ms = 0, dec_ms = 0, bytes = 0, psnr = 0;
    for (const auto& r : f.rgb) {
      std::string error;
      auto t = Clock::now();
      auto jpeg = enc.encode(r.rgb.data(), r.width, r.height, &error);
      enc_ms += ms_since(t);
      bytes += static_cast<double>(jpeg->size());
      t = Clock::now();
      auto back = dec.decode(jpeg->data(), jpeg->size(), r.width, r.height, &error);
      dec_ms += ms_since(t);
      double se = 0;
      for (std::size_t i = 0; i < back->size(); ++i) {
        const double e = static_cast<double>((*back)[i]) - r.rgb[i];
        se += e * e;
      }
      psnr += 10 * std::log10(255.0 * 255.0 / (se / static_cast<double>(back->size())));
    }
    const double n = static_cast<double>(f.rgb.size());
    std::printf("| rgb | jpeg q%d | %.2f | %.2f | %.0f | %.2f | PSNR %.1f dB |\n", quality,
                enc_ms / n, dec_ms / n, bytes / n, 640.0 * 480 * 3 / (bytes / n), psnr / n);
  }
}

// Replays preloaded frames at `fps` (RGB and depth each), stamping capture time with the steady
// clock so latency can be measured end to end.
class PacedSource final : public capture::FrameSource {
 public:
  PacedSource(const Frames* f, double fps, capture::Clock* clock)
      : f_(f), period_us_(1e6 / fps), clock_(clock) {}
  std::optional<capture::SourceFrame> next() override {
    if (stopped_) return std::nullopt;
    if (!start_us_) start_us_ = clock_->now_us();
    const std::size_t k = i_++;
    clock_->sleep_until_us(*start_us_ + static_cast<std::int64_t>((k / 2) * period_us_));
    if (stopped_) return std::nullopt;
    const std::size_t idx = (k / 2) % std::min(f_->rgb.size(), f_->depth.size());
    if (k % 2 == 0) {
      capture::RgbFrame r = f_->rgb[idx];
      r.capture_timestamp_us = clock_->now_us();
      return capture::SourceFrame(std::move(r));
    }
    capture::DepthFrame d = f_->depth[idx];
    d.capture_timestamp_us = clock_->now_us();
    return capture::SourceFrame(std::move(d));
  }
  void stop() override { stopped_ = true; }
  std::string error() const override { return {}; }
  std::string describe() const override { return "paced"; }

 private:
  const Frames* f_;
  double period_us_;
  capture::Clock* clock_;
  std::optional<std::int64_t> start_us_;
  std::size_t i_ = 0;
  std::atomic<bool> stopped_{false};
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

void end_to_end(const Frames& f, double link_mbps, double fps, double seconds) {
  std::printf(
      "\n## End to end through a %.0f Mbps token-bucket link, source %.0f fps RGB + %.0f fps "
      "depth, %.0f s per mode\n",
      link_mbps, fps, fps, seconds);
  std::printf("(raw arithmetic: %.0f Mbps / (921600 + 614400 B) = %.1f fps)\n", link_mbps,
              link_mbps * 1e6 / 8 / (921600.0 + 614400.0));
  std::printf(
      "| depth | rgb | pair depth with rgb | credits | rgb fps | depth fps | pairs/s | link Mbps "
      "used | latency ms mean / p95 (capture -> decoded) | encode ms rgb / depth | decode ms rgb / "
      "depth |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  struct Mode {
    protocol::Encoding depth, rgb;
    bool pair;
    std::uint16_t credits;
  };
  using E = protocol::Encoding;
  const Mode modes[] = {{E::kRaw, E::kRaw, false, 2},
                        {E::kRaw, E::kRaw, true, 2},
                        {E::kRaw, E::kRaw, true, 1},
                        {E::kDepthRvl, E::kRaw, true, 2},
                        {E::kDepthZstdDelta, E::kRaw, true, 2},
                        {E::kDepthRvl, E::kRgbJpeg, true, 2},
                        {E::kDepthRvl, E::kRgbJpeg, true, 1},
                        {E::kDepthZstdDelta, E::kRgbJpeg, true, 2}};
  capture::SteadyClock clock;
  for (const auto& mode : modes) {
    const auto depth_enc = mode.depth;
    const auto rgb_enc = mode.rgb;
    // One random stream key for both ends (authenticated handshake, as on the craft).
    const protocol::StreamKey key = protocol::random_stream_nonce();
    receiver::ReceiverOptions ro;
    ro.key = key;
    ro.credits_in_flight = mode.credits;
    ro.bind_address = "127.0.0.1";
    ro.rgb_port = 0;
    ro.depth_port = 0;
    receiver::StreamReceiver rx(
        ro, [&] { return clock.now_us(); }, nullptr);
    bench::ShapedProxy proxy({rx.rgb_port(), rx.depth_port()}, link_mbps * 1e6);
    stream::StreamSenderOptions so;
    so.key = key;
    so.host = "127.0.0.1";
    const rgbdquad::camera::TumCamera& fr1 = rgbdquad::camera::kTumFr1;
    so.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, {}};
    so.depth_units_per_m = capture::kTumDepthUnitsPerM;
    if (mode.pair) {
      so.pair_hint = std::make_shared<stream::PairHint>();
      so.held_frames = 6;
    }
    so.kind = protocol::StreamKind::kRgb;
    so.port = proxy.port(0);
    so.encoding = rgb_enc;
    auto rgb_so = so;
    rgb_so.held_frames = 1;
    stream::StreamSender rgb(rgb_so, &clock, nullptr);
    so.kind = protocol::StreamKind::kDepth;
    so.port = proxy.port(1);
    so.encoding = depth_enc;
    stream::StreamSender depth(so, &clock, nullptr);
    while (!(rgb.connected() && depth.connected()))
      std::this_thread::sleep_for(std::chrono::milliseconds(5));

    PacedSource source(&f, fps, &clock);
    stream::StreamerPipeline pipeline(&source, {}, std::nullopt, &rgb, &depth);
    std::atomic<bool> stop{false};
    std::thread producer([&] { pipeline.run(stop, &clock, 0, nullptr); });
    // Warm up 1 s (connections, first frames), then measure.
    std::this_thread::sleep_for(std::chrono::seconds(1));
    const auto c0 = rx.counters();
    const auto s0 = pipeline.counters();
    const auto t0 = Clock::now();
    std::vector<double> latency_ms;
    std::uint64_t pair_id = rx.newest_pair() ? rx.newest_pair()->pair_id : 0;
    const std::uint64_t first_pair = pair_id;
    std::uint32_t last_depth_seq = UINT32_MAX;
    while (ms_since(t0) < seconds * 1000) {
      auto pair = rx.wait_for_pair(pair_id, 100);
      if (!pair) continue;
      pair_id = pair->pair_id;
      const auto& d = pair->depth->info;
      if (d.sequence != last_depth_seq) {
        latency_ms.push_back((d.receive_timestamp_us + d.decode_us - d.capture_timestamp_us) /
                             1000.0);
        last_depth_seq = d.sequence;
      }
    }
    const double elapsed = ms_since(t0) / 1000.0;
    const auto c1 = rx.counters();
    const auto s1 = pipeline.counters();
    stop = true;
    source.stop();
    producer.join();
    const double rgb_fps = static_cast<double>(c1.rgb.frames - c0.rgb.frames) / elapsed;
    const double depth_fps = static_cast<double>(c1.depth.frames - c0.depth.frames) / elapsed;
    const double mbps = static_cast<double>((c1.rgb.wire_bytes - c0.rgb.wire_bytes) +
                                            (c1.depth.wire_bytes - c0.depth.wire_bytes)) *
                        8 / 1e6 / elapsed;
    auto per = [](std::int64_t us, std::uint64_t n) {
      return n ? static_cast<double>(us) / 1000.0 / static_cast<double>(n) : 0.0;
    };
    const double mean = latency_ms.empty()
                            ? 0
                            : std::accumulate(latency_ms.begin(), latency_ms.end(), 0.0) /
                                  static_cast<double>(latency_ms.size());
    std::printf(
        "| %s | %s | %s | %u | %.1f | %.1f | %.1f | %.1f | %.1f / %.1f | %.2f / %.2f | %.2f / %.2f "
        "|\n",
        stream::encoding_name(depth_enc).c_str(), stream::encoding_name(rgb_enc).c_str(),
        mode.pair ? "yes" : "no", static_cast<unsigned>(mode.credits), rgb_fps, depth_fps,
        static_cast<double>(pair_id - first_pair) / elapsed, mbps, mean,
        percentile(latency_ms, 0.95),
        per(s1.rgb.encode_us_total - s0.rgb.encode_us_total, s1.rgb.sent - s0.rgb.sent),
        per(s1.depth.encode_us_total - s0.depth.encode_us_total, s1.depth.sent - s0.depth.sent),
        per(c1.rgb.decode_us_total - c0.rgb.decode_us_total, c1.rgb.frames - c0.rgb.frames),
        per(c1.depth.decode_us_total - c0.depth.decode_us_total,
            c1.depth.frames - c0.depth.frames));
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rgbd-stream-bench: codec and end-to-end streaming figures on a TUM RGB-D folder"};
  std::string data;
  double link_mbps = 120, fps = 30, seconds = 8;
  std::size_t codec_frames = 100;
  bool skip_e2e = false;
  app.add_option("--data", data, "TUM RGB-D folder (rgb.txt, depth.txt)")->required();
  app.add_option("--link-mbps", link_mbps,
                 "shaped link rate in Mbit/s (default 120: usable WiFi in the thesis)");
  app.add_option("--fps", fps, "source rate of each stream (default 30: Kinect v1)");
  app.add_option("--seconds", seconds, "measurement time per end-to-end mode (default 8)");
  app.add_option("--codec-frames", codec_frames, "frames used for the codec table (default 100)");
  app.add_flag("--codecs-only", skip_e2e, "skip the end-to-end runs");
  CLI11_PARSE(app, argc, argv);
  if (!(link_mbps > 0) || !(fps > 0) || !(seconds > 0)) {
    std::fprintf(stderr, "link-mbps, fps and seconds must be > 0\n");
    return 2;
  }
  try {
    const auto t = Clock::now();
    Frames f = load(data);
    std::printf("loaded %zu RGB + %zu depth frames from %s in %.1f s\n", f.rgb.size(),
                f.depth.size(), data.c_str(), ms_since(t) / 1000);
    Frames subset;
    for (std::size_t i = 0; i < std::min(codec_frames, f.depth.size()); ++i)
      subset.depth.push_back(f.depth[i]);
    for (std::size_t i = 0; i < std::min(codec_frames, f.rgb.size()); ++i)
      subset.rgb.push_back(f.rgb[i]);
    codec_table(subset);
    if (!skip_e2e) end_to_end(f, link_mbps, fps, seconds);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbd-stream-bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
