#pragma once
// One client inside the collaborative system: a bounded frame queue and the worker thread that
// drains it into the client's SLAM (or, with run_slam off, only counts frames).
#include <atomic>
#include <memory>
#include <mutex>
#include <thread>

#include "core/bounded_queue.h"
#include "slam/client_slam.h"
#include "system/collaborative_system.h"

namespace cslam {

class ClientPipeline {
 public:
  ClientPipeline(const ClientInfo& info, const SystemConfig& config, std::shared_ptr<const Vocabulary> vocabulary,
                 KeyFrameListener listener);
  ~ClientPipeline();

  // Blocks while the queue is full. False once finishing. With stepped SLAM (SlamConfig::threaded
  // off) the frame is processed before it returns.
  bool submit(RgbdFrame frame);
  // Drains the queue, stops the worker and the SLAM threads. Idempotent.
  void finish();

  ClientSnapshot snapshot() const;
  Trajectory trajectory() const;
  Trajectory keyframe_trajectory() const;
  const ClientInfo& info() const { return info_; }
  ClientSlam* slam() { return slam_.get(); }
  ClientSlamTimings timings() const;
  // The next frame starts a new session (ClientSlam::start_new_session on the worker thread).
  void start_new_session() { new_session_ = true; }

 private:
  void run();
  void consume(const RgbdFrame& frame);  // one frame into SLAM (or the counters), then on_frame_done

  const ClientInfo info_;
  const SystemConfig& config_;
  std::unique_ptr<ClientSlam> slam_;  // null when run_slam is off
  BoundedQueue<RgbdFrame> queue_;
  mutable std::mutex mutex_;
  ClientSnapshot counters_;
  Trajectory counted_trajectory_;  // run_slam off: timestamps with identity poses
  std::atomic<bool> new_session_{false};
  std::thread thread_;
};

}  // namespace cslam
