// ClientSlam's export/restore pair (declared in slam/client_slam.h).
#include "slam/client_slam_state.h"

#include <shared_mutex>
#include <sstream>
#include <unordered_map>

#include "core/error.h"
#include "core/log.h"
#include "slam/map_frames.h"

namespace cslam {

namespace {
// Times one map's snapshot copy gives its lock up to a waiting writer before it copies regardless.
constexpr int kMaxSnapshotYields = 20;
}  // namespace

ClientSlamState ClientSlam::export_state() const {
  ClientSlamState s;
  s.info = info_;
  std::vector<FrameRecord> records;
  std::vector<std::shared_ptr<Map>> maps;
  {
    // Records first: every keyframe they reference exists in its map by the time the map is read.
    std::lock_guard<std::mutex> lock(mutex_);
    records = records_;
    maps = maps_;
    s.last_seq = last_seq_;
    s.current_map = snapshot_.current_map;
    s.frames_processed = snapshot_.frames_processed;
    s.frames_tracked = snapshot_.frames_tracked;
    s.frames_lost = snapshot_.frames_lost;
    s.frames_rejected = snapshot_.frames_rejected;
  }
  s.last_timestamp = records.empty() ? 0.0 : records.back().timestamp;
  std::vector<std::vector<std::size_t>> by_map(maps.size());
  for (std::size_t i = 0; i < records.size(); ++i)
    if (records[i].map_index >= 0 && std::size_t(records[i].map_index) < maps.size())
      by_map[records[i].map_index].push_back(i);
  std::vector<std::optional<FrameRecordState>> resolved(records.size());
  for (std::size_t m = 0; m < maps.size(); ++m) {
    // Each map in one shared-lock hold, which steps aside while the tracker (or local mapping)
    // waits to write; the frame records are resolved in that same hold.
    s.maps.push_back(export_map_state_yielding(*maps[m], kMaxSnapshotYields, [&] {
      for (std::size_t i : by_map[m]) {
        const FrameRecord& r = records[i];
        const LiveReference ref = live_reference(r);
        if (!ref.keyframe || ref.keyframe->bad || maps[m]->keyframe(ref.keyframe->id).get() != ref.keyframe) continue;
        resolved[i] = FrameRecordState{r.timestamp, int(m), ref.keyframe->id, ref.T_cam_ref};
      }
    }));
  }
  s.next_ids = ids_->next();  // read after the maps: above every id they hold
  for (auto& m : s.maps) tidy_map_state(m);
  s.records.reserve(records.size());
  for (auto& r : resolved)
    if (r) s.records.push_back(*r);
  return s;
}

void ClientSlam::restore_state(const ClientSlamState& s, const std::string& source) {
  if (s.info.id != info_.id)
    throw InputError(source,
                     "state of client " + std::to_string(s.info.id) + " given to client " + std::to_string(info_.id));
  if (s.maps.empty()) throw InputError(source, "client " + std::to_string(info_.id) + " has no map");
  if (s.current_map < 0 || std::size_t(s.current_map) >= s.maps.size())
    throw InputError(source, "client " + std::to_string(info_.id) + ": current map out of range");
  std::vector<std::shared_ptr<Map>> maps;
  const int levels_up = std::max(0, vocabulary_->depth() - config_.bow_direct_level);
  for (std::size_t i = 0; i < s.maps.size(); ++i) {
    MapState ms = s.maps[i];
    if (ms.index != int(i) || ms.client != info_.id)
      throw InputError(source, "client " + std::to_string(info_.id) + ": map " + std::to_string(i) + " misnumbered");
    for (auto& k : ms.keyframes) {
      if (!k.data || !k.data->bow.empty()) continue;
      auto d = std::make_shared<FrameData>(*k.data);
      derive_frame_data(*d, vocabulary_.get(), levels_up);
      k.data = std::move(d);
    }
    maps.push_back(restore_map(ms, ids_, source));
  }
  ids_->advance_to(s.next_ids);
  std::vector<FrameRecord> records;
  records.reserve(s.records.size());
  for (const auto& r : s.records) {
    if (r.map_index < 0 || std::size_t(r.map_index) >= maps.size())
      throw InputError(source, "client " + std::to_string(info_.id) + ": frame record in an unknown map");
    KeyFramePtr ref = maps[r.map_index]->keyframe(r.reference);
    if (!ref) {
      std::ostringstream os;
      os << "client " << info_.id << ": frame at " << r.timestamp << " refers to unknown keyframe " << r.reference;
      throw InputError(source, os.str());
    }
    records.push_back({r.timestamp, std::move(ref), r.T_cam_ref, r.map_index});
  }

  // The workers of the map tracking continues in (as start_new_map attaches them to a new map).
  const auto& map = maps[s.current_map];
  std::unique_ptr<LocalMapper> mapper = attach_workers(map);
  tracker_->resume_lost(map, mapper.get());
  mapper_ = std::move(mapper);
  last_timestamp_ = s.last_timestamp;
  lost_since_ = -1;
  std::lock_guard<std::mutex> lock(mutex_);
  maps_ = std::move(maps);
  records_ = std::move(records);
  last_seq_ = s.last_seq;
  snapshot_.state = FrameFate::kLost;
  snapshot_.frames_processed = s.frames_processed;
  snapshot_.frames_tracked = s.frames_tracked;
  snapshot_.frames_lost = s.frames_lost;
  snapshot_.frames_rejected = s.frames_rejected;
  snapshot_.maps = int(maps_.size());
  snapshot_.current_map = s.current_map;
  snapshot_.keyframes = int(maps_[s.current_map]->num_keyframes());
  snapshot_.map_points = int(maps_[s.current_map]->num_map_points());
  logger("slam")->info("client {}: restored {} map(s), {} frame poses, continuing in map {} after seq {}", info_.id,
                       maps_.size(), records_.size(), s.current_map, s.last_seq);
}

void ClientSlam::start_new_session() {
  last_timestamp_ = -1e300;
  lost_since_ = -1;
  start_new_map();
  logger("slam")->info("client {}: new session in map {}", info_.id, tracker_->map()->index());
}

Trajectory state_trajectory(const ClientSlamState& s, int* map_index) {
  const std::size_t n = s.maps.size();
  std::vector<std::size_t> counts(n, 0);
  for (const auto& r : s.records)
    if (r.map_index >= 0 && std::size_t(r.map_index) < n) ++counts[std::size_t(r.map_index)];
  // Maps of one fused group share a frame (the rule of ClientSlam::trajectory with fusion's groups).
  std::vector<long> labels(n);
  for (std::size_t i = 0; i < n; ++i) labels[i] = s.maps[i].group;
  const std::vector<char> included = maps_in_main_frame(counts, std::move(labels));
  int main = -1;
  std::unordered_map<KeyFrameId, SE3> poses;
  for (std::size_t i = 0; i < n; ++i) {
    if (!included[i]) continue;
    if (main < 0 || counts[i] > counts[std::size_t(main)]) main = int(i);
    for (const auto& k : s.maps[i].keyframes) poses[k.id] = k.T_cam_world;
  }
  if (map_index) *map_index = main;
  Trajectory out;
  for (const auto& r : s.records) {
    if (r.map_index < 0 || std::size_t(r.map_index) >= n || !included[std::size_t(r.map_index)]) continue;
    auto it = poses.find(r.reference);
    if (it != poses.end()) out.push_back({r.timestamp, (r.T_cam_ref * it->second).inverse()});
  }
  return out;
}

Trajectory state_keyframes(const MapState& map) {
  Trajectory out;
  for (const auto& k : map.keyframes) out.push_back({k.data ? k.data->timestamp : 0.0, k.T_cam_world.inverse()});
  sort_by_time(out);
  return out;
}

}  // namespace cslam
