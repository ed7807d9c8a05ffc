// slam-server's maps held for their clients: see slam_sessions.hpp.
#include "slam_sessions.hpp"

#include <cstdio>
#include <filesystem>
#include <utility>

namespace rgbdquad::slamlink {

namespace {

/// The failure path of is_valid(): stores `message` in *error unless error is null; false.
bool reject(std::string* error, std::string message) {
  if (error) *error = std::move(message);
  return false;
}

// Ids the registry gives itself (client asked with 0): a fixed prefix in the top bits keeps them
// apart from a client's random ids in practice, and they are never resumed.
constexpr std::uint64_t kOwnIdPrefix = 0x5E55000000000000ull;
constexpr std::uint64_t kOwnIdPrefixMask = 0xFFFF000000000000ull;
}  // namespace

bool SessionRegistryOptions::is_valid(std::string* error) const {
  if (resume_grace_ms < 0) return reject(error, "resume grace must be >= 0 ms");
  if (max_sessions < 1) return reject(error, "max sessions must be >= 1");
  return true;
}

SessionRegistry::SessionRegistry(SessionRegistryOptions options, Factory factory,
                                 CheckpointCheck checkpoint_check)
    : options_(std::move(options)),
      factory_(std::move(factory)),
      checkpoint_check_(std::move(checkpoint_check)) {}

std::string SessionRegistry::id_text(std::uint64_t session_id) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(session_id));
  return buf;
}

std::string SessionRegistry::checkpoint_path(std::uint64_t session_id) const {
  if (options_.checkpoint_dir.empty() || (session_id & kOwnIdPrefixMask) == kOwnIdPrefix) return {};
  return (std::filesystem::path(options_.checkpoint_dir) / ("map-" + id_text(session_id) + ".map"))
      .string();
}

std::string SessionRegistry::end_line(std::uint64_t id, Entry& e, const std::string& why,
                                      bool for_good) {
  std::string line = "map " + id_text(id) + " ended (" + why + "): " + e.session->finish_summary();
  if (for_good && !e.checkpoint_path.empty()) {
    std::error_code ec;
    std::filesystem::remove(e.checkpoint_path, ec);
    line += ec ? "; checkpoint " + e.checkpoint_path + " NOT deleted: " + ec.message()
               : "; checkpoint deleted";
  }
  return line;
}

AttachResult SessionRegistry::attach(std::uint64_t session_id, int connection, std::int64_t now_ms,
                                     std::vector<std::string>* log) {
  AttachResult r;
  detach(connection, now_ms);  // a second hello on the same connection re-attaches
  if (session_id != 0) {
    auto it = sessions_.find(session_id);
    if (it != sessions_.end()) {
      Entry& e = it->second;
      r.displaced_connection = e.connection;
      e.connection = connection;
      r.session = e.session.get();
      r.session_id = session_id;
      r.resumed = true;
      if (log)
        log->push_back("map " + id_text(session_id) + " resumed (world frame kept, " +
                       std::to_string(e.session->frames_processed()) + " frames" +
                       (r.displaced_connection
                            ? ", taken over from client #" + std::to_string(*r.displaced_connection)
                            : ", parked " + std::to_string(now_ms - e.parked_since_ms) + " ms") +
                       ")");
      return r;
    }
  }
  if (sessions_.size() >= options_.max_sessions) {
    // Room for a new map: drop the map parked the longest; refuse if every map has its client.
    auto victim = sessions_.end();
    for (auto it = sessions_.begin(); it != sessions_.end(); ++it)
      if (!it->second.connection && (victim == sessions_.end() ||
                                     it->second.parked_since_ms < victim->second.parked_since_ms))
        victim = it;
    if (victim == sessions_.end()) {
      r.refusal = "slam-server busy: " + std::to_string(sessions_.size()) +
                  " maps with a client each (max " + std::to_string(options_.max_sessions) + ")";
      return r;
    }
    if (log)
      log->push_back(end_line(victim->first, victim->second, "dropped to make room for a new map"));
    sessions_.erase(victim);
  }
  if (session_id == 0) {
    do session_id = kOwnIdPrefix | next_own_id_++;
    while (sessions_.count(session_id) != 0);
  }
  SessionStart start;
  start.session_id = session_id;
  start.checkpoint_path = checkpoint_path(session_id);
  std::string unusable;  // why an existing checkpoint is not resumed
  std::error_code ec;
  if (!start.checkpoint_path.empty() && std::filesystem::exists(start.checkpoint_path, ec)) {
    // (an unusable one is overwritten by the new map's first checkpoint)
    if (!checkpoint_check_) unusable = "no checkpoint check configured";
    start.resume_from_checkpoint =
        checkpoint_check_ && checkpoint_check_(start.checkpoint_path, &unusable);
  }
  Entry e;
  e.session = factory_(start);
  e.checkpoint_path = start.checkpoint_path;
  e.connection = connection;
  e.started_ms = now_ms;
  r.session = e.session.get();
  r.session_id = session_id;
  r.resumed = start.resume_from_checkpoint;
  sessions_.emplace(session_id, std::move(e));
  if (log)
    log->push_back("map " + id_text(session_id) +
                   (r.resumed
                        ? " resumed from its checkpoint " + start.checkpoint_path +
                              " (slam-server restarted; world frame kept)"
                        : " started (new" +
                              (unusable.empty() ? std::string()
                                                : "; its checkpoint is unusable: " + unusable) +
                              ")"));
  return r;
}

void SessionRegistry::detach(int connection, std::int64_t now_ms) {
  for (auto& [id, e] : sessions_) {
    if (e.connection == connection) {
      e.connection.reset();
      e.parked_since_ms = now_ms;
    }
  }
}

std::vector<std::string> SessionRegistry::expire(std::int64_t now_ms) {
  std::vector<std::string> lines;
  for (auto it = sessions_.begin(); it != sessions_.end();) {
    Entry& e = it->second;
    if (!e.connection && now_ms - e.parked_since_ms >= options_.resume_grace_ms) {
      lines.push_back(end_line(
          it->first, e, "no client for " + std::to_string(options_.resume_grace_ms) + " ms"));
      it = sessions_.erase(it);
    } else {
      ++it;
    }
  }
  return lines;
}

std::vector<std::string> SessionRegistry::finish_all() {
  std::vector<std::string> lines;
  for (auto& [id, e] : sessions_)  // checkpoints kept: a restarted slam-server resumes them
    lines.push_back(end_line(id, e, "slam-server stopping", /*for_good=*/false));
  sessions_.clear();
  return lines;
}

std::optional<std::int64_t> SessionRegistry::next_expiry_ms() const {
  std::optional<std::int64_t> next;
  for (const auto& [id, e] : sessions_)
    if (!e.connection) {
      const std::int64_t t = e.parked_since_ms + options_.resume_grace_ms;
      if (!next || t < *next) next = t;
    }
  return next;
}

SlamLinkSession* SessionRegistry::session_of(int connection) {
  for (auto& [id, e] : sessions_)
    if (e.connection == connection) return e.session.get();
  return nullptr;
}

}  // namespace rgbdquad::slamlink
