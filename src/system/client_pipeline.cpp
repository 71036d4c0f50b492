#include "system/client_pipeline.h"

#include "core/log.h"
#include "core/thread_priority.h"

namespace cslam {

ClientPipeline::ClientPipeline(const ClientInfo& info, const SystemConfig& config, std::shared_ptr<const Vocabulary> vocabulary,
                               KeyFrameListener listener)
    : info_(info), config_(config), queue_(config.client_queue_capacity) {
  if (config_.run_slam) slam_ = std::make_unique<ClientSlam>(info_, config_.slam, std::move(vocabulary), std::move(listener));
  counters_.id = info_.id;
  counters_.name = info_.name;
  counters_.group = info_.id;
  // Stepped SLAM (config.slam.threaded off): frames are processed inside submit(), in order.
  if (config_.slam.threaded) thread_ = std::thread([this] { run(); });
}

ClientPipeline::~ClientPipeline() { finish(); }

bool ClientPipeline::submit(RgbdFrame frame) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.frames_submitted;
  }
  if (!config_.slam.threaded) {
    if (queue_.closed()) return false;
    consume(frame);
    return true;
  }
  return queue_.push(std::move(frame));
}

void ClientPipeline::finish() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
  if (slam_) slam_->finish();
}

void ClientPipeline::run() {
  lower_current_thread_priority();
  while (auto frame = queue_.pop()) consume(*frame);
}

void ClientPipeline::consume(const RgbdFrame& frame) {
  if (slam_) {
    if (new_session_.exchange(false)) slam_->start_new_session();
    const ProcessResult r = slam_->process(frame);
    if (r.outcome == FrameOutcome::kRejected)
      logger("system")->warn("client {} frame {} rejected: {}", info_.id, frame.seq, r.reject_reason);
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.frames_processed;
    if (r.outcome == FrameOutcome::kRejected) ++counters_.frames_rejected;
    counters_.last_timestamp = frame.timestamp;
  } else {
    std::lock_guard<std::mutex> lock(mutex_);
    counted_trajectory_.push_back({frame.timestamp, SE3()});
    ++counters_.frames_processed;
    counters_.tracking = TrackingState::kTracking;
    counters_.last_timestamp = frame.timestamp;
  }
  if (config_.on_frame_done) config_.on_frame_done(frame.client, frame.seq);
}

ClientSnapshot ClientPipeline::snapshot() const {
  ClientSnapshot s;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    s = counters_;
  }
  s.queue_depth = queue_.size();
  if (slam_) {
    const ClientSlamSnapshot q = slam_->snapshot();
    s.tracking = q.state == TrackState::kOk ? TrackingState::kTracking
                 : q.state == TrackState::kLost ? TrackingState::kLost
                                                : TrackingState::kNotInitialized;
    s.keyframes = q.keyframes;
    s.map_points = q.map_points;
    s.T_world_cam = q.T_world_cam;
    s.frames_lost = q.frames_lost;
    s.maps = q.maps;
  }
  return s;
}

Trajectory ClientPipeline::trajectory() const {
  if (slam_) return slam_->trajectory();
  std::lock_guard<std::mutex> lock(mutex_);
  return counted_trajectory_;
}

Trajectory ClientPipeline::keyframe_trajectory() const { return slam_ ? slam_->keyframe_trajectory() : Trajectory{}; }

ClientSlamTimings ClientPipeline::timings() const { return slam_ ? slam_->timings() : ClientSlamTimings{}; }

}  // namespace cslam
