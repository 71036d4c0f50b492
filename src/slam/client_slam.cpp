#include "slam/client_slam.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <optional>
#include <shared_mutex>

#include <opencv2/imgproc.hpp>

#include "core/log.h"
#include "core/stopwatch.h"
#include "frame/frame_check.h"
#include "slam/loop/global_ba.h"
#include "slam/map/map_locks.h"
#include "slam/map_frames.h"

namespace cslam {

ClientSlam::ClientSlam(ClientInfo info, SlamConfig config, std::shared_ptr<const Vocabulary> vocabulary,
                       KeyFrameListener listener)
    : info_(std::move(info)),
      config_(std::move(config)),
      vocabulary_(std::move(vocabulary)),
      extractor_(config_.orb),
      pyramid_(ScalePyramid::from(extractor_)),
      ids_(std::make_shared<IdAllocator>(info_.id)),
      listener_(std::move(listener)) {
  if (!vocabulary_ || vocabulary_->empty()) throw std::invalid_argument("ClientSlam needs a loaded vocabulary");
  info_.camera.validate();
  config_.tracker.flow.validate();
  start_new_map();
}

ClientSlam::~ClientSlam() { finish(); }

std::unique_ptr<LocalMapper> ClientSlam::attach_workers(const std::shared_ptr<Map>& map) {
  if (mapper_) mapper_->finish();
  if (loop_closer_) loop_closer_->finish();
  auto mapper = std::make_unique<LocalMapper>(config_.mapper, map, config_.threaded);
  loop_closer_ = std::make_unique<LoopCloser>(config_.loop, map, config_.threaded);
  const ClientId client = info_.id;
  std::weak_ptr<Map> weak = map;
  LoopCloser* loop = loop_closer_.get();
  mapper->set_wait_hooks(wait_hooks_);
  mapper->set_on_processed([this, client, weak, loop](const KeyFramePtr& kf) {
    loop->insert_keyframe(kf);
    if (listener_)
      if (auto m = weak.lock()) listener_(client, m, kf);
  });
  return mapper;
}

void ClientSlam::set_tracking_wait_hooks(TrackingWaitHooks hooks) {
  wait_hooks_ = std::move(hooks);
  if (mapper_) mapper_->set_wait_hooks(wait_hooks_);
}

void ClientSlam::set_early_pose_listener(EarlyPoseListener listener) {
  early_pose_listener_ = std::move(listener);
  tracker_->set_pose_listener([this](const Tracker::TrackedPose& tracked) { publish_early_pose(tracked); });
}

void ClientSlam::publish_early_pose(const Tracker::TrackedPose& tracked) {
  if (!early_pose_listener_) return;
  FramePose pose;
  std::uint64_t epoch = 0;
  {
    // The order trajectory() takes: the records, then every map shared.
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<Map*> ptrs;
    for (const auto& m : maps_) ptrs.push_back(m.get());
    const auto map_locks = lock_maps<std::shared_lock<std::shared_mutex>>(ptrs);
    const Map& map = *tracker_->map();
    if (map.big_change_index() != tracked.change_index) return;
    // The frame's record now (process() replaces it with the keyframe as reference, the same pose).
    records_.push_back({tracked.timestamp, tracked.reference, tracked.T_cam_ref, map.index()});
    const LiveReference ref = live_reference(records_.back());
    if (!ref.keyframe) {
      records_.pop_back();
      return;
    }
    pose = {ref.T_world_cam(), map.index()};
    epoch = map_epoch_locked(ptrs);
  }
  early_pose_listener_(pose, epoch, tracked.keyframe_due_in);
}

std::uint64_t ClientSlam::map_epoch_locked(const std::vector<Map*>& maps) {
  std::uint64_t epoch = 0;
  for (const Map* m : maps) epoch += m->big_change_index();
  return epoch;
}

std::uint64_t ClientSlam::map_epoch() const {
  std::vector<Map*> ptrs;
  for (const auto& m : maps()) ptrs.push_back(m.get());
  const auto map_locks = lock_maps<std::shared_lock<std::shared_mutex>>(ptrs);
  return map_epoch_locked(ptrs);
}

void ClientSlam::start_new_map() {
  auto map = std::make_shared<Map>(info_.id, int(maps_.size()), ids_);
  std::unique_ptr<LocalMapper> mapper = attach_workers(map);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    maps_.push_back(map);
  }
  if (tracker_)
    tracker_->reset(map, mapper.get());
  else
    tracker_ = std::make_unique<Tracker>(config_.tracker, map, mapper.get());
  mapper_ = std::move(mapper);
  if (maps_.size() > 1)
    logger("slam")->warn("client {}: tracking lost for long, started map {}", info_.id, maps_.size() - 1);
}

ProcessResult ClientSlam::process(const RgbdFrame& frame, WorkerLoad load) {
  ProcessResult r;
  const auto& cam = info_.camera;
  auto reject = [&](std::string why) {
    r.fate = FrameFate::kRejected;
    r.reject_reason = std::move(why);
    std::lock_guard<std::mutex> lock(mutex_);
    ++snapshot_.frames_rejected;
    return r;
  };
  assert(frame_problem(frame, info_.camera).empty());  // checked where the frame was built (frame/frame_check.h)
  if (finished_) return reject("worker finished");
  if (frame.timestamp <= last_timestamp_)
    return reject("timestamp " + std::to_string(frame.timestamp) + " does not increase");
  last_timestamp_ = frame.timestamp;

  Stopwatch sw;
  // Where the camera moved between the colour and the depth image (none known: read in place).
  const std::optional<SE3> T_depthcam_motion = frame.depth_time_offset != 0 && !frame.depth.empty()
                                                   ? tracker_->predicted_motion(frame.depth_time_offset)
                                                   : std::nullopt;
  const std::optional<SE3> T_depthcam_cam = config_.rgbd.depth_time_compensation && frame.depth_time_offset != 0
                                                ? tracker_->predicted_motion(frame.depth_time_offset)
                                                : std::nullopt;
  // A rolling-shutter camera's last row, half the readout after the middle one (none known: as is).
  const std::optional<SE3> T_lastrow_cam =
      cam.readout_time > 0 ? tracker_->predicted_motion(0.5 * cam.readout_time) : std::nullopt;
  const int bow_levels_up = std::max(0, vocabulary_->depth() - config_.bow_direct_level);
  const FrameId id = ids_->next_frame();
  // A flow frame if the mode allows one now (tracking/frame_flow.h); the full way if none holds.
  std::optional<TrackResult> flowed;
  const FlowConfig& fc = config_.tracker.flow;
  cv::Mat gray;  // converted once: a frame the flow hands to the full path reuses it
  if (fc.mode == FlowMode::kAlways || (fc.mode == FlowMode::kUnderLoad && load != WorkerLoad::kKeepingUp)) {
    cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
    FlowPyramid pyramid = build_flow_pyramid(gray, fc);
    const int max_run = load == WorkerLoad::kOverloaded ? fc.max_run_overloaded : fc.max_run;
    const std::optional<FlowSeeds> seeds =
        flow_pyramid_.empty() ? std::nullopt : tracker_->flow_seeds(frame.timestamp, max_run);
    if (seeds) {
      const FlowFrame ff = make_flow_frame(id, frame.timestamp, frame.bgr, frame.depth, *tracker_->last_frame()->data,
                                           flow_pyramid_, pyramid, *seeds, fc, vocabulary_, bow_levels_up,
                                           T_depthcam_cam, T_lastrow_cam, frame.keyframe_eligible());
      r.features = int(ff.data->size());
      flowed = tracker_->track_flow(ff);
    }
    flow_pyramid_ = std::move(pyramid);
  } else {
    flow_pyramid_ = {};  // the next frame's flow needs this frame's pyramid
  }
  TrackResult t;
  if (flowed) {
    t = *flowed;
    r.extract_ms = sw.ms();  // flow and pose together
  } else {
    auto data =
        make_frame_data(id, frame.timestamp, frame.bgr, frame.depth, cam, config_.rgbd, extractor_, pyramid_,
                        vocabulary_, bow_levels_up, T_depthcam_cam, T_lastrow_cam, frame.keyframe_eligible(), gray);
    r.extract_ms = sw.ms();
    r.features = int(data->size());
    sw.reset();
    t = tracker_->track(std::move(data));
  }
  if (!config_.threaded) {
    while (mapper_->step()) {
    }
    while (loop_closer_->step()) {
    }
  }
  r.track_ms = sw.ms();
  r.new_keyframe = t.new_keyframe;
  r.flow = t.flow;
  r.wants_depth = t.wants_depth;
  r.keyframe_due_in = t.keyframe_due_in;
  r.keyframe = t.keyframe;
  if (T_depthcam_motion) r.T_cam_depthcam = T_depthcam_motion->inverse();
  r.inliers = t.inliers;
  r.fate = t.ok                                    ? FrameFate::kTracked
           : t.state == FrameFate::kNotInitialized ? FrameFate::kNotInitialized
                                                   : FrameFate::kLost;

  // Long loss: start a new map (merged later by map fusion); never stop processing.
  if (t.ok) {
    lost_since_ = -1;
  } else if (t.state == FrameFate::kLost) {
    if (lost_since_ < 0) lost_since_ = frame.timestamp;
    if (frame.timestamp - lost_since_ > config_.max_lost_seconds) {
      start_new_map();
      lost_since_ = -1;
    }
  }

  std::lock_guard<std::mutex> lock(mutex_);
  last_seq_ = frame.seq;
  ++snapshot_.frames_processed;
  if (t.flow) ++snapshot_.frames_flow;
  extract_ms_.push_back(r.extract_ms);
  track_ms_.push_back(r.track_ms);
  snapshot_.state = tracker_->state();
  if (t.ok && t.reference) {
    const FrameRecord record{frame.timestamp, t.reference, t.T_cam_ref, tracker_->map()->index()};
    if (!records_.empty() && records_.back().timestamp == frame.timestamp)
      records_.back() = record;  // publish_early_pose's (timestamps increase)
    else
      records_.push_back(record);
    if (++records_since_reanchor_ >= kReanchorEvery && reanchor_records()) records_since_reanchor_ = 0;
    ++snapshot_.frames_tracked;
    snapshot_.T_world_cam = t.T_cam_world.inverse();
  } else if (r.fate == FrameFate::kLost) {
    ++snapshot_.frames_lost;
  }
  snapshot_.maps = int(maps_.size());
  snapshot_.current_map = tracker_->map()->index();
  snapshot_.keyframes = int(tracker_->map()->num_keyframes());
  snapshot_.map_points = int(tracker_->map()->num_map_points());
  return r;
}

bool ClientSlam::reanchor_records() {
  // Never waits for a map's writer (bundle adjustment may hold it): tried again with a later frame.
  std::vector<std::shared_lock<std::shared_mutex>> locks;
  for (const auto& m : maps_) {
    std::shared_lock<std::shared_mutex> lock(m->mutex, std::try_to_lock);
    if (!lock.owns_lock()) return false;
    locks.push_back(std::move(lock));
  }
  reanchor_culled(records_);
  return true;
}

ClientSlamSnapshot ClientSlam::snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return snapshot_;
}

int ClientSlam::main_map_index() const {
  std::vector<int> counts(maps_.size(), 0);
  for (const auto& r : records_) ++counts[r.map_index];
  int best = 0;
  for (size_t i = 0; i < counts.size(); ++i)
    if (counts[i] > counts[best]) best = int(i);
  return best;
}

std::vector<std::shared_ptr<Map>> ClientSlam::main_frame_maps(const MapFrameOf& frame_of) const {
  std::vector<std::shared_ptr<Map>> maps;
  std::vector<std::size_t> frames;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    maps = maps_;
    frames.assign(maps.size(), 0);
    for (const auto& r : records_)
      if (std::size_t(r.map_index) < frames.size()) ++frames[std::size_t(r.map_index)];
  }
  std::vector<long> labels(maps.size(), -1);
  if (frame_of)
    for (std::size_t i = 0; i < maps.size(); ++i) labels[i] = frame_of(maps[i].get()).value();
  const std::vector<char> in = maps_in_main_frame(frames, std::move(labels));
  std::vector<std::shared_ptr<Map>> out;
  for (std::size_t i = 0; i < maps.size(); ++i)
    if (in[i]) out.push_back(maps[i]);
  return out;
}

Trajectory ClientSlam::trajectory(const MapFrameOf& frame_of) const {
  const auto included = main_frame_maps(frame_of);
  if (included.empty()) return {};
  std::vector<Map*> ptrs;
  for (const auto& m : included) ptrs.push_back(m.get());
  auto in_frame = [&ptrs](const Map* m) { return std::find(ptrs.begin(), ptrs.end(), m) != ptrs.end(); };
  std::lock_guard<std::mutex> lock(mutex_);
  const auto map_locks = lock_maps<std::shared_lock<std::shared_mutex>>(ptrs);
  Trajectory out;
  for (const auto& r : records_) {
    if (std::size_t(r.map_index) >= maps_.size() || !in_frame(maps_[std::size_t(r.map_index)].get())) continue;
    const LiveReference ref = live_reference(r);
    if (!ref.keyframe) continue;
    out.push_back({r.timestamp, ref.T_world_cam()});
  }
  return out;
}

std::optional<ClientSlam::FramePose> ClientSlam::last_frame_pose(double timestamp) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (records_.empty() || records_.back().timestamp != timestamp) return std::nullopt;
  const FrameRecord& r = records_.back();
  std::shared_lock<std::shared_mutex> map_lock(maps_[r.map_index]->mutex);
  const LiveReference ref = live_reference(r);
  if (!ref.keyframe) return std::nullopt;
  return FramePose{ref.T_world_cam(), r.map_index};
}

std::shared_ptr<Map> ClientSlam::main_map() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return maps_.empty() ? nullptr : maps_[main_map_index()];
}

Trajectory ClientSlam::keyframe_trajectory(const MapFrameOf& frame_of) const {
  const auto included = main_frame_maps(frame_of);
  std::vector<Map*> ptrs;
  for (const auto& m : included) ptrs.push_back(m.get());
  const auto map_locks = lock_maps<std::shared_lock<std::shared_mutex>>(ptrs);
  Trajectory out;
  for (Map* map : ptrs)
    for (const auto& kf : map->keyframes()) out.push_back({kf->timestamp(), kf->T_world_cam()});
  sort_by_time(out);
  return out;
}

ClientSlamTimings ClientSlam::timings() const {
  ClientSlamTimings t;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    t.extract_ms = extract_ms_;
    t.track_ms = track_ms_;
  }
  if (mapper_) t.mapper = mapper_->stats();
  if (loop_closer_) t.loop = loop_closer_->stats();
  return t;
}

std::vector<std::shared_ptr<Map>> ClientSlam::maps() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return maps_;
}

void ClientSlam::finish() {
  if (finished_) return;
  finished_ = true;
  if (mapper_) mapper_->finish();
  if (loop_closer_) loop_closer_->finish();
}

int ClientSlam::final_global_ba(const std::function<bool(const Map&)>& skip) {
  if (!finished_) throw std::logic_error("ClientSlam::final_global_ba before finish()");
  if (config_.final_global_ba_iterations <= 0) return 0;
  int n = 0;
  for (const auto& m : maps()) {
    if (skip && skip(*m)) continue;
    Stopwatch sw;
    if (!run_global_ba_once(*m, config_.final_global_ba_iterations)) continue;
    ++n;
    logger("slam")->info("client {}: final global BA over map {} ({} keyframes), {:.0f} ms", info_.id, m->index(),
                         m->num_keyframes(), sw.ms());
  }
  return n;
}

}  // namespace cslam
