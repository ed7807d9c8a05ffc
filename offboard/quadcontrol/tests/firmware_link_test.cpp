// FirmwareLink with send_on_pose against a fake firmware (bridge) on loopback: the asio wiring of
// CommandScheduler (notify_pose -> a pose-driven command; no poses -> keep-alives; a withheld
// command uses its slot). The schedule's timing itself is tested with time passed in
// (command_scheduler_test.cpp); here only counts are asserted, waited for up to a generous
// deadline.
#include "app/firmware_link.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr auto kDeadline = std::chrono::seconds(10);  // generous: the machine may be loaded

/// Answers every HTTP request like the WiFi bridge + firmware: 200 with a valid reply line echoing
/// the request's seq (0 for GET /status). Records method + target. Stopped in the destructor.
class FakeFirmware {
 public:
  FakeFirmware() {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 8) != 0) {
      throw std::runtime_error("fake firmware: cannot listen");
    }
    socklen_t len = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { serve(); });
  }
  ~FakeFirmware() {
    stop_ = true;
    thread_.join();
    ::close(fd_);
  }
  std::uint16_t port() const { return port_; }
  std::vector<std::string> requests() {
    std::lock_guard<std::mutex> lock(mutex_);
    return requests_;
  }

 private:
  void serve() {
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      const int c = ::accept(fd_, nullptr, nullptr);
      if (c < 0) continue;
      std::string req;
      char buf[512];
      while (req.find("\r\n\r\n") == std::string::npos) {
        pollfd q{c, POLLIN, 0};
        if (::poll(&q, 1, 1000) <= 0) break;
        const ssize_t n = ::recv(c, buf, sizeof buf, 0);
        if (n <= 0) break;
        req.append(buf, static_cast<std::size_t>(n));
      }
      const std::string line = req.substr(0, req.find("\r\n"));
      unsigned long seq = 0;
      if (auto i = line.find("seq="); i != std::string::npos) seq = std::stoul(line.substr(i + 4));
      const std::string body =
          R"({"ver":)" + std::to_string(rgbd_control::kControlLinkVersion) +
          R"(,"err":"ok","fw":"0.1.0","state":"armed","seq":)" + std::to_string(seq) +
          R"(,"out_us":[1500,1500,1000,1500],"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,)"
          R"("imu_raw":[0,0,0,0,0,0],"imu_age_ms":null})";
      const std::string resp = "HTTP/1.1 200 OK\r\nContent-Length: " + std::to_string(body.size()) +
                               "\r\nConnection: close\r\n\r\n" + body;
      (void)::send(c, resp.data(), resp.size(), MSG_NOSIGNAL);
      ::close(c);
      std::lock_guard<std::mutex> lock(mutex_);
      requests_.push_back(line);
    }
  }
  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::vector<std::string> requests_;
  std::thread thread_;
};

bool wait_for(const std::function<bool()>& done) {
  const auto end = std::chrono::steady_clock::now() + kDeadline;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return done();
}

struct Fixture {
  FakeFirmware firmware;
  std::atomic<bool> withhold{false};
  std::atomic<int> provided{0};
  std::unique_ptr<FirmwareLink> link;

  explicit Fixture(FirmwareLinkOptions o) {
    o.host = "127.0.0.1";
    o.port = firmware.port();
    o.timeout_ms = 1000;
    link = std::make_unique<FirmwareLink>(
        o, generated_control_spec(), rgbd_control::Key{},
        [this](std::int64_t, std::uint32_t) -> std::optional<PwmCommand> {
          ++provided;
          if (withhold) return std::nullopt;
          return PwmCommand{1500, 1500, 1000, 1500, true};
        },
        nullptr);
  }
};

FirmwareLinkOptions on_pose(int keep_alive_ms) {
  FirmwareLinkOptions o;
  o.send_on_pose = true;
  o.min_interval_ms = 17;
  o.keep_alive_ms = keep_alive_ms;
  return o;
}

TEST(FirmwareLinkOnPose, GivenAFreshPoseThenAPoseDrivenCommandIsSent) {
  // GIVEN a link whose keep-alive is slow (125 ms), past its GET /status
  Fixture f(on_pose(125));
  ASSERT_TRUE(wait_for([&] { return f.link->stats().ok >= 1; }));  // the status reply
  // WHEN poses arrive
  for (int i = 0; i < 3; ++i) {
    f.link->notify_pose();
    ASSERT_TRUE(
        wait_for([&] { return f.link->stats().pose_driven >= static_cast<std::uint64_t>(i + 1); }));
  }
  // THEN each one went out as a signed PUT /control carrying the controller's command (the link
  // counts a send before the fake firmware's thread has recorded it: wait for the recording)
  int puts = 0;
  EXPECT_TRUE(wait_for([&] {
    puts = 0;
    for (const auto& r : f.firmware.requests())
      puts += r.rfind("PUT /control?", 0) == 0 && r.find("&mac=") != std::string::npos;
    return puts >= 3;
  })) << puts
      << " signed PUTs recorded";
  const auto reqs = f.firmware.requests();
  ASSERT_FALSE(reqs.empty());
  EXPECT_EQ(reqs.front().rfind("GET ", 0), 0U);
  EXPECT_EQ(f.link->stats().http_errors, 0U);
}

TEST(FirmwareLinkOnPose, GivenNoPosesThenKeepAlivesAreSent) {
  // GIVEN a link and no poses at all, WHEN it runs, THEN keep-alives carry commands
  Fixture f(on_pose(20));
  ASSERT_TRUE(
      wait_for([&] { return f.link->stats().keep_alives >= 5 && f.link->stats().ok >= 4; }));
  EXPECT_EQ(f.link->stats().pose_driven, 0U);
}

TEST(FirmwareLinkOnPose, GivenAWithheldCommandThenNothingIsSentButTheScheduleGoesOn) {
  // GIVEN a controller that withholds every command (blind landing), WHEN poses come,
  // THEN the provider is asked again and again but no PUT reaches the firmware
  Fixture f(on_pose(20));
  ASSERT_TRUE(wait_for([&] { return f.link->stats().ok >= 1; }));
  f.withhold = true;
  const int asked = f.provided;
  const auto sent = f.link->stats().sent;
  f.link->notify_pose();
  ASSERT_TRUE(wait_for([&] { return f.provided >= asked + 3; }));
  EXPECT_LE(f.link->stats().sent,
            sent + 1);  // at most one already in flight when withholding began
}

TEST(FirmwareLinkOnPose, GivenAHandOverThenTheLinksOwnPauseIsToldApartFromTheCommandGap) {
  // GIVEN a link sending keep-alives, WHEN the controller withholds 15 asks in a row (a blind
  // landing's hand-over) and then commands again
  Fixture f(on_pose(20));
  ASSERT_TRUE(wait_for([&] { return f.link->stats().keep_alives >= 3; }));
  f.withhold = true;
  const int asked = f.provided;
  ASSERT_TRUE(wait_for([&] { return f.provided >= asked + 15; }));
  f.withhold = false;
  ASSERT_TRUE(wait_for([&] { return f.link->stats().command_gaps >= 1; }));
  // THEN the gap between commands spans the hand-over, while the link's own longest pause
  // (between two asks, sent or withheld) is a fraction of it: the link kept asking throughout
  const FirmwareLinkStats st = f.link->stats();
  EXPECT_GE(st.withheld, 15U);
  EXPECT_GT(st.max_command_gap_ms, 100.0);
  EXPECT_LT(st.max_link_pause_ms, st.max_command_gap_ms);
}

TEST(FirmwareLinkOnPose, OptionsAreValidated) {
  FirmwareLinkOptions o = on_pose(10);  // keep-alive shorter than the minimum interval
  EXPECT_NE(testing::problem(o), "");
  o.send_on_pose = false;  // the fixed period ignores them
  EXPECT_EQ(testing::problem(o), "");
  EXPECT_EQ(testing::problem(on_pose(50)), "");
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
