#pragma once
// One map of one client: owns its keyframes and map points, the covisibility graph, the
// spanning tree and its keyframe database. Not a singleton: each client has its own maps.
// Locking: `mutex` guards every mutable member of the map, its keyframes and its points.
// Methods marked [unique] require the caller to hold mutex exclusively, [shared] at least shared.
// Whole-map readers yield to writers: a writer that takes `mutex` through MapWriteLock is counted
// while it waits (writers_waiting), and a long reader (the snapshot copy, export_map_state) checks
// that count as it goes, gives the lock up when a writer waits and starts again after it.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <unordered_map>
#include <vector>

#include "slam/bow/keyframe_database.h"
#include "slam/map/keyframe.h"

namespace cslam {

// Hands out ids for one client; shared by every map the client starts (so ids never repeat).
class IdAllocator {
 public:
  explicit IdAllocator(ClientId client) : client_(client) {}
  KeyFrameId next_keyframe() { return {client_, next_kf_++}; }
  MapPointId next_map_point() { return {client_, next_mp_++}; }
  FrameId next_frame() { return {client_, next_frame_++}; }
  ClientId client() const { return client_; }
  // Persistence: the next sequence numbers, and moving them forward past restored ids.
  std::array<std::uint32_t, 3> next() const { return {next_kf_.load(), next_mp_.load(), next_frame_.load()}; }
  void advance_to(const std::array<std::uint32_t, 3>& next) {
    next_kf_ = std::max(next_kf_.load(), next[0]);
    next_mp_ = std::max(next_mp_.load(), next[1]);
    next_frame_ = std::max(next_frame_.load(), next[2]);
  }

 private:
  ClientId client_;
  std::atomic<std::uint32_t> next_kf_{0}, next_mp_{0}, next_frame_{0};
};

class Map {
 public:
  Map(ClientId client, int index, std::shared_ptr<IdAllocator> ids)
      : client_(client), index_(index), ids_(std::move(ids)) {}

  ClientId client() const { return client_; }
  int index() const { return index_; }
  IdAllocator& ids() { return *ids_; }

  mutable std::shared_mutex mutex;
  KeyFrameDatabase database;

  // [unique]
  void add_keyframe(const KeyFramePtr& kf);
  void add_map_point(const MapPointPtr& mp);
  // [shared]
  std::vector<KeyFramePtr> keyframes() const;
  std::vector<MapPointPtr> map_points() const;
  // Visits every point without copying owning pointers (no reference-count traffic): for
  // readers that walk the whole map under the lock, such as the snapshot copy.
  template <class F>
  void for_each_map_point(F&& f) const {
    for (const auto& entry : map_points_) f(*entry.second);
  }
  // The same, handing f the owning pointer itself (a reader that keeps some of them copies only those).
  template <class F>
  void for_each_map_point_ptr(F&& f) const {
    for (const auto& entry : map_points_) f(entry.second);
  }
  // The same as for_each_map_point, stopping as soon as f returns false; false if it stopped.
  template <class F>
  bool for_each_map_point_while(F&& f) const {
    for (const auto& entry : map_points_)
      if (!f(*entry.second)) return false;
    return true;
  }
  KeyFramePtr keyframe(KeyFrameId id) const;
  MapPointPtr map_point(MapPointId id) const;  // null if the map does not hold it
  std::size_t num_keyframes() const { return keyframes_.size(); }
  std::size_t num_map_points() const { return map_points_.size(); }
  KeyFramePtr origin() const { return origin_; }
  KeyFramePtr shared(KeyFrame* kf) const;  // the owning pointer of a keyframe in this map

  // Graph operations [unique].
  static void add_observation(KeyFrame* kf, int index, const MapPointPtr& mp);
  void erase_observation(KeyFrame* kf, const MapPointPtr& mp);
  void set_map_point_bad(const MapPointPtr& mp);
  // Moves all observations of `from` to `into` and marks `from` bad (replaced).
  void replace_map_point(const MapPointPtr& from, const MapPointPtr& into);
  void update_connections(KeyFrame* kf);
  // Culls a keyframe: repairs the spanning tree, drops its observations, removes it from the
  // tables and the database. Deferred while no_erase > 0.
  void set_keyframe_bad(KeyFrame* kf);
  // Recomputes a point's normal, distance bounds (from its reference keyframe) and descriptor.
  void update_map_point(MapPoint* mp) const;

  // Writers (MapWriteLock) waiting for `mutex` right now.
  int writers_waiting() const { return writers_waiting_.load(std::memory_order_relaxed); }
  // Blocks (no lock of the map held) until no MapWriteLock waits for `mutex`; a writer that was
  // waiting holds it by then, so a shared lock taken next is granted after that writer is through.
  void wait_until_no_writer_waits() const;
  // [shared] How long each MapWriteLock built with record_wait waited for `mutex` (the tracker's
  // keyframe insertions), in order; the first kMaxRecordedWaits only.
  struct WriteWait {
    std::chrono::steady_clock::time_point asked;  // when it asked for the lock
    double ms = 0;                                // until it held it
  };
  static constexpr std::size_t kMaxRecordedWaits = 1 << 16;
  const std::vector<WriteWait>& recorded_write_waits() const { return write_waits_; }

  // Monotone counter of structural changes (loop corrections, fusions) for consumers to notice.
  std::uint64_t big_change_index() const { return big_changes_; }
  void note_big_change() { ++big_changes_; }
  // Loop closures corrected in this map (its own loop closer): a fused group re-adjusts after one.
  std::uint64_t loops_closed() const { return loops_closed_; }
  void note_loop_closed() { ++loops_closed_; }

 private:
  friend class MapWriteLock;
  void erase_keyframe_from_tables(KeyFrame* kf);

  ClientId client_;
  int index_;
  std::shared_ptr<IdAllocator> ids_;
  std::unordered_map<KeyFrameId, KeyFramePtr> keyframes_;
  std::unordered_map<MapPointId, MapPointPtr> map_points_;
  KeyFramePtr origin_;
  std::uint64_t big_changes_ = 0;
  std::uint64_t loops_closed_ = 0;
  mutable std::atomic<int> writers_waiting_{0};
  mutable std::mutex writers_mutex_;  // only to wait for writers_waiting_ == 0
  mutable std::condition_variable writers_cv_;
  std::vector<WriteWait> write_waits_;  // [unique] to append
};

// The map's exclusive lock, taken so that whole-map readers step aside: counted in
// writers_waiting() from before it asks for the lock until it holds it. With record_wait, the
// wait is appended to the map's recorded_write_waits().
class MapWriteLock {
 public:
  explicit MapWriteLock(Map& map, bool record_wait = false);
  MapWriteLock(const MapWriteLock&) = delete;
  MapWriteLock& operator=(const MapWriteLock&) = delete;

 private:
  std::unique_lock<std::shared_mutex> lock_;
};

}  // namespace cslam
