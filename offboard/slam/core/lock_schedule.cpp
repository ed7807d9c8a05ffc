// Lock-step record and replay; see lock_schedule.hpp.
#include "slam/core/lock_schedule.hpp"

#include <chrono>
#include <cmath>
#include <sstream>

namespace rgbdquad::slam {

namespace {

constexpr const char* kHeader =
    "# rgbd-quad lock schedule v1: the order in which the SLAM threads took the map's lock\n"
    "# L <party> <n>: the party took it n times in a row; A <party> <value>: a timing-dependent "
    "answer it was given; F <us>: tracking began the frame stamped <us> microseconds\n"
    "# parties: t tracking, m mapping, l loop closing\n";

bool party_of(char c, MapParty* out) {
  switch (c) {
    case 't':
      *out = MapParty::kTracking;
      return true;
    case 'm':
      *out = MapParty::kMapping;
      return true;
    case 'l':
      *out = MapParty::kLoopClosing;
      return true;
    default:
      return false;
  }
}

std::size_t slot(MapParty p) { return static_cast<std::size_t>(p); }

}  // namespace

char party_letter(MapParty p) {
  switch (p) {
    case MapParty::kTracking:
      return 't';
    case MapParty::kMapping:
      return 'm';
    case MapParty::kLoopClosing:
      return 'l';
  }
  return '?';
}

std::unique_ptr<LockSchedule> LockSchedule::recorder(const std::string& path, std::string* error) {
  std::unique_ptr<LockSchedule> s(new LockSchedule());
  s->out_.open(path, std::ios::out | std::ios::trunc);
  if (!s->out_) {
    if (error) *error = "lock schedule: cannot write " + path;
    return nullptr;
  }
  s->path_ = path;
  s->out_ << kHeader;
  return s;
}

std::unique_ptr<LockSchedule> LockSchedule::replayer(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = "lock schedule: cannot read " + path;
    return nullptr;
  }
  std::ostringstream text;
  text << in.rdbuf();
  auto s = replayer_from_text(text.str(), error);
  if (!s && error) *error = path + ": " + *error;
  return s;
}

std::unique_ptr<LockSchedule> LockSchedule::replayer_from_text(const std::string& text,
                                                               std::string* error) {
  std::unique_ptr<LockSchedule> s(new LockSchedule());
  s->replaying_ = true;
  std::istringstream in(text);
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    if (s->add_event(line)) continue;
    // A record cut short by a killed process ends in a partial line: replay up to it.
    if (in.peek() == std::char_traits<char>::eof()) break;
    if (error) *error = "line " + std::to_string(line_no) + " is not a lock-schedule event";
    return nullptr;
  }
  return s;
}

bool LockSchedule::add_event(const std::string& line) {
  std::istringstream fields(line);
  std::string rest;
  if (line[0] == 'F') {
    char f = 0;
    long long us = 0;
    if (!(fields >> f >> us) || (fields >> rest)) return false;
    frames_us_.push_back(us);
    record_has_frames_ = true;
    return true;
  }
  char kind = 0, letter = 0;
  long long value = 0;
  MapParty who{};
  if (!(fields >> kind >> letter >> value) || (fields >> rest) || !party_of(letter, &who) ||
      (kind != 'L' && kind != 'A') || (kind == 'L' && value <= 0))
    return false;
  if (kind == 'L')
    order_.insert(order_.end(), static_cast<std::size_t>(value), who);
  else
    answers_[slot(who)].push_back(value);
  return true;
}

LockSchedule::~LockSchedule() { flush(); }

void LockSchedule::write_run_locked() {
  if (run_length_ == 0 || !out_.is_open()) return;
  out_ << "L " << party_letter(static_cast<MapParty>(run_party_)) << ' ' << run_length_ << '\n';
  run_length_ = 0;
}

void LockSchedule::go_free_locked(std::string why) {
  if (free_) return;
  free_ = true;
  if (turns_ < order_.size()) why_free_ = std::move(why);
  turn_taken_.notify_all();
}

void LockSchedule::before_lock(MapParty who) {
  if (!replaying_) return;
  std::unique_lock<std::mutex> lock(mutex_);
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(kReplayStallS);
  std::size_t seen = turns_;
  while (!free_) {
    if (turns_ >= order_.size()) {
      go_free_locked("");  // the record is followed to its end
      break;
    }
    const MapParty next = order_[turns_];
    if (next == who) return;
    if (retired_[slot(next)]) {
      go_free_locked(std::string("the record's next turn is ") + party_letter(next) +
                     "'s, whose thread has finished");
      break;
    }
    if (turn_taken_.wait_until(lock, deadline) == std::cv_status::timeout) {
      if (turns_ != seen) {  // others progressed: keep waiting
        seen = turns_;
        deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(kReplayStallS);
        continue;
      }
      go_free_locked(std::string("no turn taken for ") + std::to_string(int(kReplayStallS)) +
                     " s: the record's next turn is " + party_letter(next) + "'s, " +
                     party_letter(who) + " waits");
    }
  }
}

void LockSchedule::after_lock(MapParty who) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (replaying_) {
    if (free_) return;
    ++turns_;
    turn_taken_.notify_all();
    return;
  }
  ++turns_;
  if (run_party_ != static_cast<int>(who)) {
    write_run_locked();
    run_party_ = static_cast<int>(who);
  }
  ++run_length_;
}

std::int64_t LockSchedule::answer(MapParty who, std::int64_t live) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (replaying_) {
    if (free_) return live;
    auto& q = answers_[slot(who)];
    if (q.empty()) {
      go_free_locked(std::string("the record has no more answers for ") + party_letter(who));
      return live;
    }
    const std::int64_t v = q.front();
    q.pop_front();
    ++answers_taken_;
    return v;
  }
  write_run_locked();
  if (out_.is_open()) {
    out_ << "A " << party_letter(who) << ' ' << live << '\n';
  }
  ++answers_taken_;
  return live;
}

void LockSchedule::frame(double stamp_s) {
  const auto us = static_cast<std::int64_t>(std::llround(stamp_s * 1e6));
  std::lock_guard<std::mutex> lock(mutex_);
  if (!replaying_) {
    if (!out_.is_open()) return;
    write_run_locked();
    out_ << "F " << us << '\n';
    // Once a frame, outside the map's lock: a killed or still running process leaves a record
    // complete up to its last frame.
    out_.flush();
    ++frames_;
    return;
  }
  if (free_ || !record_has_frames_) return;
  if (frames_us_.empty()) {
    go_free_locked("the replay has more frames than the record (from " + std::to_string(us) +
                   " us)");
    return;
  }
  const std::int64_t recorded = frames_us_.front();
  frames_us_.pop_front();
  if (recorded != us) {
    go_free_locked("the replay's frame " + std::to_string(frames_) + " is stamped " +
                   std::to_string(us) + " us, the record's " + std::to_string(recorded) +
                   " us (a frame missing from the recording or the record)");
    return;
  }
  ++frames_;
}

void LockSchedule::retire(MapParty who) {
  std::lock_guard<std::mutex> lock(mutex_);
  retired_[slot(who)] = true;
  turn_taken_.notify_all();
}

void LockSchedule::flush() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (replaying_ || !out_.is_open()) return;
  write_run_locked();
  out_.flush();
  if (!out_ && error_.empty()) error_ = "lock schedule: writing " + path_ + " failed";
}

LockSchedule::Status LockSchedule::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Status s;
  s.replaying = replaying_;
  s.turns = turns_;
  s.turns_in_file = order_.size();
  s.answers = answers_taken_;
  s.frames = frames_;
  s.left_record = !why_free_.empty();
  s.why_free = why_free_;
  s.error = error_;
  return s;
}

std::string LockSchedule::describe() const {
  const Status s = status();
  std::ostringstream m;
  if (!s.replaying) {
    m << "recorded " << s.frames << " frames, " << s.turns << " map-lock turns and " << s.answers
      << " answers";
    if (!s.error.empty()) m << "; " << s.error;
    return m.str();
  }
  m << "lock-step replay: " << s.turns << " of " << s.turns_in_file << " map-lock turns, "
    << s.answers << " answers and " << s.frames << " frames as recorded";
  if (s.left_record) m << "; then ran free: " << s.why_free;
  return m.str();
}

}  // namespace rgbdquad::slam
