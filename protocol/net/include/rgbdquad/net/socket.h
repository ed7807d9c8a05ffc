// Small RAII layer over POSIX TCP sockets for the two RGB-D stream links (sender in onboard/,
// receiver in offboard/receiver). Every blocking call waits with poll() on the socket AND a
// Waker, so a stop request interrupts it at once; nothing blocks without a bound.
//
// Thread safety: UniqueFd is a plain owner (one thread). Waker::wake() may be called from any
// thread; the other members belong to the thread that waits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace rgbdquad::net {

// Owns one file descriptor; closes it on destruction.
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() { reset(); }
  UniqueFd(UniqueFd&& other) noexcept : fd_(other.release()) {}
  UniqueFd& operator=(UniqueFd&& other) noexcept {
    if (this != &other) reset(other.release());
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;

  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }
  void reset(int fd = -1);

 private:
  int fd_ = -1;
};

// An eventfd that interrupts waits: wake() makes it readable until clear().
class Waker {
 public:
  Waker();  // throws std::runtime_error if eventfd() fails (start-up)
  void wake();
  void clear();
  int fd() const { return fd_.get(); }

 private:
  UniqueFd fd_;
};

enum class IoStatus { kOk, kTimeout, kWoken, kClosed, kError };
const char* to_string(IoStatus status);

// Connects to host:port (numeric IPv4/IPv6 or a name) within timeout_ms. TCP_NODELAY is set:
// a frame request must not sit in Nagle's buffer.
std::optional<UniqueFd> connect_tcp(const std::string& host, std::uint16_t port, int timeout_ms,
                                    const Waker& waker, std::string* error);

// Listens on address:port (port 0 = any free port; SO_REUSEADDR so a restarted receiver can
// bind again at once). Throws std::runtime_error (start-up boundary) on failure.
UniqueFd listen_tcp(const std::string& address, std::uint16_t port, int backlog = 4);
std::uint16_t local_port(const UniqueFd& fd);

// Waits until fd is readable (or the waker fires / timeout). timeout_ms < 0 = no timeout.
IoStatus wait_readable(int fd, const Waker& waker, int timeout_ms);
// Accepts one connection when the listening socket is readable.
std::optional<UniqueFd> accept_tcp(const UniqueFd& listener, std::string* peer);

// Sends every byte; gives up after timeout_ms without progress (a dead or stalled peer).
IoStatus send_all(int fd, const std::uint8_t* data, std::size_t size, const Waker& waker,
                  int stall_timeout_ms);
// Reads what is available (at least 1 byte) after waiting up to timeout_ms.
IoStatus read_some(int fd, std::uint8_t* buffer, std::size_t capacity, std::size_t* got,
                   const Waker& waker, int timeout_ms);

// Capped exponential backoff for reconnect attempts: first_ms, 2x per failure, at most max_ms.
// Pure: the caller sleeps. reset() after a successful connection.
class Backoff {
 public:
  Backoff(int first_ms, int max_ms) : first_ms_(first_ms), max_ms_(max_ms), next_ms_(first_ms) {}
  int next_delay_ms();
  void reset() { next_ms_ = first_ms_; }

 private:
  int first_ms_;
  int max_ms_;
  int next_ms_;
};

}  // namespace rgbdquad::net
