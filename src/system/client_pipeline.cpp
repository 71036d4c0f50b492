#include "system/client_pipeline.h"

#include <algorithm>
#include <cstdio>
#include <shared_mutex>
#include <utility>

#include "core/log.h"
#include "core/stopwatch.h"
#include "core/thread_priority.h"

namespace cslam {

namespace {

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, std::size_t(p * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + long(k), v.end());
  return v[k];
}

// Time the calling thread has waited for a core so far (Linux schedstat), ms; 0 if unknown.
double thread_runqueue_ms() {
  std::FILE* f = std::fopen("/proc/thread-self/schedstat", "r");
  if (!f) return 0;
  unsigned long long run = 0, wait = 0;
  const int n = std::fscanf(f, "%llu %llu", &run, &wait);
  std::fclose(f);
  return n == 2 ? double(wait) * 1e-6 : 0;
}

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

ClientPipeline::ClientPipeline(const ClientInfo& info, const SystemConfig& config,
                               std::shared_ptr<const Vocabulary> vocabulary, KeyFrameListener listener,
                               std::function<GroupId(const Map*)> group_of, FifoSlots* tracking_slots)
    : info_(info),
      config_(config),
      group_of_(std::move(group_of)),
      tracking_slots_(tracking_slots),
      queue_(config.client_queue_capacity),
      latency_log_(logger("latency")) {
  if (config_.run_slam)
    slam_ = std::make_unique<ClientSlam>(info_, config_.slam, std::move(vocabulary), std::move(listener));
  if (slam_)  // on the worker thread, inside process(): slot_ is its frame's
    slam_->set_tracking_wait_hooks({[this] {
                                      mapping_wait_start_ = Clock::now();
                                      if (slot_) slot_->lend();
                                    },
                                    [this] {
                                      if (slot_) slot_->take_back();
                                      mapping_wait_ms_ += ms_since(mapping_wait_start_);
                                    }});
  if (slam_)
    slam_->set_early_pose_listener([this](const ClientSlam::FramePose& pose, std::uint64_t map_epoch,
                                          int keyframe_due_in) { on_early_pose(pose, map_epoch, keyframe_due_in); });
  counters_.id = info_.id;
  counters_.name = info_.name;
  counters_.group = GroupId::from_value(info_.id);  // until the first frame reports its group
  latency_ms_.reserve(kLatencyWindow);
  latency_parts_.reserve(kLatencyWindow);
  // Stepped (config.stepped): frames are processed inside submit(), in order.
  if (!config_.stepped) thread_ = std::thread([this] { run(); });
}

ClientPipeline::~ClientPipeline() { finish(); }

bool ClientPipeline::submit(RgbdFrame frame) {
  if (frame.received == std::chrono::steady_clock::time_point{}) frame.received = std::chrono::steady_clock::now();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.frames_submitted;
  }
  if (config_.stepped) {
    if (queue_.closed()) return false;
    current_ = {&frame, frame.received};
    report(process_timed(frame), frame);
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
  name_current_thread("track/c" + std::to_string(info_.id));
  lower_current_thread_priority();
  // Until then the worker counts as behind (overloaded) its live frames (WorkerLoad).
  std::chrono::steady_clock::time_point behind_until{}, overloaded_until{};
  while (auto frame = queue_.pop()) {
    // The slot first: the frames that arrive while this worker waits for it are skipped below.
    const auto popped = Clock::now();
    FifoSlots::Hold slot(tracking_slots_);
    slot_ = &slot;
    const double slot_ms = tracking_slots_ ? ms_since(popped) : 0;
    // Live: only the newest queued frame is worth processing; older ones are skipped (acked). A
    // frame with full depth (a possible keyframe) gives way only to a newer such frame.
    bool skipped_any = false;
    while (frame->live) {
      auto newer = !frame->keyframe_eligible()
                       ? queue_.try_pop()
                       : queue_.try_pop_if([](const RgbdFrame& f) { return f.keyframe_eligible(); });
      if (!newer) break;
      FrameDone skipped;
      skipped.fate = FrameFate::kSkipped;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        ++counters_.frames_skipped;
      }
      report(skipped, *frame);
      frame = std::move(newer);
      skipped_any = true;
    }
    // A skipped frame or a frame still waiting: behind; a frame skipped while already behind:
    // overloaded. Each holds for a while (config), so that the cheaper frames that let the worker
    // catch up do not switch themselves off at once.
    const auto now = std::chrono::steady_clock::now();
    const auto hold = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(config_.behind_hold_s));
    if (frame->live && skipped_any && now < behind_until) overloaded_until = now + hold;
    if (frame->live && (skipped_any || queue_.size() > 0)) behind_until = now + hold;
    const WorkerLoad load = !frame->live || now >= behind_until ? WorkerLoad::kKeepingUp
                            : now < overloaded_until            ? WorkerLoad::kOverloaded
                                                                : WorkerLoad::kBehind;
    const auto started = Clock::now();
    current_ = {&*frame, started, skipped_any ? 0 : slot_ms};
    report(process_timed(*frame, load), *frame, started, current_.slot_ms);
  }
}

FrameDone ClientPipeline::process_timed(const RgbdFrame& frame, WorkerLoad load) {
  const double cpu_started = thread_cpu_ms();
  current_.cpu_started_ms = cpu_started;
  const bool tracing = latency_log_->should_log(spdlog::level::trace);
  const double runqueue_started = tracing ? thread_runqueue_ms() : 0;
  current_.runqueue_started_ms = runqueue_started;
  FrameDone done = process(frame, load);
  done_cpu_ms_ = thread_cpu_ms() - cpu_started;
  done_runqueue_ms_ = tracing ? thread_runqueue_ms() - runqueue_started : 0;
  return done;
}

FrameDone ClientPipeline::process(const RgbdFrame& frame, WorkerLoad load) {
  FrameDone done;
  if (!slam_) {
    std::lock_guard<std::mutex> lock(mutex_);
    counted_trajectory_.push_back({frame.timestamp, SE3()});
    ++counters_.frames_processed;
    counters_.tracking = FrameFate::kTracked;
    counters_.last_timestamp = frame.timestamp;
    done.fate = FrameFate::kTracked;
    done.has_pose = true;  // identity: the counting-only pipeline's trajectory
    return done;
  }
  if (new_session_.exchange(false)) slam_->start_new_session();
  mapping_wait_ms_ = 0;
  const ProcessResult r = slam_->process(frame, load);
  done.wants_depth = r.wants_depth;
  done.keyframe_due_in = r.keyframe_due_in;
  if (r.keyframe && config_.on_keyframe) config_.on_keyframe(info_, *r.keyframe, frame, r.T_cam_depthcam);
  if (r.fate == FrameFate::kRejected)
    logger("system")->warn("client {} frame {} rejected: {}", info_.id, frame.seq, r.reject_reason);
  done.fate = r.fate;
  if (done.fate == FrameFate::kTracked) {
    // The same computation as the frame's trajectory entry; a frame that did not make it into
    // the trajectory gets no pose (never the previous frame's).
    if (const auto pose = slam_->last_frame_pose(frame.timestamp)) {
      done.has_pose = true;
      done.T_world_cam = pose->T_world_cam;
      done.map = pose->map_index;
    } else {
      done.fate = FrameFate::kLost;
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.frames_processed;
  if (r.fate == FrameFate::kRejected) ++counters_.frames_rejected;
  counters_.last_timestamp = frame.timestamp;
  return done;
}

void ClientPipeline::report(FrameDone done, const RgbdFrame& frame, Clock::time_point started, double slot_ms) {
  if (std::exchange(current_.pose_sent, false)) return;  // on_early_pose sent this frame's
  if (slam_) {
    // Group and epoch of the map the frame belongs to (the current map when it has no pose).
    if (!done.has_pose) done.map = slam_->snapshot().current_map;
    done.map_epoch = slam_->map_epoch();
    done.group = group_of_map(slam_->maps(), done.map);
  } else {
    done.group = GroupId::from_value(info_.id);  // counting-only pipeline
  }
  const bool skipped = done.fate == FrameFate::kSkipped;
  publish(done, frame, started, slot_ms, skipped ? 0 : mapping_wait_ms_, skipped ? 0 : done_cpu_ms_);
}

void ClientPipeline::on_early_pose(const ClientSlam::FramePose& pose, std::uint64_t map_epoch, int keyframe_due_in) {
  if (!current_.frame) return;
  FrameDone done;
  done.fate = FrameFate::kTracked;
  done.has_pose = true;
  done.T_world_cam = pose.T_world_cam;
  done.map = pose.map_index;
  done.map_epoch = map_epoch;
  done.group = group_of_map(slam_->maps(), pose.map_index);
  done.keyframe_due_in = keyframe_due_in;
  if (latency_log_->should_log(spdlog::level::trace))
    done_runqueue_ms_ = thread_runqueue_ms() - current_.runqueue_started_ms;  // so far (the trace line)
  publish(done, *current_.frame, current_.started, current_.slot_ms, mapping_wait_ms_,
          thread_cpu_ms() - current_.cpu_started_ms);
  current_.pose_sent = true;
}

GroupId ClientPipeline::group_of_map(const std::vector<std::shared_ptr<Map>>& maps, int map) const {
  const GroupId g = map >= 0 && std::size_t(map) < maps.size() && group_of_ ? group_of_(maps[map].get()) : GroupId();
  return g.valid() ? g : GroupId::of_map(info_.id, 0);
}

void ClientPipeline::publish(FrameDone& done, const RgbdFrame& frame, Clock::time_point started, double slot_ms,
                             double mapping_wait_ms, double work_cpu_ms) {
  done.client = frame.client;
  done.seq = frame.seq;
  done.timestamp = frame.timestamp;
  const auto now = Clock::now();
  done.server_ms = std::chrono::duration<double, std::milli>(now - frame.received).count();
  // Stepped: processed inside submit (no queue, no slot).
  if (started == Clock::time_point{}) started = frame.received;
  ClientSnapshot::LatencyParts parts;
  if (frame.arrived != Clock::time_point{})
    parts.decode_ms = std::chrono::duration<double, std::milli>(frame.received - frame.arrived).count();
  parts.slot_ms = slot_ms;
  parts.queue_ms = std::max(0.0, std::chrono::duration<double, std::milli>(started - frame.received).count() - slot_ms);
  parts.mapping_wait_ms = mapping_wait_ms;
  parts.work_ms = std::max(0.0, std::chrono::duration<double, std::milli>(now - started).count() - mapping_wait_ms);
  parts.work_cpu_ms = work_cpu_ms;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    done.frames_skipped = counters_.frames_skipped;
    if (done.fate != FrameFate::kSkipped) {
      if (latency_ms_.size() < kLatencyWindow) {
        latency_ms_.push_back(done.server_ms);
        latency_parts_.push_back(parts);
      } else {
        latency_ms_[latency_next_] = done.server_ms;
        latency_parts_[latency_next_] = parts;
      }
      latency_next_ = (latency_next_ + 1) % kLatencyWindow;
      counters_.pose_latency_last_ms = done.server_ms;
    }
  }
  if (done.fate != FrameFate::kSkipped)
    latency_log_->trace(
        "client {} frame {}: {:.1f} ms from arrival (decode {:.1f}, queue {:.1f}, slot {:.1f}, "
        "mapping wait {:.1f}, work {:.1f}, of it CPU {:.1f}, waiting for a core {:.1f})",
        info_.id, frame.seq, parts.decode_ms + done.server_ms, parts.decode_ms, parts.queue_ms, parts.slot_ms,
        parts.mapping_wait_ms, parts.work_ms, parts.work_cpu_ms, done_runqueue_ms_);
  if (config_.on_frame_done) config_.on_frame_done(done);
}

ClientSnapshot ClientPipeline::snapshot() const {
  ClientSnapshot s;
  std::vector<double> latencies;
  std::vector<ClientSnapshot::LatencyParts> parts;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    s = counters_;
    latencies = latency_ms_;
    parts = latency_parts_;
  }
  s.pose_latency_samples = latencies.size();
  s.pose_latency_p50_ms = percentile(latencies, 0.5);
  s.pose_latency_p99_ms = percentile(latencies, 0.99);
  const auto p99_of = [&parts](double ClientSnapshot::LatencyParts::*part) {
    std::vector<double> v;
    v.reserve(parts.size());
    for (const auto& p : parts) v.push_back(p.*part);
    return percentile(std::move(v), 0.99);
  };
  using Parts = ClientSnapshot::LatencyParts;
  for (double Parts::*part : {&Parts::decode_ms, &Parts::queue_ms, &Parts::slot_ms, &Parts::mapping_wait_ms,
                              &Parts::work_ms, &Parts::work_cpu_ms})
    s.pose_latency_parts_p99.*part = p99_of(part);
  s.queue_depth = queue_.size();
  if (slam_) {
    const ClientSlamSnapshot q = slam_->snapshot();
    s.tracking = q.state;
    s.keyframes = q.keyframes;
    s.map_points = q.map_points;
    s.T_world_cam = q.T_world_cam;
    s.frames_lost = q.frames_lost;
    s.frames_flow = q.frames_flow;
    s.maps = q.maps;
  }
  return s;
}

Trajectory ClientPipeline::trajectory() const {
  if (slam_) return slam_->trajectory(group_of_);
  std::lock_guard<std::mutex> lock(mutex_);
  return counted_trajectory_;
}

Trajectory ClientPipeline::keyframe_trajectory() const {
  return slam_ ? slam_->keyframe_trajectory(group_of_) : Trajectory{};
}

ClientSlamTimings ClientPipeline::timings() const { return slam_ ? slam_->timings() : ClientSlamTimings{}; }

}  // namespace cslam
