// TCP helpers on loopback: connect/accept/send/read, stop interrupts waits, refused connects fail
// fast, backoff is capped.
#include "rgbdquad/net/socket.h"

#include <gtest/gtest.h>

#include <thread>

namespace rgbdquad::net {
namespace {

TEST(Backoff, DoublesAndCapsAtMax) {
  Backoff b(50, 1000);
  const int expected[] = {50, 100, 200, 400, 800, 1000, 1000};
  for (int e : expected) EXPECT_EQ(b.next_delay_ms(), e);
  b.reset();
  EXPECT_EQ(b.next_delay_ms(), 50);
}

TEST(Socket, LoopbackRoundTrip) {
  Waker waker;
  UniqueFd listener = listen_tcp("127.0.0.1", 0);
  const std::uint16_t port = local_port(listener);
  ASSERT_GT(port, 0);
  std::string error;
  auto client = connect_tcp("127.0.0.1", port, 1000, waker, &error);
  ASSERT_TRUE(client.has_value()) << error;
  ASSERT_EQ(wait_readable(listener.get(), waker, 1000), IoStatus::kOk);
  std::string peer;
  auto server = accept_tcp(listener, &peer);
  ASSERT_TRUE(server.has_value());
  EXPECT_EQ(peer.rfind("127.0.0.1:", 0), 0u);
  std::vector<std::uint8_t> data(3'000'000);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(i * 7);
  std::thread sender([&] {
    EXPECT_EQ(send_all(client->get(), data.data(), data.size(), waker, 2000), IoStatus::kOk);
    client->reset();
  });
  std::vector<std::uint8_t> received;
  std::uint8_t buffer[65536];
  while (true) {
    std::size_t got = 0;
    const IoStatus s = read_some(server->get(), buffer, sizeof buffer, &got, waker, 2000);
    if (s == IoStatus::kClosed) break;
    ASSERT_EQ(s, IoStatus::kOk);
    received.insert(received.end(), buffer, buffer + got);
  }
  sender.join();
  EXPECT_EQ(received, data);
}

TEST(Socket, RefusedConnectFailsWithReason) {
  Waker waker;
  std::uint16_t port = 0;
  {
    UniqueFd probe = listen_tcp("127.0.0.1", 0);
    port = local_port(probe);
  }  // closed: nobody listens on `port` now
  std::string error;
  EXPECT_FALSE(connect_tcp("127.0.0.1", port, 1000, waker, &error).has_value());
  EXPECT_NE(error.find("refused"), std::string::npos) << error;
}

TEST(Socket, WakerInterruptsWait) {
  Waker waker;
  UniqueFd listener = listen_tcp("127.0.0.1", 0);
  waker.wake();
  EXPECT_EQ(wait_readable(listener.get(), waker, -1), IoStatus::kWoken);
  waker.clear();
  EXPECT_EQ(wait_readable(listener.get(), waker, 0), IoStatus::kTimeout);
}

TEST(Socket, BadListenAddressThrows) {
  EXPECT_THROW(listen_tcp("not-an-address", 0), std::runtime_error);
}

}  // namespace
}  // namespace rgbdquad::net
