// A TCP client socket whose every operation has a deadline that fires: connect, write and read
// wait in poll() with the time left, on a non-blocking descriptor. (A blocking read does not
// honour SO_RCVTIMEO when it goes through asio: asio's synchronous read_some treats the EAGAIN
// that SO_RCVTIMEO produces as "not ready yet" and polls again without a timeout, so the SLAM
// link's 5 s reply timeout would never fire.)
//
// Owned and used by one thread; wake_up() may be called from any thread (it shuts the socket
// down so a wait in progress returns at once). Errors are returned as text for the log.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

namespace rgbdquad::quadcontrol {

class SlamLinkSocket {
 public:
  using Clock = std::chrono::steady_clock;

  SlamLinkSocket() = default;
  ~SlamLinkSocket() { close(); }
  SlamLinkSocket(const SlamLinkSocket&) = delete;
  SlamLinkSocket& operator=(const SlamLinkSocket&) = delete;

  /// Resolves host (IPv4/IPv6 or a name) and connects before `deadline`. TCP_NODELAY is set.
  bool connect(const std::string& host, std::uint16_t port, Clock::time_point deadline,
               std::string* error);
  /// Sends every byte before `deadline`.
  bool write_all(const std::uint8_t* data, std::size_t size, Clock::time_point deadline,
                 std::string* error);

  enum class ReadStatus { kData, kTimeout, kClosed, kError };
  /// Reads what is there (up to `capacity`), waiting until `deadline` for the first byte.
  /// kData: *n > 0 bytes; kTimeout: nothing before the deadline; kClosed: the peer closed (end of
  /// file); kError: *error says why.
  ReadStatus read_some(std::uint8_t* buffer, std::size_t capacity, Clock::time_point deadline,
                       std::size_t* n, std::string* error);

  void close();
  bool is_open() const { return fd_.load() >= 0; }
  /// Thread-safe: makes a wait in progress return (the socket reads as closed).
  void wake_up();

 private:
  /// poll() for `events` until the deadline; 1 ready, 0 timeout, -1 error (errno).
  int wait(short events, Clock::time_point deadline);

  std::atomic<int> fd_{-1};
};

}  // namespace rgbdquad::quadcontrol
