#pragma once
// One client's SLAM worker: ORB extraction, tracking (on the caller's thread), local mapping (its
// own thread, or stepped inline), several maps if tracking is lost for long, and the frame
// trajectory kept relative to reference keyframes so map corrections reach every frame.
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "slam/bow/vocabulary.h"
#include "io/trajectory_io.h"
#include "slam/frame_record.h"
#include "slam/slam_config.h"
#include "frame/rgbd_frame.h"

namespace cslam {

struct ProcessResult {
  FrameFate fate = FrameFate::kRejected;  // never kSkipped here: skipping is the worker's
  std::string reject_reason;
  bool new_keyframe = false;
  bool flow = false;  // tracked as a flow frame (tracking/frame_flow.h): no ORB extraction, no local-map search
  std::optional<KeyFrameId> keyframe;  // the keyframe this frame became (also a new map's first)
  // A light frame (no full depth) on which tracking needed full depth (a keyframe deferred, or no map yet): the
  // robot's next frame should carry depth.
  bool wants_depth = false;
  int keyframe_due_in = 0;  // TrackResult::keyframe_due_in: when the robot's next keyframe falls due
  // Where the camera was when the depth image was taken (frame.depth_time_offset away), relative
  // to the colour image's pose, as the motion model predicts it (identity without one).
  SE3 T_cam_depthcam;
  int inliers = 0;
  int features = 0;
  double extract_ms = 0, track_ms = 0;
};

struct ClientSlamSnapshot {
  FrameFate state = FrameFate::kNotInitialized;
  std::uint64_t frames_processed = 0, frames_tracked = 0, frames_lost = 0, frames_rejected = 0;
  std::uint64_t frames_flow = 0;  // of them tracked as flow frames
  int maps = 0, keyframes = 0, map_points = 0;
  SE3 T_world_cam;  // current pose in the current map's frame
  int current_map = 0;
};

struct ClientSlamTimings {
  std::vector<double> extract_ms, track_ms;  // per processed frame
  LocalMapperStats mapper;
  LoopClosingStats loop;
};

// Told about every keyframe local mapping has finished (map fusion, loop detection listen).
using KeyFrameListener = std::function<void(ClientId, const std::shared_ptr<Map>&, const KeyFramePtr&)>;

// Which of a client's maps share one frame: frame_of(map) labels the frame the map's poses are in
// (maps with equal valid labels share it, e.g. map fusion's group; invalid: a frame of its own). A
// client has several maps after a long tracking loss or a new session; once map fusion has joined
// them, their frames belong in one trajectory. Without it every map is a frame of its own.
using MapFrameOf = std::function<GroupId(const Map*)>;

struct ClientSlamState;  // slam/client_slam_state.h

class ClientSlam {
 public:
  ClientSlam(ClientInfo info, SlamConfig config, std::shared_ptr<const Vocabulary> vocabulary,
             KeyFrameListener listener = {});
  ~ClientSlam();
  ClientSlam(const ClientSlam&) = delete;
  ClientSlam& operator=(const ClientSlam&) = delete;

  // Never throws on bad data: returns kRejected with a reason (wrong size/type, time going back).
  // `load`: how far the caller is behind live frames (WorkerLoad: FlowMode::kUnderLoad allows flow
  // frames while behind; runs of them grow to FlowConfig::max_run_overloaded while overloaded).
  ProcessResult process(const RgbdFrame& frame, WorkerLoad load = WorkerLoad::kKeepingUp);
  ClientSlamSnapshot snapshot() const;
  // Every tracked frame (camera-to-world, current estimates) of the maps that share the frame
  // holding most tracked frames (see MapFrameOf; without it: the map with most frames).
  Trajectory trajectory(const MapFrameOf& frame_of = {}) const;
  // Current estimate of the frame processed last, if it had `timestamp` and was tracked: the
  // same computation as its trajectory() entry (its reference keyframe's current pose), in the
  // frame of the map it was tracked in (map_index). For pose feedback to the robot.
  struct FramePose {
    SE3 T_world_cam;
    int map_index = 0;
  };
  std::optional<FramePose> last_frame_pose(double timestamp) const;
  // The map the trajectory is expressed in.
  std::shared_ptr<Map> main_map() const;
  // Keyframes of the maps trajectory(frame_of) covers, time-ordered.
  Trajectory keyframe_trajectory(const MapFrameOf& frame_of = {}) const;
  ClientSlamTimings timings() const;
  std::vector<std::shared_ptr<Map>> maps() const;
  // Stops local mapping after processing what is queued. Idempotent.
  void finish();
  // After finish(): one global BA over each map (config final_global_ba_iterations; 0: none),
  // except those `skip` names (e.g. maps fused with other clients' maps, which the group BA after
  // each fusion refines). Returns how many maps were refined.
  int final_global_ba(const std::function<bool(const Map&)>& skip = {});
  const ClientInfo& info() const { return info_; }

  // Persistence (slam/client_slam_state.cpp). export_state: one consistent copy (maps read under
  // their shared locks, briefly; frame data shared, not copied). restore_state: only before the
  // first frame; continues in the restored current map (lost until it relocalises there).
  ClientSlamState export_state() const;
  void restore_state(const ClientSlamState& state, const std::string& source);
  // A new recording session of the same client: a new map (fused later by map fusion) and a new
  // time base; the restored maps are kept.
  void start_new_session();
  // Runs around tracking's waits for local mapping, in every map's mapper; set before the first
  // frame (the system lends the worker's tracking slot meanwhile).
  void set_tracking_wait_hooks(TrackingWaitHooks hooks);
  // Called on the processing thread, inside process(), with a frame's pose as soon as it is final
  // when that is well before process() returns: a frame that becomes a keyframe, before the
  // keyframe is made and local mapping is waited for. The pose is the frame's trajectory() entry,
  // which exists from then on; `map_epoch`: the sum of the client's maps' big-change indices, read
  // with it; `keyframe_due_in`: TrackResult::keyframe_due_in once the frame is a keyframe. Not
  // called if the map moved after the frame was tracked (process() then ends with the pose in the
  // moved map). Set before the first frame.
  using EarlyPoseListener = std::function<void(const FramePose& pose, std::uint64_t map_epoch, int keyframe_due_in)>;
  void set_early_pose_listener(EarlyPoseListener listener);
  // The sum of the client's maps' big-change indices: it grows whenever a fusion, group BA or loop
  // correction may have moved a map (FrameDone::map_epoch).
  std::uint64_t map_epoch() const;

 private:
  // Finishes the current map's local mapper and loop closer and starts both on `map`, the mapper
  // handing each keyframe it finished to the loop closer and the listener. The caller gives the
  // tracker the returned mapper, then keeps it in mapper_.
  std::unique_ptr<LocalMapper> attach_workers(const std::shared_ptr<Map>& map);
  void start_new_map();
  void publish_early_pose(const Tracker::TrackedPose& tracked);
  static std::uint64_t map_epoch_locked(const std::vector<Map*>& maps);  // caller holds their locks
  // reanchor_culled() over the records (frame_record.h) with every map's lock held shared,
  // taken without waiting. Caller holds mutex_; false if a map was busy (tried again later).
  bool reanchor_records();
  static constexpr int kReanchorEvery = 30;  // frames between passes
  int main_map_index() const;
  // The maps that share the frame holding most tracked frames (never locks a map; calls
  // frame_of without holding mutex_).
  std::vector<std::shared_ptr<Map>> main_frame_maps(const MapFrameOf& frame_of) const;

  const ClientInfo info_;
  SlamConfig config_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  OrbExtractor extractor_;
  std::shared_ptr<const ScalePyramid> pyramid_;
  std::shared_ptr<IdAllocator> ids_;
  KeyFrameListener listener_;
  TrackingWaitHooks wait_hooks_;
  EarlyPoseListener early_pose_listener_;
  std::vector<std::shared_ptr<Map>> maps_;
  std::unique_ptr<LocalMapper> mapper_;
  std::unique_ptr<LoopCloser> loop_closer_;
  std::unique_ptr<Tracker> tracker_;
  FlowPyramid flow_pyramid_;  // the last frame's, while flow frames are allowed
  double last_timestamp_ = -1e300;
  double lost_since_ = -1;

  mutable std::mutex mutex_;  // guards records_, snapshot_, timings_, maps_ (list only)
  std::vector<FrameRecord> records_;
  int records_since_reanchor_ = 0;
  ClientSlamSnapshot snapshot_;
  std::vector<double> extract_ms_, track_ms_;
  bool finished_ = false;
  std::uint64_t last_seq_ = 0;  // sender's seq of the last frame processed (guarded by mutex_)
};

}  // namespace cslam
