#pragma once
// Per-client RGB-D tracking (ORB-SLAM2 class): map initialisation from the first frame with
// enough depth, constant-velocity motion model, reference-keyframe tracking by BoW, local-map
// tracking, pose-only optimisation, keyframe decision and relocalisation.
#include <deque>
#include <functional>
#include <memory>
#include <optional>

#include "core/pointer_set.h"
#include "frame/frame_fate.h"
#include "slam/map/frame.h"
#include "slam/map/map.h"
#include "optimize/pose_optimizer.h"
#include "slam/tracking/frame_flow.h"

namespace cslam {

struct TrackerConfig {
  int min_init_points = 500;       // keypoints with depth needed to initialise a map
  double motion_radius = 15.0;     // projection search radius (pixels at level 0) for the motion model
  double local_map_radius = 3.0;   // local-map projection search window (x 2.5..4 x level scale)
  int min_motion_matches = 20;     // below this the search is repeated with twice the radius
  int min_pose_inliers = 10;       // after motion-model / reference-keyframe pose optimisation
  int min_local_map_inliers = 30;  // local-map tracking success
  int min_local_map_inliers_after_reloc = 50;
  int max_local_keyframes = 80;
  // Keyframe rule: the tracked points fall below ref_ratio of the reference keyframe's points seen
  // by two keyframes, or too few close points are tracked, once min_frames_between_keyframes
  // frames have passed; and at least every keyframe_every_frames frames while tracking is healthy,
  // so that loop closing and map fusion see consecutive keyframes of every place (their 3-keyframe
  // consistency check needs them). It depends on tracking alone, never on whether local mapping
  // happens to be busy, so threaded and stepped (--sync) runs decide alike.
  int max_frames_between_keyframes = 30;  // ~1 s at 30 Hz; also the relocalisation grace period
  int min_frames_between_keyframes = 0;
  // The ratio rule alone makes a keyframe only this long (sensor time) after the previous one: a
  // deterministic stand-in for ORB-SLAM2's "local mapping is idle" term. Without it, stepped runs
  // (where local mapping is always done) made a keyframe almost every other frame on fr1/desk
  // (318 against 138 threaded) at 4x the CPU time and a higher error; see docs/slam.md.
  double min_keyframe_interval_s = 0.1;
  int keyframe_every_frames = 10;  // ~1/3 s at 30 Hz; 0: off
  double ref_ratio = 0.75;
  int ref_min_observations = 3;  // reference-keyframe points counted by the keyframe rule: seen by two keyframes (an
                                 // RGB-D observation counts 2)
  int close_tracked_threshold = 100, close_untracked_threshold = 70;  // RGB-D "need close points" rule
  int min_new_close_points = 100;  // new map points per keyframe: all close ones and at least this many
  int reloc_min_bow_matches = 15;
  int reloc_min_inliers = 50;
  FlowConfig flow;  // frame-to-frame tracking by optical flow between full frames (frame_flow.h)
};

// What the tracker needs from local mapping.
class KeyFrameSink {
 public:
  virtual ~KeyFrameSink() = default;
  // May wait while the sink is behind (backpressure); never called with the map lock held.
  virtual void insert_keyframe(const KeyFramePtr& kf) = 0;
  virtual bool accepts_keyframes() const = 0;
};

struct TrackResult {
  FrameFate state = FrameFate::kNotInitialized;
  bool ok = false;
  bool new_keyframe = false;
  bool relocalized = false;
  bool initialized_map = false;
  bool flow = false;  // tracked as a flow frame (Tracker::track_flow)
  // The frame had no depth image and tracking needs one: a keyframe is due (deferred to the next
  // frame with depth) or the map is not initialised yet. The server asks the robot for depth.
  bool wants_depth = false;
  // Frames after this one at which the periodic keyframe rule (keyframe_every_frames) falls due
  // unless the ratio rule makes a keyframe first; 0: no hint (tracking is not healthy, the rule
  // is off, or a keyframe is already waiting for depth: wants_depth).
  int keyframe_due_in = 0;
  // The keyframe this frame became (new_keyframe or initialized_map).
  std::optional<KeyFrameId> keyframe;
  int inliers = 0;
  SE3 T_cam_world;
  KeyFramePtr reference;
  SE3 T_cam_ref;  // pose relative to the reference keyframe (valid when ok)
};

class Tracker {
 public:
  Tracker(TrackerConfig config, std::shared_ptr<Map> map, KeyFrameSink* sink);

  TrackResult track(std::shared_ptr<const FrameData> data);
  FrameFate state() const { return state_; }
  // Flow frames (frame_flow.h, tracker_flow.cpp). flow_seeds: the last frame's matched keypoints
  // and where the motion model puts them at `timestamp`, if this frame may be a flow frame
  // (tracking healthy, no keyframe due or deferred, fewer than `max_run` flow frames in a row); nullopt: track
  // it the full way. track_flow: tracks a flow frame made from those seeds; nullopt if it is not
  // good enough or a keyframe may be due (then call track(); pose, velocity and counters are
  // unchanged, only the estimate that track() calibrates against is kept).
  std::optional<FlowSeeds> flow_seeds(double timestamp, int max_run);
  std::optional<TrackResult> track_flow(const FlowFrame& flow);
  const Frame* last_frame() const { return last_.get(); }
  // The camera's motion over `seconds` at the current constant-velocity estimate, as the pose of
  // the camera at the start seen from the camera at the end (T_later_earlier for seconds > 0);
  // nullopt while tracking has no velocity (before the second tracked frame, after a loss).
  std::optional<SE3> predicted_motion(double seconds) const;
  const std::shared_ptr<Map>& map() const { return map_; }
  // Called with a frame's final pose when the frame is about to become a keyframe, before the
  // keyframe is made and handed to local mapping (which may wait): whoever reports poses need not
  // wait for that.
  struct TrackedPose {
    double timestamp = 0;
    KeyFramePtr reference;  // the frame's reference keyframe before it becomes one itself
    SE3 T_cam_ref;
    std::uint64_t change_index = 0;  // the map's big-change index the pose was tracked under
    int keyframe_due_in = 0;         // TrackResult::keyframe_due_in once the frame is a keyframe
  };
  using PoseListener = std::function<void(const TrackedPose&)>;
  void set_pose_listener(PoseListener listener) { pose_listener_ = std::move(listener); }
  // Starts over on a new, empty map (after a long loss); the previous map is kept by the caller.
  void reset(std::shared_ptr<Map> new_map, KeyFrameSink* sink);
  // Continues in an existing (restored) map: lost, so the next frames relocalise in it.
  void resume_lost(std::shared_ptr<Map> map, KeyFrameSink* sink) {
    reset(std::move(map), sink);
    state_ = FrameFate::kLost;
  }

 private:
  bool initialize(Frame& frame);
  bool track_with_motion_model(Frame& frame);
  bool track_reference_keyframe(Frame& frame);
  bool relocalize(Frame& frame);
  bool track_local_map(Frame& frame);
  void update_last_frame();
  // The keyframes observing the frame's inlier map points and how many of them each observes, in
  // id order, and the first good one of those observing the most (null if none): the reference
  // keyframe (map lock held shared).
  static std::vector<std::pair<KeyFrame*, int>> keyframes_sharing(const Frame& frame);
  static KeyFrame* most_sharing(const std::vector<std::pair<KeyFrame*, int>>& sharing);
  // The slots of the local keyframes' points (read them while the map's shared lock is held), and
  // the reference keyframe.
  const std::vector<const MapPointPtr*>& update_local_map(const Frame& frame, KeyFramePtr& reference);
  int optimize_frame_pose(Frame& frame) const;
  // The constant-velocity model's pose at `timestamp`, from the last frame's (needs last_).
  SE3 motion_model_pose(double timestamp) const;
  bool need_new_keyframe(const Frame& frame) const;
  // TrackResult::keyframe_due_in after the keyframe decision, `frames_since_keyframe` frames after
  // the last keyframe (0: this frame becomes one).
  int keyframe_due_in(std::uint32_t frames_since_keyframe) const;
  // A flow frame's counts do not rule out the keyframe rule firing (map lock held shared).
  bool keyframe_may_be_due(const Frame& frame, int inliers);
  // On a full frame after a flow estimate: records actual / estimated local-map inliers.
  void calibrate_flow();
  // Makes the keyframe that the rule (or a deferral) asks for; a frame without full depth (FrameData::keyframe_depth)
  // defers it.
  void decide_keyframe(Frame& frame, TrackResult& result);
  KeyFramePtr create_keyframe(Frame& frame);
  StereoIntrinsics intrinsics(const FrameData& f) const;

  TrackerConfig config_;
  std::shared_ptr<Map> map_;
  KeyFrameSink* sink_;
  PoseListener pose_listener_;
  FrameFate state_ = FrameFate::kNotInitialized;
  std::unique_ptr<Frame> last_;
  std::unique_ptr<Frame> last_full_;  // while flow frames follow it: the last full frame (track_with_motion_model)
  bool last_is_keyframe_ = false;
  // A keyframe was due on a frame without full depth: the next frame with it becomes one.
  bool keyframe_deferred_ = false;
  bool has_velocity_ = false;
  SE3 velocity_;  // T_cur_world = velocity * T_last_world, over velocity_dt_ seconds
  double velocity_dt_ = 0;
  KeyFramePtr reference_kf_;
  KeyFramePtr last_keyframe_;
  std::uint32_t frames_since_keyframe_ = 0, frames_since_reloc_ = 1000000;
  int last_inliers_ = 0;
  std::uint64_t tracked_change_index_ = 0;  // map change index when the frame was tracked
  PointerSet local_points_seen_;            // update_local_map's scratch, reused frame to frame
  // The local keyframes of the last full frame, their slots' versions and their points' slots:
  // the next frame reuses the points while it chooses the same keyframes and no slot changed
  // (the keyframes are held, so no other keyframe takes their addresses meanwhile).
  struct LocalMap {
    std::vector<KeyFramePtr> keyframes;
    std::vector<std::uint64_t> versions;
    std::vector<const MapPointPtr*> points;
  };
  LocalMap local_map_;
  int flow_run_ = 0;           // flow frames since the last full frame
  int full_inliers_ = 0;       // local-map inliers of the last full frame
  int full_close_ = 0;         // ... and of them close points
  double flow_estimate_ = -1;  // a flow frame's estimate of local-map inliers, until a full frame measures them
  std::deque<double> flow_calibration_;  // recent actual / estimated local-map inliers (keyframe_may_be_due)
  int flow_seeded_ = 0;                  // map points seeded into the flow (flow_seeds)
  double flow_in_view_ = 0;              // share of the last frame's map points predicted in view
  double flow_survival_ = 1;             // share of the last full frame's points the flow run still holds
  std::uint64_t flow_change_index_ = 0;  // map change index when the flow seeds were taken
};

}  // namespace cslam
