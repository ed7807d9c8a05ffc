// TCP client socket with deadlines: see slam_link_socket.hpp.
#include "app/slam_link_socket.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rgbdquad::quadcontrol {

namespace {
std::string errno_text(const char* what) { return std::string(what) + ": " + std::strerror(errno); }
}  // namespace

int SlamLinkSocket::wait(short events, Clock::time_point deadline) {
  for (;;) {
    const int fd = fd_.load();
    if (fd < 0) {
      errno = EBADF;
      return -1;
    }
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return 0;
    pollfd p{fd, events, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1000 * 1000)));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return r;
    return 1;  // ready, or POLLERR/POLLHUP: the following call reports it
  }
}

bool SlamLinkSocket::connect(const std::string& host, std::uint16_t port,
                             Clock::time_point deadline, std::string* error) {
  close();
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const int gai = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &res);
  if (gai != 0) {
    *error = "cannot resolve '" + host + "': " + ::gai_strerror(gai);
    return false;
  }
  std::string last = "no address";
  for (addrinfo* a = res; a != nullptr; a = a->ai_next) {
    const int fd =
        ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
    if (fd < 0) {
      last = errno_text("socket");
      continue;
    }
    fd_ = fd;
    if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0 && errno != EINPROGRESS) {
      last = errno_text("connect");
      close();
      continue;
    }
    const int w = wait(POLLOUT, deadline);
    int so_error = 0;
    socklen_t len = sizeof so_error;
    if (w == 0) {
      last = "connect: no answer before the deadline";
    } else if (w < 0) {
      last = errno_text("connect");
    } else if (::getsockopt(fd, SOL_SOCKET, SO_ERROR, &so_error, &len) != 0 || so_error != 0) {
      last = std::string("connect: ") + std::strerror(so_error != 0 ? so_error : errno);
    } else {
      const int one = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      ::freeaddrinfo(res);
      return true;
    }
    close();
  }
  ::freeaddrinfo(res);
  *error = last;
  return false;
}

bool SlamLinkSocket::write_all(const std::uint8_t* data, std::size_t size,
                               Clock::time_point deadline, std::string* error) {
  std::size_t off = 0;
  while (off < size) {
    const int fd = fd_.load();
    if (fd < 0) {
      *error = "send: socket closed";
      return false;
    }
    const ssize_t n = ::send(fd, data + off, size - off, MSG_NOSIGNAL);
    if (n > 0) {
      off += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      const int w = wait(POLLOUT, deadline);
      if (w == 0) {
        *error = "send: peer took " + std::to_string(off) + " of " + std::to_string(size) +
                 " bytes before the deadline";
        return false;
      }
      if (w < 0) {
        *error = errno_text("send");
        return false;
      }
      continue;
    }
    *error = errno_text("send");
    return false;
  }
  return true;
}

SlamLinkSocket::ReadStatus SlamLinkSocket::read_some(std::uint8_t* buffer, std::size_t capacity,
                                                     Clock::time_point deadline, std::size_t* n,
                                                     std::string* error) {
  *n = 0;
  for (;;) {
    const int fd = fd_.load();
    if (fd < 0) {
      *error = "receive: socket closed";
      return ReadStatus::kError;
    }
    const ssize_t r = ::recv(fd, buffer, capacity, 0);
    if (r > 0) {
      *n = static_cast<std::size_t>(r);
      return ReadStatus::kData;
    }
    if (r == 0) return ReadStatus::kClosed;
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      *error = errno_text("receive");
      return ReadStatus::kError;
    }
    const int w = wait(POLLIN, deadline);
    if (w == 0) return ReadStatus::kTimeout;
    if (w < 0) {
      *error = errno_text("receive");
      return ReadStatus::kError;
    }
  }
}

void SlamLinkSocket::close() {
  const int fd = fd_.exchange(-1);
  if (fd >= 0) ::close(fd);
}

void SlamLinkSocket::wake_up() {
  const int fd = fd_.load();
  if (fd >= 0) ::shutdown(fd, SHUT_RDWR);
}

}  // namespace rgbdquad::quadcontrol
