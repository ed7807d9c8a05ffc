// Token-bucket shaped loopback proxy.
#include "shaped_proxy.h"

#include <sys/socket.h>

#include <algorithm>
#include <chrono>

namespace rgbdquad::bench {
namespace {
std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
// Forwarding chunk: 16 KiB = 1.1 ms at 120 Mbps, fine-grained enough that both streams interleave.
constexpr std::size_t kChunkBytes = 16 * 1024;
constexpr int kPollMs = 100;
}  // namespace

TokenBucket::TokenBucket(double bytes_per_s, double burst_bytes)
    : bytes_per_s_(bytes_per_s),
      burst_bytes_(burst_bytes),
      tokens_(burst_bytes),
      last_us_(now_us()) {}

void TokenBucket::acquire(std::size_t bytes) {
  while (true) {
    double wait_s = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const std::int64_t t = now_us();
      tokens_ = std::min(burst_bytes_, tokens_ + (t - last_us_) * 1e-6 * bytes_per_s_);
      last_us_ = t;
      if (tokens_ >= static_cast<double>(bytes)) {
        tokens_ -= static_cast<double>(bytes);
        return;
      }
      wait_s = (static_cast<double>(bytes) - tokens_) / bytes_per_s_;
    }
    std::this_thread::sleep_for(
        std::chrono::microseconds(static_cast<std::int64_t>(wait_s * 1e6) + 1));
  }
}

ShapedProxy::ShapedProxy(const std::vector<std::uint16_t>& upstream_ports, double link_bits_per_s)
    // Burst 16 KiB: one chunk; a WiFi link has no credit to send faster than its rate.
    : bucket_(link_bits_per_s / 8.0, static_cast<double>(kChunkBytes)), upstream_(upstream_ports) {
  for (std::size_t i = 0; i < upstream_.size(); ++i) {
    listeners_.push_back(net::listen_tcp("127.0.0.1", 0));
    ports_.push_back(net::local_port(listeners_.back()));
  }
  for (std::size_t i = 0; i < upstream_.size(); ++i)
    threads_.emplace_back([this, i] { accept_loop(i); });
}

ShapedProxy::~ShapedProxy() {
  stop_.wake();
  // Accept loops spawn pumps; join until no thread is left.
  while (true) {
    std::vector<std::thread> joining;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      joining.swap(threads_);
    }
    if (joining.empty()) break;
    for (auto& t : joining) t.join();
  }
}

void ShapedProxy::accept_loop(std::size_t i) {
  while (net::wait_readable(listeners_[i].get(), stop_, -1) == net::IoStatus::kOk) {
    auto client = net::accept_tcp(listeners_[i], nullptr);
    if (!client) continue;
    std::string error;
    auto server = net::connect_tcp("127.0.0.1", upstream_[i], 1000, stop_, &error);
    if (!server) continue;
    std::lock_guard<std::mutex> lock(mutex_);
    sockets_.push_back(std::make_unique<net::UniqueFd>(std::move(*client)));
    net::UniqueFd* c = sockets_.back().get();
    sockets_.push_back(std::make_unique<net::UniqueFd>(std::move(*server)));
    net::UniqueFd* s = sockets_.back().get();
    threads_.emplace_back([this, c, s] { pump(c, s, true); });
    threads_.emplace_back([this, c, s] { pump(s, c, false); });
  }
}

void ShapedProxy::pump(net::UniqueFd* from, net::UniqueFd* to, bool shaped) {
  std::vector<std::uint8_t> buffer(kChunkBytes);
  while (true) {
    std::size_t got = 0;
    const net::IoStatus s =
        net::read_some(from->get(), buffer.data(), buffer.size(), &got, stop_, kPollMs);
    if (s == net::IoStatus::kTimeout) continue;
    if (s != net::IoStatus::kOk) break;
    if (shaped) bucket_.acquire(got);
    if (net::send_all(to->get(), buffer.data(), got, stop_, 2000) != net::IoStatus::kOk) break;
  }
  // Half-close both ways so the peer pump ends too; descriptors close with the proxy.
  shutdown(from->get(), SHUT_RDWR);
  shutdown(to->get(), SHUT_RDWR);
}

}  // namespace rgbdquad::bench
