// slam-server: the SLAM engine on the live SLAM link (protocol/spec/messages.json, link "slam").
// Listens on TCP (default 127.0.0.1:5700), one client (quad-control) at a time; per connection:
// SlamHello exchange, then one PoseUpdate per RgbdFrame. A new connection starts a new map.
// SIGINT/SIGTERM end it cleanly (signalfd; the current pipeline is finished and summarised).
// Wiring only: sockets + codec here, the logic is SlamLinkSession.
#include <cerrno>
#include <cstring>
#include <CLI/CLI.hpp>
#include <arpa/inet.h>
#include <csignal>
#include <iostream>
#include <netinet/in.h>
#include <poll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include "rgbdquad/protocol/codec.hpp"
#include "slam_link_session.hpp"

namespace {

namespace proto = rgbdquad::protocol;

bool write_all(int fd, const std::vector<std::uint8_t>& bytes) {
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      std::cerr << "slam-server: send failed: " << std::strerror(errno) << "\n";
      return false;
    }
    off += static_cast<std::size_t>(n);
  }
  return true;
}

// Serves one connection; returns false when a signal asked to stop.
bool serve(int conn, int sigfd, const slam::PipelineOptions& options) {
  slam::SlamLinkSession session(options, "slam-server");
  proto::StreamDecoder decoder;
  std::vector<std::uint8_t> buf(1 << 16);
  bool keep_running = true;
  for (;;) {
    pollfd fds[2] = {{conn, POLLIN, 0}, {sigfd, POLLIN, 0}};
    if (::poll(fds, 2, -1) < 0) continue;
    if (fds[1].revents & POLLIN) { keep_running = false; break; }
    const ssize_t n = ::recv(conn, buf.data(), buf.size(), 0);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    if (n < 0) std::cerr << "slam-server: receive failed: " << std::strerror(errno) << "\n";
    if (n <= 0) break;
    decoder.feed(buf.data(), static_cast<std::size_t>(n));
    bool close_now = false;
    for (;;) {
      proto::DecodeResult r = decoder.next();
      if (r.status == proto::DecodeStatus::kNeedMoreBytes) break;
      if (r.status == proto::DecodeStatus::kError) {
        std::cerr << "slam-server: dropped bytes: " << proto::to_string(r.error) << " " << r.detail << "\n";
        continue;
      }
      std::string err;
      bool fatal = false;
      for (const auto& reply : session.on_message(*r.message, &err, &fatal)) {
        const proto::EncodeResult e = proto::encode(reply);
        if (!e.ok() || !write_all(conn, e.bytes)) { close_now = true; break; }
      }
      if (!err.empty()) std::cerr << "slam-server: " << err << "\n";
      if (fatal) close_now = true;
      if (close_now) break;
      if (session.frames_processed() % 100 == 0 && session.frames_processed() > 0 &&
          std::holds_alternative<proto::RgbdFrame>(*r.message))
        std::cerr << "slam-server: " << session.frames_processed() << " frames\n";
    }
    if (close_now) break;
  }
  if (auto* p = session.pipeline()) {
    p->finish();
    const auto s = p->summary();
    std::cerr << "slam-server: connection closed after " << session.frames_processed() << " frames, "
              << s.keyframes << " keyframes, " << s.loop_closures << " loop closures\n";
  }
  return keep_running;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"slam-server: RGB-D SLAM on the SLAM link (SlamHello, RgbdFrame -> PoseUpdate)"};
  std::string bind = "127.0.0.1", features = "orb", backend = "glc";
  int port = 5700;
  app.add_option("--bind", bind, "IPv4 address to listen on")->capture_default_str();
  app.add_option("--port", port, "TCP port")->check(CLI::Range(1, 65535))->capture_default_str();
  app.add_option("--features", features, "sift | surf | orb")->check(CLI::IsMember({"sift", "surf", "orb"}))->capture_default_str();
  app.add_option("--backend", backend, "vo | llc | glc")->check(CLI::IsMember({"vo", "llc", "glc"}))->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  slam::PipelineOptions options;
  std::string err;
  if (!slam::parse_detector_kind(features, &options.frontend.features.kind, &err) ||
      !slam::parse_backend_kind(backend, &options.backend.kind, &err)) {
    std::cerr << "slam-server: " << err << "\n";
    return 2;
  }
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &mask, nullptr);
  const int sigfd = ::signalfd(-1, &mask, SFD_CLOEXEC);
  const int lfd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (sigfd < 0 || lfd < 0) {
    std::cerr << "slam-server: cannot create sockets\n";
    return 1;
  }
  const int one = 1;
  ::setsockopt(lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, bind.c_str(), &addr.sin_addr) != 1) {
    std::cerr << "slam-server: bad --bind address '" << bind << "'\n";
    return 2;
  }
  if (::bind(lfd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(lfd, 1) != 0) {
    std::cerr << "slam-server: cannot listen on " << bind << ":" << port << "\n";
    return 1;
  }
  std::cerr << "slam-server: listening on " << bind << ":" << port << " (features " << features
            << ", backend " << backend << ")\n";
  for (bool running = true; running;) {
    pollfd fds[2] = {{lfd, POLLIN, 0}, {sigfd, POLLIN, 0}};
    if (::poll(fds, 2, -1) < 0) continue;
    if (fds[1].revents & POLLIN) break;
    const int conn = ::accept4(lfd, nullptr, nullptr, SOCK_CLOEXEC);
    if (conn < 0) continue;
    std::cerr << "slam-server: client connected\n";
    running = serve(conn, sigfd, options);
    ::close(conn);
  }
  ::close(lfd);
  ::close(sigfd);
  std::cerr << "slam-server: stopped\n";
  return 0;
}
