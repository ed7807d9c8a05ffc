// The real SLAM pipeline behind SessionPipeline (slam_link_session.hpp): slam-server's sessions.
#include <memory>
#include <string>
#include <utility>

#include "slam/report/run_tables.hpp"
#include "slam_link_session.hpp"

namespace rgbdquad::slamlink {

namespace {

class LivePipeline final : public SessionPipeline {
 public:
  /// A kLive record is final when submit() returns and the session reads it at once: one second at
  /// 30 fps is held for record() lookups, older records go to frames.csv (or are dropped without
  /// tables), so a flight's memory does not grow per frame (was ~0.8 MiB a minute at 30 fps).
  static constexpr std::size_t kRetainedRecords = 30;

  explicit LivePipeline(std::unique_ptr<slam::Pipeline> pipeline) : pipeline_(std::move(pipeline)) {
    pipeline_->retire_records(kRetainedRecords, [this](const slam::FrameRecord& r) {
      if (frames_) frames_->append(r);
    });
  }
  void submit(slam::RgbdFrame frame) override { pipeline_->submit(std::move(frame)); }
  std::optional<slam::FrameRecord> record(std::int64_t index) const override {
    return pipeline_->record(index);
  }
  bool load_map(const std::string& path, std::string* error) override {
    return pipeline_->load_map(path, error);
  }
  bool save_map(const std::string& path, std::string* error) const override {
    return pipeline_->save_map(path, error);
  }
  void finish() override { pipeline_->finish(); }
  slam::PipelineSummary summary() const override { return pipeline_->summary(); }
  bool start_tables(const std::string& dir, std::string* error) override {
    tables_dir_ = dir;
    frames_ = slam::FramesTable::create(std::filesystem::path(dir) / "frames.csv", error);
    return frames_.has_value();
  }
  bool finish_tables(std::string* error) override {
    if (!frames_) {
      if (error) *error = "the tables were not started";
      return false;
    }
    for (const slam::FrameRecord& r : pipeline_->records()) frames_->append(r);
    const bool frames_ok = frames_->close(error);
    frames_.reset();
    return frames_ok && slam::write_keyframe_tables(tables_dir_, pipeline_->mapper_stats(),
                                                    pipeline_->loop_stats(), nullptr, error);
  }

 private:
  // Declared before the pipeline so that they outlive it: the pipeline's threads may still retire
  // records into frames_ while it is destroyed.
  std::string tables_dir_;
  std::optional<slam::FramesTable> frames_;
  std::unique_ptr<slam::Pipeline> pipeline_;
};

}  // namespace

PipelineFactory live_pipeline_factory() {
  return [](const slam::PipelineOptions& options, const slam::Intrinsics& intrinsics,
            std::string* error) -> std::unique_ptr<SessionPipeline> {
    auto pipeline = slam::Pipeline::create(options, intrinsics, error);
    if (!pipeline) return nullptr;
    return std::make_unique<LivePipeline>(std::move(pipeline));
  };
}

}  // namespace rgbdquad::slamlink
