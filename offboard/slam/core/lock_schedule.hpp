// Lock-step record and replay of the threads that share the SLAM map.
//
// In real time (PipelineMode::kLive, kRealtime) tracking, local mapping and loop closing take the
// map's lock in an order set by the machine's timing, and two answers that depend on timing steer
// them: how many keyframes the mapper holds when the tracker decides on a keyframe (keyframe
// admission), and whether a keyframe waits when the mapper decides to cut its work short (catch-up,
// an interrupted bundle adjustment). Everything else a thread does between two lock acquisitions
// depends only on the frames and on the map it read. So the order of the acquisitions plus the
// answers, recorded in flight, replay the run exactly: the same frames through the same binary,
// with each thread let into the map only when the record says it was its turn, give the same poses
// bit for bit, on any machine and at any speed.
//
// Recording costs one mutex and a few bytes per lock acquisition (a line per run of acquisitions by
// one thread, a line per frame with its stamp) and one write to the file per frame, so that the
// record of a killed or still running process is complete up to its last frame.
//
// A replay whose threads stop following the record (other frames, another binary, another
// configuration) would wait forever for a turn that never comes: after kReplayStallS without
// progress, or when the record runs out, the replay lets every thread run free and says so
// (status()); the poses from there on are an ordinary run's.
//
// Thread safety: every member may be called from any thread.
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <fstream>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace rgbdquad::slam {

/// The threads that share the map (the checkpoint writer and reports only read it: not scheduled).
enum class MapParty : std::uint8_t { kTracking = 0, kMapping = 1, kLoopClosing = 2 };
inline constexpr std::size_t kMapParties = 3;
/// One letter per party in the file.
char party_letter(MapParty p);

class LockSchedule {
 public:
  /// A replay stalled this long without a turn taken has left the record (a thread waits for a
  /// turn of a thread that will not take it). The longest legitimate wait is one loop correction
  /// or one bundle adjustment on a loaded machine, a few seconds.
  static constexpr double kReplayStallS = 20.0;

  /// Records to `path` (created or truncated). nullptr with `error` if it cannot be written.
  static std::unique_ptr<LockSchedule> recorder(const std::string& path, std::string* error);
  /// Replays the record in `path`. nullptr with `error` naming the line if it is unreadable.
  static std::unique_ptr<LockSchedule> replayer(const std::string& path, std::string* error);
  /// From text already read (tests, the replayer).
  static std::unique_ptr<LockSchedule> replayer_from_text(const std::string& text,
                                                          std::string* error);
  ~LockSchedule();
  LockSchedule(const LockSchedule&) = delete;
  LockSchedule& operator=(const LockSchedule&) = delete;

  /// Call before locking the map: in replay, waits until it is `who`'s turn.
  void before_lock(MapParty who);
  /// Call with the map's lock held: records the acquisition, or passes the turn on.
  void after_lock(MapParty who);
  /// A timing-dependent answer: records `live` and returns it, or returns the recorded one.
  std::int64_t answer(MapParty who, std::int64_t live);
  /// Tracking is about to track the frame stamped `stamp_s`: recorded (to the microsecond), or, in
  /// replay, checked against the record's next frame. A frame the recording lacks (a recorder that
  /// dropped its images) or has extra would otherwise go unnoticed while the turns still line up:
  /// the replay runs free from there and says which frame. Records without frames are not checked.
  void frame(double stamp_s);
  /// `who` takes no more turns (its thread finished): a replay waiting for its turn runs free.
  void retire(MapParty who);
  /// Writes what is buffered (recording).
  void flush();

  struct Status {
    bool replaying = false;
    std::size_t turns = 0;          ///< recorded, or replayed in lock-step
    std::size_t turns_in_file = 0;  ///< replay: the record's total
    std::size_t answers = 0;        ///< recorded, or taken from the record
    std::size_t frames = 0;         ///< frames recorded, or checked against the record
    bool left_record = false;       ///< replay: ran free before the record's end
    std::string why_free;           ///< replay: why it ran free (empty: followed to the end)
    std::string error;              ///< recording: the file could not be written
  };
  Status status() const;
  /// One line for summaries and logs.
  std::string describe() const;

 private:
  LockSchedule() = default;
  /// Replay: adds one line of a record; false if it is not an event.
  bool add_event(const std::string& line);
  void write_run_locked();
  void go_free_locked(std::string why);

  mutable std::mutex mutex_;
  std::condition_variable turn_taken_;
  bool replaying_ = false;
  // Recording.
  std::ofstream out_;
  std::string path_;
  int run_party_ = -1;
  std::size_t run_length_ = 0;
  // Replay.
  std::vector<MapParty> order_;
  std::array<std::deque<std::int64_t>, kMapParties> answers_;
  std::array<bool, kMapParties> retired_{};
  std::deque<std::int64_t> frames_us_;
  bool record_has_frames_ = false;
  bool free_ = false;
  // Both.
  std::size_t turns_ = 0, answers_taken_ = 0, frames_ = 0;
  std::string why_free_, error_;
};

}  // namespace rgbdquad::slam
