// A userspace stand-in for the WiFi link in `make bench`: a loopback TCP proxy per stream port
// whose streamer -> ground-station direction goes through ONE token bucket shared by all its
// connections (both streams share the radio), at link_bits_per_s. The reverse direction (frame
// requests, a few bytes) is not shaped.
//
// Thread safety: construct, then use; the proxy owns its threads and joins them on destruction.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "rgbdquad/net/socket.h"

namespace rgbdquad::bench {

// Token bucket on the steady clock: acquire(n) blocks until n bytes may pass.
class TokenBucket {
 public:
  TokenBucket(double bytes_per_s, double burst_bytes);
  void acquire(std::size_t bytes);

 private:
  std::mutex mutex_;
  double bytes_per_s_;
  double burst_bytes_;
  double tokens_;
  std::int64_t last_us_;
};

class ShapedProxy {
 public:
  // Listens on 127.0.0.1 (any free port per upstream) and forwards to 127.0.0.1:upstream_ports[i].
  ShapedProxy(const std::vector<std::uint16_t>& upstream_ports, double link_bits_per_s);
  ~ShapedProxy();
  std::uint16_t port(std::size_t i) const { return ports_[i]; }

 private:
  void accept_loop(std::size_t i);
  void pump(net::UniqueFd* from, net::UniqueFd* to, bool shaped);

  TokenBucket bucket_;
  net::Waker stop_;
  std::vector<std::uint16_t> upstream_;
  std::vector<net::UniqueFd> listeners_;
  std::vector<std::uint16_t> ports_;
  std::mutex mutex_;
  std::vector<std::thread> threads_;  // accept loops and pumps
  std::vector<std::unique_ptr<net::UniqueFd>> sockets_;
};

}  // namespace rgbdquad::bench
