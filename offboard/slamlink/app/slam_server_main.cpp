// slam-server: the SLAM engine on the live SLAM link (protocol/spec/messages.json, link "slam").
// Listens on TCP (default 127.0.0.1:5700) and serves up to --max-clients connections from one
// poll loop (no client can hold another up for longer than one frame's SLAM). Per connection:
// SlamHello exchange naming a flight's map, then one PoseUpdate per RgbdFrame. A broken
// connection parks its map for --resume-grace-ms: the same client reconnecting with the same map
// id continues the same map and world frame. Every connection that ends logs why. SIGINT/SIGTERM
// end it cleanly (signalfd; every map is finished and summarised).
// Wiring only: sockets here; the logic is SlamConnection, SessionRegistry and SlamLinkSession.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>

#include "slam/core/thread_priority.hpp"
#include "slam/map/map_io.hpp"
#include "slam_connection.hpp"
#include "slam_sessions.hpp"

namespace slam = rgbdquad::slam;
namespace slamlink = rgbdquad::slamlink;

namespace {

// Bytes read from one connection per loop turn: a whole RAW 640x480 frame (1.5 MB) in a few
// turns without letting one client starve the others' timers.
constexpr std::size_t kMaxReadPerTurnBytes = 4u << 20;
constexpr std::size_t kReadChunkBytes = 1u << 16;
// When every slot is taken, a newcomer may replace the connection idle the longest if it has
// been idle this long (quad-control sends a frame at least every ~100 ms while it streams).
constexpr std::int64_t kEvictIdleMs = 2000;

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void log_line(const std::string& s) { std::cerr << "slam-server: " << s << std::endl; }

struct Client {
  int fd = -1;
  std::unique_ptr<slamlink::SlamConnection> conn;
  bool closing_after_flush = false;
  std::string close_cause;
};

class Server {
 public:
  Server(int listen_fd, int sig_fd, std::size_t max_clients, slamlink::ConnectionOptions copt,
         slamlink::SessionRegistry registry)
      : lfd_(listen_fd),
        sigfd_(sig_fd),
        max_clients_(max_clients),
        copt_(copt),
        registry_(std::move(registry)) {}

  void run() {
    for (;;) {
      std::vector<pollfd> fds = {{lfd_, POLLIN, 0}, {sigfd_, POLLIN, 0}};
      std::vector<int> ids;
      for (auto& [id, c] : clients_) {
        short ev = POLLIN;
        if (!c.conn->output().empty()) ev |= POLLOUT;
        fds.push_back({c.fd, ev, 0});
        ids.push_back(id);
      }
      const int timeout = poll_timeout_ms();
      if (::poll(fds.data(), fds.size(), timeout) < 0) {
        if (errno != EINTR) log_line(std::string("poll failed: ") + std::strerror(errno));
        continue;
      }
      if (fds[1].revents & POLLIN) break;
      const std::int64_t t = now_ms();
      for (std::size_t i = 0; i < ids.size(); ++i) {
        auto it = clients_.find(ids[i]);
        if (it == clients_.end()) continue;
        if (fds[2 + i].revents & (POLLIN | POLLHUP | POLLERR)) read_from(it->second, t);
      }
      if (fds[0].revents & POLLIN) accept_one(t);
      // Deadlines right after reading (before SLAM runs), so time spent on one client's frame is
      // never charged to another whose bytes are waiting in the kernel.
      for (auto& [id, c] : clients_)
        if (c.close_cause.empty())
          if (auto cause = c.conn->timed_out(t)) c.close_cause = *cause;
      for (auto& [id, c] : clients_) {
        if (!c.close_cause.empty()) continue;
        std::vector<int> displaced;
        std::vector<std::string> log;
        bool flush_first = false;
        auto cause = c.conn->process(registry_, now_ms(), &displaced, &log, &flush_first);
        for (const auto& l : log) log_line(l);
        for (int d : displaced) {
          auto dit = clients_.find(d);
          if (dit != clients_.end() && dit->second.close_cause.empty())
            dit->second.close_cause = "map taken over by client #" + std::to_string(id) +
                                      " (the same flight reconnected)";
        }
        if (cause) {
          c.close_cause = *cause;
          c.closing_after_flush = flush_first;
        }
      }
      for (auto& [id, c] : clients_) flush(c, now_ms());
      close_finished();
      for (const auto& l : registry_.expire(now_ms())) log_line(l);
    }
    for (auto& [id, c] : clients_) close_client(c, "slam-server stopping");
    clients_.clear();
    for (const auto& l : registry_.finish_all()) log_line(l);
  }

 private:
  int poll_timeout_ms() const {
    const std::int64_t t = now_ms();
    std::int64_t next = t + 1000;
    for (const auto& [id, c] : clients_) next = std::min(next, c.conn->next_deadline_ms());
    if (auto e = registry_.next_expiry_ms()) next = std::min(next, *e);
    return static_cast<int>(std::max<std::int64_t>(0, next - t));
  }

  void read_from(Client& c, std::int64_t t) {
    if (!c.close_cause.empty()) return;
    std::uint8_t buf[kReadChunkBytes];
    std::size_t total = 0;
    while (total < kMaxReadPerTurnBytes) {
      const ssize_t n = ::recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
      if (n > 0) {
        c.conn->on_bytes(buf, static_cast<std::size_t>(n), t);
        total += static_cast<std::size_t>(n);
        continue;
      }
      if (n == 0) {
        c.close_cause = "peer closed the connection (end of file)";
      } else if (errno == EINTR) {
        continue;
      } else if (errno != EAGAIN && errno != EWOULDBLOCK) {
        c.close_cause = std::string("receive failed: ") + std::strerror(errno);
      }
      break;
    }
  }

  void accept_one(std::int64_t t) {
    sockaddr_in addr{};
    socklen_t len = sizeof addr;
    const int fd =
        ::accept4(lfd_, reinterpret_cast<sockaddr*>(&addr), &len, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) {
      if (errno != EAGAIN && errno != EINTR)
        log_line(std::string("accept failed: ") + std::strerror(errno));
      return;
    }
    char ip[INET_ADDRSTRLEN] = "?";
    ::inet_ntop(AF_INET, &addr.sin_addr, ip, sizeof ip);
    const std::string peer = std::string(ip) + ":" + std::to_string(ntohs(addr.sin_port));
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    const int id = next_id_++;
    if (clients_.size() >= max_clients_) {
      // Full: make room by closing the connection idle the longest, if it is idle at all.
      Client* idlest = nullptr;
      for (auto& [cid, c] : clients_)
        if (!idlest || c.conn->last_byte_ms() < idlest->conn->last_byte_ms()) idlest = &c;
      if (idlest && t - idlest->conn->last_byte_ms() >= kEvictIdleMs) {
        close_client(*idlest, "evicted to admit client #" + std::to_string(id) + " (all " +
                                  std::to_string(max_clients_) + " slots taken, this one idle " +
                                  std::to_string(t - idlest->conn->last_byte_ms()) + " ms)");
        clients_.erase(idlest->conn->id());
      } else {
        log_line("client #" + std::to_string(id) + " from " + peer + " refused: all " +
                 std::to_string(max_clients_) + " slots busy");
        rgbdquad::protocol::SlamHello refusal;
        refusal.peer_name = "slam-server";
        refusal.refusal =
            "slam-server busy: all " + std::to_string(max_clients_) + " client slots in use";
        const auto e = rgbdquad::protocol::encode(refusal);
        if (e.ok()) (void)::send(fd, e.bytes.data(), e.bytes.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        ::close(fd);
        return;
      }
    }
    log_line("client #" + std::to_string(id) + " connected from " + peer);
    Client c;
    c.fd = fd;
    c.conn = std::make_unique<slamlink::SlamConnection>(id, peer, copt_, t);
    clients_.emplace(id, std::move(c));
  }

  void flush(Client& c, std::int64_t t) {
    if (!c.close_cause.empty() && !c.closing_after_flush) return;
    while (!c.conn->output().empty()) {
      const auto& out = c.conn->output();
      const ssize_t n = ::send(c.fd, out.data(), out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) {
        c.conn->consumed_output(static_cast<std::size_t>(n), t);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;  // POLLOUT next turn
      if (c.close_cause.empty())
        c.close_cause = std::string("send failed: ") + std::strerror(errno);
      c.closing_after_flush = false;
      break;
    }
    if (c.closing_after_flush && c.conn->output().empty()) c.closing_after_flush = false;
  }

  void close_finished() {
    for (auto it = clients_.begin(); it != clients_.end();) {
      Client& c = it->second;
      if (!c.close_cause.empty() && !c.closing_after_flush) {
        close_client(c, c.close_cause);
        it = clients_.erase(it);
      } else {
        ++it;
      }
    }
  }

  void close_client(Client& c, const std::string& cause) {
    const bool had_session = c.conn->hello_done() && registry_.session_of(c.conn->id()) != nullptr;
    registry_.detach(c.conn->id(), now_ms());
    log_line("client #" + std::to_string(c.conn->id()) + " (" + c.conn->peer() +
             ") closed: " + cause + "; " + c.conn->summary() +
             (had_session ? "; its map is kept for a reconnect" : ""));
    ::close(c.fd);
    c.fd = -1;
  }

  int lfd_;
  int sigfd_;
  std::size_t max_clients_;
  slamlink::ConnectionOptions copt_;
  slamlink::SessionRegistry registry_;
  std::map<int, Client> clients_;
  int next_id_ = 1;
};

/// Creates the checkpoint folder; false after logging why not (it also needs the localmap
/// back-end).
bool make_checkpoint_dir(const std::string& dir, const slam::PipelineOptions& options) {
  if (options.backend.kind != slam::BackendKind::kLocalMap) {
    log_line("--checkpoint-dir needs --backend localmap");
    return false;
  }
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    log_line("--checkpoint-dir " + dir + ": cannot create it" +
             (ec ? ": " + ec.message() : std::string()));
    return false;
  }
  return true;
}

/// The command line.
struct ServerArgs {
  std::string bind = "127.0.0.1", features = "orb", backend = "localmap";
  std::string load_map, save_map, tables_dir;
  int port = 5700;
  std::size_t max_clients = 4;
  slamlink::ConnectionOptions copt;
  slamlink::SessionRegistryOptions ropt;
  double checkpoint_period_s = slam::PipelineOptions{}.checkpoint_period_s;
  std::string loop_closing = slam::PipelineOptions{}.loop_closing ? "on" : "off";
  std::string restart_when_lost = slam::TrackerOptions{}.restart_when_lost ? "on" : "off";
  std::string depthless_observations = slam::PipelineOptions{}.depthless_observations();
  std::string cross_check = "on";
  std::string confirm_off_path = slam::TrackerOptions{}.confirm_off_path ? "on" : "off";
  std::string gravity = slam::TrackerOptions{}.gravity.enabled ? "on" : "off";
  std::string gravity_accelerometer =
      slam::TrackerOptions{}.gravity.from_accelerometer ? "on" : "off";
  std::string thread_policy = "rr";
  slam::ThreadPriorityOptions priority;
  int mapping_rt_priority = slam::PipelineOptions{}.mapping_rt_priority;
};

/// What is served: the address, the SLAM system, its map files and tables, the clients at once.
void add_serving_options(CLI::App& app, ServerArgs& a) {
  app.add_option("--bind", a.bind, "IPv4 address to listen on")->capture_default_str();
  app.add_option("--port", a.port, "TCP port")->check(CLI::Range(1, 65535))->capture_default_str();
  app.add_option("--features", a.features, "sift | surf | orb")
      ->check(CLI::IsMember({"sift", "surf", "orb"}))
      ->capture_default_str();
  app.add_option(
         "--load-map", a.load_map,
         "localmap: every new map starts from this saved map (relocalises in it, poses in its "
         "world frame); a map of another camera/detector/version is refused and logged")
      ->check(CLI::ExistingFile);
  app.add_option("--save-map", a.save_map, "localmap: write each map here when it ends");
  app.add_option("--tables-dir", a.tables_dir,
                 "write each map's per-frame tables (frames.csv: tracking wall and CPU ms, "
                 "features / matching / relocalisation ms, map-lock wait; "
                 "mapping.csv, loops.csv) into DIR/map-N (N from 1 in the order maps "
                 "start) when it ends");
  app.add_option("--backend", a.backend,
                 "localmap (tracking against a local map, the default) | vo | llc | glc (thesis)")
      ->check(CLI::IsMember({"localmap", "vo", "llc", "glc"}))
      ->capture_default_str();
  app.add_option("--max-clients", a.max_clients, "connections served at once")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
}

/// The link's timeouts, and the maps kept for reconnects and their checkpoints.
void add_link_options(CLI::App& app, ServerArgs& a) {
  app.add_option("--hello-timeout-ms", a.copt.hello_timeout_ms,
                 "SlamHello due within this of connecting")
      ->capture_default_str();
  app.add_option("--idle-timeout-ms", a.copt.idle_timeout_ms, "close a connection silent this long")
      ->capture_default_str();
  app.add_option("--message-timeout-ms", a.copt.message_timeout_ms,
                 "a begun message must be complete within this")
      ->capture_default_str();
  app.add_option("--write-timeout-ms", a.copt.write_timeout_ms,
                 "the peer must take reply bytes within this")
      ->capture_default_str();
  app.add_option("--resume-grace-ms", a.ropt.resume_grace_ms,
                 "a map without its client is kept this long")
      ->capture_default_str();
  app.add_option("--checkpoint-dir", a.ropt.checkpoint_dir,
                 "localmap: checkpoint each map into DIR/map-<id>.map (created if "
                 "missing) every --checkpoint-period-s of data and after each loop correction; a "
                 "restarted slam-server asked for that map id resumes its map and world frame "
                 "(SlamHello.resumed) instead of starting a new one; deleted when the map "
                 "ends for good, kept when slam-server stops");
  app.add_option("--checkpoint-period-s", a.checkpoint_period_s,
                 "data seconds between map checkpoints (0: after every keyframe)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  app.add_option("--max-sessions", a.ropt.max_sessions, "maps held at once (attached + parked)")
      ->capture_default_str();
}

/// Ablation switches of the tracker and the scheduling of the serving thread and the mappers.
void add_tracking_options(CLI::App& app, ServerArgs& a) {
  app.add_option("--loop-closing", a.loop_closing,
                 "localmap: loop closing on its own thread (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--restart-when-lost", a.restart_when_lost,
                 "localmap: a frame that can be neither tracked nor relocalised within 0.2 s of "
                 "the last tracked one starts a new map segment at the predicted pose "
                 "(docs/slam.md); off: it stays lost until relocalised")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--depthless-observations", a.depthless_observations,
                 "localmap: keypoints without a depth reading are fitted as (u, v) observations; "
                 "map: keyframes also keep them and the mapper triangulates points from them "
                 "(docs/slam.md)")
      ->check(CLI::IsMember({"on", "off", "map"}))
      ->capture_default_str();
  app.add_option("--cross-check", a.cross_check,
                 "localmap: cross-check weak fits against the reference keyframe (docs/slam.md); "
                 "off for ablations")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--confirm-off-path", a.confirm_off_path,
                 "localmap: a fit only the motion bound refuses is kept when a registration to "
                 "the reference keyframe lands on the same pose (docs/slam.md); off for ablations")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--gravity", a.gravity,
                 "localmap: gravity's direction (the frame's flight-controller attitude, else "
                 "the Kinect's accelerometer with --gravity-accelerometer on) on roll and pitch in "
                 "tracking, local BA and the loop-closing graph (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--gravity-accelerometer", a.gravity_accelerometer,
                 "localmap, with --gravity on: the Kinect's accelerometer as a gravity source when "
                 "a frame carries no attitude (off: it measures the camera's acceleration too; "
                 "docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option(
         "--thread-policy", a.thread_policy,
         "scheduling of the serving (tracking) thread: rr | fifo (real-time, falls back to nice "
         "with a logged reason) | nice | off; local mapping runs below it (--mapping-rt-priority)")
      ->check(CLI::IsMember({"rr", "fifo", "nice", "off"}))
      ->capture_default_str();
  app.add_option("--rt-priority", a.priority.rt_priority,
                 "real-time priority of the serving thread")
      ->check(CLI::Range(1, 99))
      ->capture_default_str();
  app.add_option("--mapping-rt-priority", a.mapping_rt_priority,
                 "SCHED_RR priority of each map's local-mapping thread while the serving thread "
                 "is real-time; must be below --rt-priority (0: normal policy at nice -10)")
      ->check(CLI::Range(0, 98))
      ->capture_default_str();
}

/// The pipeline's options from the command line, checked (and the checkpoint folder created);
/// nullopt after logging why not.
std::optional<slam::PipelineOptions> pipeline_options(ServerArgs& a) {
  slam::parse_thread_policy(a.thread_policy, &a.priority.policy, nullptr);
  if (a.mapping_rt_priority >= a.priority.rt_priority) {
    log_line("--mapping-rt-priority (" + std::to_string(a.mapping_rt_priority) +
             ") must be below --rt-priority (" + std::to_string(a.priority.rt_priority) +
             "): mapping must never delay tracking");
    return std::nullopt;
  }
  slam::PipelineOptions options;
  options.loop_closing = a.loop_closing == "on";
  if (a.cross_check == "off") options.tracker.cross_check_tracked_ratio = 0;
  options.tracker.restart_when_lost = a.restart_when_lost == "on";
  options.set_depthless_observations(a.depthless_observations);
  options.tracker.confirm_off_path = a.confirm_off_path == "on";
  options.tracker.gravity.enabled = a.gravity == "on";
  options.tracker.gravity.from_accelerometer = a.gravity_accelerometer == "on";
  options.mapping_rt_priority = a.mapping_rt_priority;
  options.checkpoint_period_s = a.checkpoint_period_s;
  std::string err;
  if (!slam::parse_detector_kind(a.features, &options.frontend.features.kind, &err) ||
      !slam::parse_backend_kind(a.backend, &options.backend.kind, &err)) {
    log_line(err);
    return std::nullopt;
  }
  std::string connection_error, registry_error;
  const bool connection_ok = a.copt.is_valid(&connection_error);
  if (!a.ropt.is_valid(&registry_error) || !connection_ok) {
    log_line(connection_error + registry_error);
    return std::nullopt;
  }
  if (!a.ropt.checkpoint_dir.empty() && !make_checkpoint_dir(a.ropt.checkpoint_dir, options))
    return std::nullopt;
  return options;
}

/// Binds and listens on --bind:--port; the listening socket, or -1 after logging why (`*exit_code`
/// 2 for a bad address, 1 for a socket error).
int open_listener(const ServerArgs& a, int* exit_code) {
  const int lfd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (lfd < 0) {
    log_line("cannot create sockets");
    *exit_code = 1;
    return -1;
  }
  const int one = 1;
  ::setsockopt(lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(a.port));
  if (::inet_pton(AF_INET, a.bind.c_str(), &addr.sin_addr) != 1) {
    log_line("bad --bind address '" + a.bind + "'");
    *exit_code = 2;
    return -1;
  }
  if (::bind(lfd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(lfd, 8) != 0) {
    log_line("cannot listen on " + a.bind + ":" + std::to_string(a.port) + ": " +
             std::strerror(errno));
    *exit_code = 1;
    return -1;
  }
  return lfd;
}

/// The maps: each new one gets its own SLAM pipeline and map files.
slamlink::SessionRegistry make_registry(const ServerArgs& a, const slam::PipelineOptions& options) {
  return slamlink::SessionRegistry(
      a.ropt,
      [options, load_map = a.load_map, save_map = a.save_map, tables_dir = a.tables_dir,
       maps_started = std::make_shared<int>(0)](const slamlink::SessionStart& start) {
        slamlink::SessionMapFiles files;
        files.load_path = load_map;
        files.save_path = save_map;
        files.checkpoint_path = start.checkpoint_path;
        files.resume_from_checkpoint = start.resume_from_checkpoint;
        ++*maps_started;
        if (!tables_dir.empty())
          files.tables_dir = tables_dir + "/map-" + std::to_string(*maps_started);
        return std::make_unique<slamlink::SlamLinkSession>(options, files);
      },
      [](const std::string& path, std::string* why) { return slam::check_map_file(path, why); });
}

void log_listening(const ServerArgs& a) {
  std::cerr << "slam-server: listening on " << a.bind << ":" << a.port << " (features "
            << a.features << ", backend " << a.backend << ", max " << a.max_clients
            << " clients, hello/idle/message/write timeouts " << a.copt.hello_timeout_ms << "/"
            << a.copt.idle_timeout_ms << "/" << a.copt.message_timeout_ms << "/"
            << a.copt.write_timeout_ms << " ms, resume grace " << a.ropt.resume_grace_ms << " ms)"
            << std::endl;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"slam-server: RGB-D SLAM on the SLAM link (SlamHello, RgbdFrame -> PoseUpdate)"};
  ServerArgs a;
  add_serving_options(app, a);
  add_link_options(app, a);
  add_tracking_options(app, a);
  CLI11_PARSE(app, argc, argv);
  const std::optional<slam::PipelineOptions> options = pipeline_options(a);
  if (!options) return 2;
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &mask, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  const int sigfd = ::signalfd(-1, &mask, SFD_CLOEXEC);
  if (sigfd < 0) {
    log_line("cannot create sockets");
    return 1;
  }
  int exit_code = 0;
  const int lfd = open_listener(a, &exit_code);
  if (lfd < 0) return exit_code;
  log_listening(a);
  // Tracking runs on this (the poll) thread: it is the real-time path; maps' mappers place
  // themselves below it (slam::PipelineOptions::mapping_rt_priority).
  log_line(slam::raise_current_thread(a.priority).describe("serving"));
  Server(lfd, sigfd, a.max_clients, a.copt, make_registry(a, *options)).run();
  ::close(lfd);
  ::close(sigfd);
  log_line("stopped");
  return 0;
}
