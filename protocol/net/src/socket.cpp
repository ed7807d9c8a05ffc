// POSIX TCP helpers with poll()-bounded waits.
#include "rgbdquad/net/socket.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace rgbdquad::net {
namespace {

void set_nonblocking(int fd) { fcntl(fd, F_SETFL, fcntl(fd, F_GETFL, 0) | O_NONBLOCK); }

void set_nodelay(int fd) {
  int one = 1;
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

// Waits for `events` on fd or readability of the waker.
IoStatus wait_for(int fd, short events, const Waker& waker, int timeout_ms) {
  pollfd fds[2] = {{fd, events, 0}, {waker.fd(), POLLIN, 0}};
  while (true) {
    const int n = poll(fds, 2, timeout_ms);
    if (n < 0) {
      if (errno == EINTR) continue;
      return IoStatus::kError;
    }
    if (n == 0) return IoStatus::kTimeout;
    if (fds[1].revents & POLLIN) return IoStatus::kWoken;
    if (fds[0].revents & (events | POLLHUP | POLLERR)) return IoStatus::kOk;
  }
}

}  // namespace

void UniqueFd::reset(int fd) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
}

Waker::Waker() : fd_(eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
  if (!fd_.valid()) throw std::runtime_error(std::string("eventfd: ") + std::strerror(errno));
}

void Waker::wake() {
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(fd_.get(), &one, sizeof one);
}

void Waker::clear() {
  std::uint64_t value = 0;
  [[maybe_unused]] const ssize_t n = ::read(fd_.get(), &value, sizeof value);
}

const char* to_string(IoStatus status) {
  switch (status) {
    case IoStatus::kOk:
      return "ok";
    case IoStatus::kTimeout:
      return "timeout";
    case IoStatus::kWoken:
      return "stopped";
    case IoStatus::kClosed:
      return "closed by peer";
    case IoStatus::kError:
      return "socket error";
  }
  return "unknown";
}

std::optional<UniqueFd> connect_tcp(const std::string& host, std::uint16_t port, int timeout_ms,
                                    const Waker& waker, std::string* error) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int rc = getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found);
  if (rc != 0) {
    *error = "resolve " + host + ": " + gai_strerror(rc);
    return std::nullopt;
  }
  std::optional<UniqueFd> result;
  for (addrinfo* a = found; a != nullptr && !result; a = a->ai_next) {
    UniqueFd fd(::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol));
    if (!fd.valid()) continue;
    set_nonblocking(fd.get());
    if (::connect(fd.get(), a->ai_addr, a->ai_addrlen) != 0 && errno != EINPROGRESS) {
      *error = std::string("connect: ") + std::strerror(errno);
      continue;
    }
    const IoStatus s = wait_for(fd.get(), POLLOUT, waker, timeout_ms);
    if (s != IoStatus::kOk) {
      *error = std::string("connect: ") + to_string(s);
      if (s == IoStatus::kWoken) break;
      continue;
    }
    int so_error = 0;
    socklen_t len = sizeof so_error;
    getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &so_error, &len);
    if (so_error != 0) {
      *error = std::string("connect: ") + std::strerror(so_error);
      continue;
    }
    set_nodelay(fd.get());
    result = std::move(fd);
  }
  freeaddrinfo(found);
  return result;
}

UniqueFd listen_tcp(const std::string& address, std::uint16_t port, int backlog) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICHOST;
  addrinfo* found = nullptr;
  const int rc = getaddrinfo(address.empty() ? nullptr : address.c_str(),
                             std::to_string(port).c_str(), &hints, &found);
  if (rc != 0) throw std::runtime_error("listen address " + address + ": " + gai_strerror(rc));
  std::string why = "no usable address";
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    UniqueFd fd(::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol));
    if (!fd.valid()) continue;
    int one = 1;
    setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (::bind(fd.get(), a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd.get(), backlog) == 0) {
      set_nonblocking(fd.get());
      freeaddrinfo(found);
      return fd;
    }
    why = std::strerror(errno);
  }
  freeaddrinfo(found);
  throw std::runtime_error("cannot listen on " + address + ":" + std::to_string(port) + ": " + why);
}

std::uint16_t local_port(const UniqueFd& fd) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  getsockname(fd.get(), reinterpret_cast<sockaddr*>(&addr), &len);
  if (addr.ss_family == AF_INET6) return ntohs(reinterpret_cast<sockaddr_in6*>(&addr)->sin6_port);
  return ntohs(reinterpret_cast<sockaddr_in*>(&addr)->sin_port);
}

IoStatus wait_readable(int fd, const Waker& waker, int timeout_ms) {
  return wait_for(fd, POLLIN, waker, timeout_ms);
}

std::optional<UniqueFd> accept_tcp(const UniqueFd& listener, std::string* peer) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  UniqueFd fd(::accept4(listener.get(), reinterpret_cast<sockaddr*>(&addr), &len,
                        SOCK_NONBLOCK | SOCK_CLOEXEC));
  if (!fd.valid()) return std::nullopt;
  set_nodelay(fd.get());
  char host[NI_MAXHOST] = "?";
  char service[NI_MAXSERV] = "?";
  getnameinfo(reinterpret_cast<sockaddr*>(&addr), len, host, sizeof host, service, sizeof service,
              NI_NUMERICHOST | NI_NUMERICSERV);
  if (peer) *peer = std::string(host) + ":" + service;
  return fd;
}

IoStatus send_all(int fd, const std::uint8_t* data, std::size_t size, const Waker& waker,
                  int stall_timeout_ms) {
  std::size_t sent = 0;
  while (sent < size) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      const IoStatus s = wait_for(fd, POLLOUT, waker, stall_timeout_ms);
      if (s != IoStatus::kOk) return s;
      continue;
    }
    return (errno == EPIPE || errno == ECONNRESET) ? IoStatus::kClosed : IoStatus::kError;
  }
  return IoStatus::kOk;
}

IoStatus read_some(int fd, std::uint8_t* buffer, std::size_t capacity, std::size_t* got,
                   const Waker& waker, int timeout_ms) {
  *got = 0;
  while (true) {
    const ssize_t n = ::recv(fd, buffer, capacity, 0);
    if (n > 0) {
      *got = static_cast<std::size_t>(n);
      return IoStatus::kOk;
    }
    if (n == 0) return IoStatus::kClosed;
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      return errno == ECONNRESET ? IoStatus::kClosed : IoStatus::kError;
    }
    const IoStatus s = wait_for(fd, POLLIN, waker, timeout_ms);
    if (s != IoStatus::kOk) return s;
  }
}

int Backoff::next_delay_ms() {
  const int delay = next_ms_;
  next_ms_ = std::min(max_ms_, next_ms_ * 2);
  return delay;
}

}  // namespace rgbdquad::net
