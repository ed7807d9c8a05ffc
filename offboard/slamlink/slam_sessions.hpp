// slam-server's maps held for their clients, socket-free. Each entry is one flight's map and world
// frame (a SlamLinkSession), named by the session_id the client sends in its SlamHello (the wire
// field's name; it names the map). A connection attaches to a map; when the connection breaks, the
// map is parked for `resume_grace_ms` so that a reconnecting client of the same flight continues
// the same map and world frame (a broken link must not discard the map); after that it is finished
// and dropped. A connection that presents the id of a map another connection still holds takes it
// over (the caller closes the old connection): a client that timed out reconnects before the
// server noticed the old socket died. session_id 0 asks for a new map that cannot be resumed; the
// registry then names it itself. With a checkpoint folder, every map with a client's id is
// checkpointed there (map-<id>.map, PipelineOptions::checkpoint_path): a restarted slam-server
// that is asked for an id it does not hold, and finds that id's whole checkpoint, resumes it (map
// and world frame kept) instead of starting a new map. A map that ends for good (grace over,
// dropped for room) deletes its checkpoint; one ended by slam-server stopping keeps it for the
// next start.
//
// Time is passed in (now_ms, any monotonic origin). Not thread-safe (slam-server's single loop).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam_link_session.hpp"

namespace rgbdquad::slamlink {

struct SessionRegistryOptions {
  /// How long a map waits for its client to come back: longer than quad-control's reply timeout
  /// (5 s) plus a reconnect (<= 1 s) several times over, short enough that a finished flight's map
  /// does not hold memory for long.
  std::int64_t resume_grace_ms = 30000;
  /// Maps held at once (attached + parked). A map holds keyframes (images + features): a few
  /// hundred MB for a long flight. Beyond it the oldest parked map is dropped.
  std::size_t max_sessions = 4;
  /// Where maps are checkpointed ("" = no checkpoints; the folder must exist).
  std::string checkpoint_dir;
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

struct AttachResult {
  SlamLinkSession* session = nullptr;       ///< null: refused (see refusal)
  std::uint64_t session_id = 0;             ///< the id served (the registry's own when 0 was asked)
  bool resumed = false;                     ///< an existing map continues
  std::optional<int> displaced_connection;  ///< held the map until now: close it
  std::string refusal;
};

/// How a map starts (SessionRegistry's factory fills its SessionMapFiles from it).
struct SessionStart {
  std::uint64_t session_id = 0;
  std::string checkpoint_path;          ///< "" = no checkpoint
  bool resume_from_checkpoint = false;  ///< continue the map in checkpoint_path
};

class SessionRegistry {
 public:
  using Factory = std::function<std::unique_ptr<SlamLinkSession>(const SessionStart&)>;
  /// Whether the checkpoint file at `path` can be resumed (slam::check_map_file in slam-server;
  /// passed in so that the registry does not depend on the SLAM engine: the fuzz target builds it
  /// without). Without one, checkpoints are written but never resumed.
  using CheckpointCheck = std::function<bool(const std::string& path, std::string* why)>;
  SessionRegistry(SessionRegistryOptions options, Factory factory,
                  CheckpointCheck checkpoint_check = nullptr);

  /// Attaches `connection` to map `session_id` (new or resumed). Log lines (a map started,
  /// resumed, a parked map dropped to make room) are appended to `log`.
  AttachResult attach(std::uint64_t session_id, int connection, std::int64_t now_ms,
                      std::vector<std::string>* log);
  /// The connection is gone: its map (if any) is parked until now_ms + resume_grace_ms.
  void detach(int connection, std::int64_t now_ms);
  /// Finishes and drops maps parked past their grace period; one log line each.
  std::vector<std::string> expire(std::int64_t now_ms);
  /// Finishes every map (shutdown); one log line each.
  std::vector<std::string> finish_all();
  /// Earliest expiry among parked maps (for the poll timeout).
  std::optional<std::int64_t> next_expiry_ms() const;
  /// The map a connection holds (null if none).
  SlamLinkSession* session_of(int connection);
  std::size_t size() const { return sessions_.size(); }

  static std::string id_text(std::uint64_t session_id);
  /// The checkpoint file of `session_id` ("" without a checkpoint folder, or for the registry's
  /// own ids, which restart from 1 with every slam-server and are never resumed).
  std::string checkpoint_path(std::uint64_t session_id) const;

 private:
  struct Entry {
    std::unique_ptr<SlamLinkSession> session;
    std::string checkpoint_path;
    std::optional<int> connection;  ///< attached connection
    std::int64_t parked_since_ms = 0;
    std::int64_t started_ms = 0;
  };
  /// Finishes the map; `for_good`: its checkpoint is deleted (the flight's map is over).
  std::string end_line(std::uint64_t id, Entry& e, const std::string& why, bool for_good = true);

  SessionRegistryOptions options_;
  Factory factory_;
  CheckpointCheck checkpoint_check_;
  std::map<std::uint64_t, Entry> sessions_;
  std::uint64_t next_own_id_ = 1;  ///< ids for clients that ask with 0 (high bit set, see .cpp)
};

}  // namespace rgbdquad::slamlink
