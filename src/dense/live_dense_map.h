#pragma once
// The live dense map: TSDF submaps built from the robots' keyframes while they map, following
// every correction. Sources of truth are the keyframes (their images, loaded on demand) and their
// current poses; a step() applies the poses of the moment:
//   1. every submap takes the current pose of its reference keyframe (rigid move, no re-integration),
//      published at once;
//   2. keyframes culled by local mapping are forgotten (reported, so their images can be dropped);
//   3. keyframes that have waited integration_delay_s (local BA has refined them) are integrated
//      into their client's open submap, a new one opening when the window is full;
//   4. if no due keyframe is left waiting, submaps whose keyframes moved relative to each other
//      beyond the threshold are re-integrated from their images, the most distorted first;
//   5. open submaps are re-meshed at most every mesh_interval_s.
// One thread owns the map (the dense worker); readers take view(), an immutable snapshot.
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "dense/backproject.h"
#include "dense/submap.h"
#include "geometry/camera.h"
#include "slam/map/keyframe_pose.h"

namespace cslam {

struct DenseMapView {
  std::uint64_t version = 0;             // increases with every change a reader can see
  std::vector<DenseSubmapView> submaps;  // sorted by id
  std::size_t keyframes_integrated = 0, keyframes_pending = 0;
  // What the map still owes the current poses: open submaps whose mesh lags their volume (re-meshed
  // within mesh_interval_s) and submaps distorted beyond the threshold, waiting to be re-integrated.
  // With no keyframe pending either, the map is settled: it shows everything at the current poses.
  std::size_t stale_meshes = 0, distorted_submaps = 0;
  bool settled() const { return keyframes_pending == 0 && stale_meshes == 0 && distorted_submaps == 0; }
  std::size_t mesh_bytes = 0, volume_bytes = 0;  // summed over the submaps
};

// Finds a keyframe's images (e.g. decodes them from the keyframe store); nullopt if it has none.
using DenseImageLoader = std::function<std::optional<DenseImages>(KeyFrameId)>;

struct DenseStepBudget {
  int max_integrations = 1 << 30;
  int max_reintegrations = 1 << 30;
};

struct DenseStepResult {
  int moved = 0;         // submaps whose pose changed
  int integrated = 0;    // keyframes fused
  int reintegrated = 0;  // submaps rebuilt
  int remeshed = 0;
  int removed = 0;                   // submaps left without keyframes
  int missing_images = 0;            // keyframes without images (skipped, counted)
  std::vector<KeyFrameId> culled;    // keyframes gone from the maps since the last step
  std::vector<double> integrate_ms;  // per keyframe fused
  double max_deviation_m = 0;        // worst relative keyframe motion found in a submap
};

class LiveDenseMap {
 public:
  explicit LiveDenseMap(LiveDenseConfig config);  // throws ConfigError

  // The camera of a client (before its keyframes can be integrated).
  void set_camera(ClientId client, const PinholeCamera& camera);
  // A new keyframe; its images if at hand (else the loader is asked when it is integrated), and
  // where its depth image was taken relative to its colour image's pose.
  void add_keyframe(KeyFrameId id, std::optional<DenseImages> images, double now_s, const SE3& T_cam_depthcam = SE3());
  // One step with the current poses of every live keyframe (any order).
  DenseStepResult step(const std::vector<KeyframePose>& poses, double now_s, const DenseImageLoader& loader,
                       const DenseStepBudget& budget = {});
  // Integrates every pending keyframe and meshes every submap (end of a run, tests).
  DenseStepResult flush(const std::vector<KeyframePose>& poses, const DenseImageLoader& loader);

  std::shared_ptr<const DenseMapView> view() const;
  std::size_t pending() const { return pending_.size(); }
  const LiveDenseConfig& config() const { return config_; }

 private:
  struct Pending {
    KeyFrameId id;
    double added_s = 0;
    std::optional<DenseImages> images;
    SE3 T_cam_depthcam;
  };
  using PoseIndex = std::map<KeyFrameId, const KeyframePose*>;

  // One step; `all`: every pending keyframe is due and every stale mesh is redone (flush).
  DenseStepResult run_step(const std::vector<KeyframePose>& poses, double now_s, bool all,
                           const DenseImageLoader& loader, const DenseStepBudget& budget);

  void apply_poses(const PoseIndex& poses, DenseStepResult& r, std::vector<std::pair<double, SubmapId>>& distorted);
  void find_culled(const PoseIndex& poses, DenseStepResult& r);
  // Returns how many due keyframes were left for a later step (over the budget).
  int integrate_pending(const PoseIndex& poses, double now_s, bool all, const DenseImageLoader& loader, int budget,
                        DenseStepResult& r);
  bool integrate_one(const KeyframePose& pose, const DenseImages& images, const SE3& T_cam_depthcam,
                     DenseStepResult& r);
  void reintegrate(DenseSubmap& submap, const PoseIndex& poses, const DenseImageLoader& loader, DenseStepResult& r);
  void remesh_due(double now_s, bool all, DenseStepResult& r);
  void publish();

  LiveDenseConfig config_;
  std::map<ClientId, std::unique_ptr<RayTable>> rays_;
  std::map<SubmapId, std::unique_ptr<DenseSubmap>> submaps_;
  std::map<ClientId, SubmapId> open_;  // each client's submap taking keyframes
  std::map<ClientId, std::uint32_t> next_index_;
  std::map<SubmapId, double> last_mesh_s_;
  std::vector<Pending> pending_;                     // by id
  std::map<ClientId, std::uint32_t> newest_listed_;  // newest keyframe seq seen in the poses per client
  std::size_t integrated_ = 0;
  std::size_t distorted_left_ = 0;  // distorted submaps the last step did not rebuild
  std::uint64_t version_ = 0;

  mutable std::mutex view_mutex_;  // guards view_ only
  std::shared_ptr<const DenseMapView> view_;
};

}  // namespace cslam
