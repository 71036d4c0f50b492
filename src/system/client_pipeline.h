#pragma once
// One client inside the collaborative system: a bounded frame queue and the worker thread that
// drains it into the client's SLAM (or, with run_slam off, only counts frames). A live frame with
// a newer frame of the same client queued behind it is skipped (counted, reported as skipped), so
// a worker that falls behind catches up with the camera instead of processing stale frames; while
// it is behind, its SLAM may track frames by optical flow (FlowMode::kUnderLoad), which costs a
// fraction of a full frame, so that fewer frames are skipped.
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "core/fifo_slots.h"
#include "core/bounded_queue.h"
#include "core/log.h"
#include "slam/client_slam.h"
#include "system/collaborative_system.h"

namespace cslam {

class ClientPipeline {
 public:
  // `group_of` names the fused group of one of this client's maps (invalid: none yet); it is called
  // on the worker thread and must not lock the system's client table.
  ClientPipeline(const ClientInfo& info, const SystemConfig& config, std::shared_ptr<const Vocabulary> vocabulary,
                 KeyFrameListener listener, std::function<GroupId(const Map*)> group_of = {},
                 FifoSlots* tracking_slots = nullptr);
  ~ClientPipeline();

  // Stepped (SystemConfig::stepped): the frame is processed before submit returns.
  // Blocks while the queue is full. False once finishing.
  bool submit(RgbdFrame frame);
  // Drains the queue, stops the worker and the SLAM threads. Idempotent.
  void finish();

  ClientSnapshot snapshot() const;
  // Every frame of the client's maps that share the fused group holding most of its frames (a
  // map started after a long loss counts once fusion has joined it), in that group's frame.
  Trajectory trajectory() const;
  Trajectory keyframe_trajectory() const;
  const ClientInfo& info() const { return info_; }
  ClientSlam* slam() { return slam_.get(); }
  ClientSlamTimings timings() const;

  // The next frame starts a new session (ClientSlam::start_new_session on the worker thread).
  void start_new_session() { new_session_ = true; }

 private:
  using Clock = std::chrono::steady_clock;
  void run();
  FrameDone process(const RgbdFrame& frame, WorkerLoad load = WorkerLoad::kKeepingUp);
  // process() with the worker's CPU time (and, when tracing, its wait for a core) kept for report().
  FrameDone process_timed(const RgbdFrame& frame, WorkerLoad load = WorkerLoad::kKeepingUp);
  // `started`: when the worker began this frame; `slot_ms`: how long it waited for a slot first.
  // Nothing more goes out for a frame whose pose on_early_pose sent.
  void report(FrameDone done, const RgbdFrame& frame, Clock::time_point started = {}, double slot_ms = 0);
  // ClientSlam's early pose of the current frame (a new keyframe's, before local mapping's wait).
  void on_early_pose(const ClientSlam::FramePose& pose, std::uint64_t map_epoch, int keyframe_due_in);
  // The frame's latency and parts recorded, then config_.on_frame_done.
  void publish(FrameDone& done, const RgbdFrame& frame, Clock::time_point started, double slot_ms,
               double mapping_wait_ms, double work_cpu_ms);
  GroupId group_of_map(const std::vector<std::shared_ptr<Map>>& maps, int map) const;

  static constexpr std::size_t kLatencyWindow = 512;  // frames kept for the latency percentiles

  const ClientInfo info_;
  const SystemConfig& config_;
  std::function<GroupId(const Map*)> group_of_;
  FifoSlots* tracking_slots_;         // shared by the system's workers (nullptr: no limit)
  FifoSlots::Hold* slot_ = nullptr;   // the worker's slot for its current frame (worker thread only)
  std::unique_ptr<ClientSlam> slam_;  // null when run_slam is off
  BoundedQueue<RgbdFrame> queue_;
  std::shared_ptr<spdlog::logger> latency_log_;  // per-frame parts at trace level
  mutable std::mutex mutex_;
  ClientSnapshot counters_;
  Trajectory counted_trajectory_;  // run_slam off: timestamps with identity poses
  std::atomic<bool> new_session_{false};
  std::vector<double> latency_ms_;                           // ring of the last kLatencyWindow frames
  std::vector<ClientSnapshot::LatencyParts> latency_parts_;  // the same frames' parts
  std::size_t latency_next_ = 0;
  double mapping_wait_ms_ = 0;   // the current frame's wait for local mapping (worker thread only)
  double done_cpu_ms_ = 0;       // the worker's CPU time for its last processed frame (worker thread only)
  double done_runqueue_ms_ = 0;  // ... and its time waiting for a core (traced only)
  Clock::time_point mapping_wait_start_;
  // The frame being processed, for on_early_pose (worker thread only).
  struct Current {
    const RgbdFrame* frame = nullptr;
    Clock::time_point started;
    double slot_ms = 0;
    double cpu_started_ms = 0;
    double runqueue_started_ms = 0;  // when tracing
    bool pose_sent = false;
  } current_;
  std::thread thread_;
};

}  // namespace cslam
