// One client connection of slam-server, socket-free: bytes in, bytes out, deadlines, and the
// reason it must close. The server loop (app/slam_server_main.cpp) owns the socket and feeds this.
//
//   connected --SlamHello (compatible; attached to a map)--> serving: RgbdFrame -> PoseUpdate
//
// Every way a connection can end has a cause string that the server logs:
//   * no SlamHello within hello_timeout_ms of connecting (a silent or idle client);
//   * no byte for idle_timeout_ms;
//   * a message begun and not finished within message_timeout_ms (a peer that stops mid-message or
//     drips bytes: the clock starts at the message's first byte and is not reset by later ones);
//   * replies not taken by the peer within write_timeout_ms (a client that does not read);
//   * an incompatible SlamHello, an RgbdFrame before SlamHello, a message that is not for the
//     server, a refused attach (registry full), or its map taken over by a newer connection.
// Undecodable bytes are skipped (the decoder resynchronises on the magic) and counted; the first
// is logged, the rest summarised when the connection closes (no log line per garbage chunk).
//
// Time is passed in (now_ms). Not thread-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/protocol/codec.hpp"
#include "slam_sessions.hpp"

namespace rgbdquad::slamlink {

struct ConnectionOptions {
  std::int64_t hello_timeout_ms = 5000;  ///< quad-control sends its hello at once
  std::int64_t idle_timeout_ms = 60000;  ///< quad-control sends frames at up to 30 Hz while flying
  std::int64_t message_timeout_ms = 10000;  ///< a 1.5 MB RAW frame takes ~0.1 s even at 100 Mbit/s
  std::int64_t write_timeout_ms = 10000;    ///< a PoseUpdate is 150 bytes
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

class SlamConnection {
 public:
  SlamConnection(int id, std::string peer, ConnectionOptions options, std::int64_t now_ms);

  /// Bytes received from the peer.
  void on_bytes(const std::uint8_t* data, std::size_t size, std::int64_t now_ms);
  /// Handles every complete message received (SLAM runs here, synchronously). Replies are queued
  /// in output(). Returns the cause when the connection must close (after output() is flushed if
  /// `flush_first`). A connection whose map was taken over is added to `displaced`.
  std::optional<std::string> process(SessionRegistry& registry, std::int64_t now_ms,
                                     std::vector<int>* displaced, std::vector<std::string>* log,
                                     bool* flush_first);
  /// The deadline cause if one has passed at now_ms.
  std::optional<std::string> timed_out(std::int64_t now_ms) const;
  /// The earliest deadline (for the poll timeout).
  std::int64_t next_deadline_ms() const;

  const std::vector<std::uint8_t>& output() const { return out_; }
  void consumed_output(std::size_t n, std::int64_t now_ms);

  int id() const { return id_; }
  const std::string& peer() const { return peer_; }
  std::int64_t last_byte_ms() const { return last_byte_ms_; }
  bool hello_done() const { return session_id_.has_value(); }
  std::size_t frames() const { return frames_; }
  /// "n frames, map <id>, k undecodable byte runs" for the close log line.
  std::string summary() const;

 private:
  void queue(const rgbdquad::protocol::Message& m);
  void track_partial(std::int64_t now_ms);

  int id_;
  std::string peer_;
  ConnectionOptions options_;
  rgbdquad::protocol::StreamDecoder decoder_;
  std::vector<std::uint8_t> out_;
  std::int64_t connected_ms_;
  std::int64_t last_byte_ms_;
  std::optional<std::int64_t> partial_since_ms_;  ///< first byte of an unfinished message
  std::optional<std::int64_t> output_since_ms_;   ///< replies waiting since
  std::optional<std::uint64_t> session_id_;
  std::size_t frames_ = 0;
  std::size_t decode_errors_ = 0;
  std::size_t faults_logged_ = 0;  ///< frames answered LOST for a fault or with a repaired pose
};

}  // namespace rgbdquad::slamlink
