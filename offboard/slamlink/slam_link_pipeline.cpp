// The real SLAM pipeline behind SessionPipeline (slam_link_session.hpp): slam-server's sessions.
#include <memory>
#include <string>
#include <utility>

#include "slam/report/run_tables.hpp"
#include "slam_link_session.hpp"

namespace slam {

namespace {

class LivePipeline final : public SessionPipeline {
 public:
  explicit LivePipeline(std::unique_ptr<Pipeline> pipeline) : pipeline_(std::move(pipeline)) {}
  void submit(RgbdFrame frame) override { pipeline_->submit(std::move(frame)); }
  std::optional<FrameRecord> record(std::int64_t index) const override {
    return pipeline_->record(index);
  }
  bool load_map(const std::string& path, std::string* error) override {
    return pipeline_->load_map(path, error);
  }
  bool save_map(const std::string& path, std::string* error) const override {
    return pipeline_->save_map(path, error);
  }
  void finish() override { pipeline_->finish(); }
  PipelineSummary summary() const override { return pipeline_->summary(); }
  bool write_tables(const std::string& dir, std::string* error) const override {
    return write_run_tables(dir, pipeline_->records(), pipeline_->mapper_stats(),
                            pipeline_->loop_stats(), {}, error);
  }

 private:
  std::unique_ptr<Pipeline> pipeline_;
};

}  // namespace

PipelineFactory live_pipeline_factory() {
  return [](const PipelineOptions& options, const Intrinsics& intrinsics,
            std::string* error) -> std::unique_ptr<SessionPipeline> {
    auto pipeline = Pipeline::create(options, intrinsics, error);
    if (!pipeline) return nullptr;
    return std::make_unique<LivePipeline>(std::move(pipeline));
  };
}

}  // namespace slam
