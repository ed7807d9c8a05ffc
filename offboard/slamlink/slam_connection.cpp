// One client connection of slam-server: see slam_connection.hpp.
#include "slam_connection.hpp"

#include <algorithm>
#include <limits>
#include <utility>

namespace rgbdquad::slamlink {

namespace proto = rgbdquad::protocol;

namespace {

/// The failure path of is_valid(): stores `message` in *error unless error is null; false.
bool reject(std::string* error, std::string message) {
  if (error) *error = std::move(message);
  return false;
}

constexpr const char* kServerName = "slam-server";
constexpr std::size_t kMaxFaultLogs =
    20;  // then counted: a stream of bad frames must not flood the log
}  // namespace

bool ConnectionOptions::is_valid(std::string* error) const {
  if (hello_timeout_ms < 1 || idle_timeout_ms < 1 || message_timeout_ms < 1 || write_timeout_ms < 1)
    return reject(error, "connection timeouts must be >= 1 ms");
  return true;
}

SlamConnection::SlamConnection(int id, std::string peer, ConnectionOptions options,
                               std::int64_t now_ms)
    : id_(id),
      peer_(std::move(peer)),
      options_(options),
      connected_ms_(now_ms),
      last_byte_ms_(now_ms) {}

void SlamConnection::on_bytes(const std::uint8_t* data, std::size_t size, std::int64_t now_ms) {
  if (size == 0) return;
  last_byte_ms_ = now_ms;
  decoder_.feed(data, size);
  if (!partial_since_ms_) partial_since_ms_ = now_ms;
}

void SlamConnection::track_partial(std::int64_t now_ms) {
  // Called after the decoder was drained: bytes left are the start of an unfinished message.
  if (decoder_.buffered_bytes() == 0)
    partial_since_ms_.reset();
  else if (!partial_since_ms_)
    partial_since_ms_ = now_ms;
}

void SlamConnection::queue(const proto::Message& m) {
  const proto::EncodeResult e = proto::encode(m);
  if (!e.ok()) return;  // callers only queue messages they validated
  out_.insert(out_.end(), e.bytes.begin(), e.bytes.end());
}

void SlamConnection::consumed_output(std::size_t n, std::int64_t now_ms) {
  out_.erase(out_.begin(), out_.begin() + static_cast<std::ptrdiff_t>(std::min(n, out_.size())));
  if (out_.empty())
    output_since_ms_.reset();
  else if (n > 0)
    output_since_ms_ = now_ms;  // progress: the peer reads
}

std::optional<std::string> SlamConnection::process(SessionRegistry& registry, std::int64_t now_ms,
                                                   std::vector<int>* displaced,
                                                   std::vector<std::string>* log,
                                                   bool* flush_first) {
  *flush_first = false;
  const std::size_t out_before = out_.size();
  std::optional<std::string> cause;
  for (;;) {
    proto::DecodeResult r = decoder_.next();
    if (r.status == proto::DecodeStatus::kNeedMoreBytes) break;
    if (r.status == proto::DecodeStatus::kError) {
      if (decode_errors_++ == 0 && log)
        log->push_back("client #" + std::to_string(id_) +
                       ": undecodable bytes skipped: " + proto::to_string(r.error) + " " +
                       r.detail + " (further ones counted, reported at close)");
      continue;
    }
    partial_since_ms_ = now_ms;  // a message ended here: the next one starts at the latest now
    if (const auto* hello = std::get_if<proto::SlamHello>(&*r.message)) {
      if (const std::string why = proto::hello_incompatibility(*hello); !why.empty()) {
        cause = "incompatible peer '" + hello->peer_name + "': " + why;
        break;
      }
      AttachResult a = registry.attach(hello->session_id, id_, now_ms, log);
      proto::SlamHello reply;
      reply.peer_name = kServerName;
      if (!a.session) {
        reply.refusal = a.refusal;
        queue(reply);
        *flush_first = true;
        cause = "refused: " + a.refusal;
        break;
      }
      if (a.displaced_connection && *a.displaced_connection != id_ && displaced)
        displaced->push_back(*a.displaced_connection);
      session_id_ = a.session_id;
      reply.session_id = a.session_id;
      reply.resumed = a.resumed;
      reply.session_frames = static_cast<std::uint32_t>(std::min<std::size_t>(
          a.session->frames_processed(), std::numeric_limits<std::uint32_t>::max()));
      queue(reply);
      if (log)
        log->push_back("client #" + std::to_string(id_) + " (" + hello->peer_name + ", " + peer_ +
                       "): map " + SessionRegistry::id_text(a.session_id) +
                       (a.resumed ? " resumed" : " new"));
      continue;
    }
    const auto* frame = std::get_if<proto::RgbdFrame>(&*r.message);
    if (!frame) {
      cause = "unexpected " + std::string(proto::to_string(proto::message_type(*r.message))) +
              " from a client (slam-server takes SlamHello and slam::RgbdFrame only)";
      break;
    }
    SlamLinkSession* session = session_id_ ? registry.session_of(id_) : nullptr;
    if (!session) {
      cause = "RgbdFrame before SlamHello";
      break;
    }
    std::string err;
    const proto::PoseUpdate update = session->on_frame(*frame, &err);
    queue(update);
    ++frames_;
    // Faults are logged, the first kMaxFaultLogs per connection in full, the rest counted.
    if (!err.empty() && log && faults_logged_++ < kMaxFaultLogs)
      log->push_back(
          "client #" + std::to_string(id_) + ": frame " + std::to_string(frame->pair_sequence) +
          (update.tracking_state == proto::TrackingState::kLost && update.inlier_count == 0
               ? " answered LOST: "
               : ": ") +
          err);
  }
  track_partial(now_ms);
  if (out_before == 0 && !out_.empty()) output_since_ms_ = now_ms;
  return cause;
}

std::optional<std::string> SlamConnection::timed_out(std::int64_t now_ms) const {
  if (!session_id_ && now_ms - connected_ms_ >= options_.hello_timeout_ms)
    return "no SlamHello within " + std::to_string(options_.hello_timeout_ms) + " ms of connecting";
  if (partial_since_ms_ && now_ms - *partial_since_ms_ >= options_.message_timeout_ms)
    return "a message begun and not finished within " +
           std::to_string(options_.message_timeout_ms) + " ms (" +
           std::to_string(decoder_.buffered_bytes()) +
           " bytes of it received; peer stalled or dripping)";
  if (output_since_ms_ && now_ms - *output_since_ms_ >= options_.write_timeout_ms)
    return "peer took no reply bytes for " + std::to_string(options_.write_timeout_ms) + " ms (" +
           std::to_string(out_.size()) + " bytes waiting)";
  if (now_ms - last_byte_ms_ >= options_.idle_timeout_ms)
    return "idle: no bytes for " + std::to_string(options_.idle_timeout_ms) + " ms";
  return std::nullopt;
}

std::int64_t SlamConnection::next_deadline_ms() const {
  std::int64_t t = last_byte_ms_ + options_.idle_timeout_ms;
  if (!session_id_) t = std::min(t, connected_ms_ + options_.hello_timeout_ms);
  if (partial_since_ms_) t = std::min(t, *partial_since_ms_ + options_.message_timeout_ms);
  if (output_since_ms_) t = std::min(t, *output_since_ms_ + options_.write_timeout_ms);
  return t;
}

std::string SlamConnection::summary() const {
  std::string s = std::to_string(frames_) + " frames on this connection";
  if (session_id_) s += ", map " + SessionRegistry::id_text(*session_id_);
  if (decode_errors_ > 0)
    s += ", " + std::to_string(decode_errors_) + " undecodable byte runs skipped";
  if (faults_logged_ > 0)
    s += ", " + std::to_string(faults_logged_) + " frames with a fault or a repaired pose";
  return s;
}

}  // namespace rgbdquad::slamlink
