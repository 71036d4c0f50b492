#pragma once
// The collaborative SLAM system as the server and the offline runner see it: clients register,
// frames are submitted per client, snapshots are read at any time, outputs are written at the end.
// The network layer only decodes packets and calls this; it never touches SLAM internals.
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "fusion/fusion_event.h"
#include "io/trajectory_io.h"
#include "slam/map/keyframe_pose.h"
#include "frame/rgbd_frame.h"
#include "system/system_config.h"

namespace cslam {

// A client's tracking state for status pages: its tracker's state (the fate of its last processed
// frame: not initialised, tracked or lost), labelled "not_initialized", "tracking" or "lost".
const char* tracking_label(FrameFate state);

struct ClientSnapshot {
  ClientId id = 0;
  std::string name;
  FrameFate tracking = FrameFate::kNotInitialized;  // kNotInitialized, kTracked or kLost
  std::uint64_t frames_submitted = 0, frames_processed = 0, frames_rejected = 0, frames_lost = 0;
  std::uint64_t frames_skipped = 0;  // live frames skipped because a newer one was queued
  std::uint64_t frames_flow = 0;     // frames tracked as flow frames (tracking/frame_flow.h)
  // Receipt to pose (frame done) on the server over the client's last frames, milliseconds.
  double pose_latency_last_ms = 0, pose_latency_p50_ms = 0, pose_latency_p99_ms = 0;
  std::size_t pose_latency_samples = 0;
  // Where a frame's time on the server goes, each part's p99 over the same frames: decoding (the
  // packet read to submit; 0 offline), waiting in the client's queue, waiting for a tracking slot,
  // the tracker waiting for local mapping (a keyframe's new points), and the rest of processing;
  // work_cpu_ms is the worker thread's CPU time within `work` (much less than it: the thread
  // waited for a core or a lock).
  struct LatencyParts {
    double decode_ms = 0, queue_ms = 0, slot_ms = 0, mapping_wait_ms = 0, work_ms = 0, work_cpu_ms = 0;
  } pose_latency_parts_p99;
  int maps = 1;
  std::size_t queue_depth = 0;
  int keyframes = 0, map_points = 0;
  GroupId group;    // fused group (clients in one group share a frame); its first map's if unfused
  SE3 T_world_cam;  // current pose in the group frame
  double last_timestamp = 0;
};

// A sparse map point for viewers: position in its group's frame, colour, owning client.
struct ViewerPoint {
  float x = 0, y = 0, z = 0;
  std::uint8_t r = 0, g = 0, b = 0;
  ClientId client = 0;
};

struct SystemSnapshot {
  double uptime_s = 0;
  std::vector<ClientSnapshot> clients;
  std::vector<FusionEvent> events;
  GroupBaStats group_ba;
};

class ClientPipeline;
struct SystemState;  // system/system_state.h

class CollaborativeSystem {
 public:
  explicit CollaborativeSystem(SystemConfig config);
  ~CollaborativeSystem();  // finishes and joins every thread
  CollaborativeSystem(const CollaborativeSystem&) = delete;
  CollaborativeSystem& operator=(const CollaborativeSystem&) = delete;

  // Registers a client (or re-registers the same one after a reconnect: its map is kept).
  // Throws std::invalid_argument if the id is known with a different camera.
  void add_client(const ClientInfo& info);
  bool has_client(ClientId id) const;

  // Queues a frame for its client's SLAM worker; blocks while that queue is full (back-pressure).
  // Returns false if the system is finishing or the client is unknown. Frames whose images
  // contradict the client's camera are rejected (counted) here.
  bool submit(RgbdFrame frame);

  // Releases an idle client: processes its queued frames, joins its threads, writes its outputs
  // (client_K.txt, keyframes_K.txt and stats.json for that client alone) into dir, and removes
  // it, so that a later add_client() with its id starts a new map. A client whose map is fused
  // with another client's stays (its map is part of the group): returns false and only joins
  // nothing. Returns true if the client was removed (also if it was unknown).
  bool retire_client(ClientId id, const std::string& dir);

  // One consistent view of every client (one call, one lock).
  SystemSnapshot snapshot() const;
  // Client workers waiting for a tracking slot now (SystemConfig::tracking_slots; 0 without).
  std::size_t tracking_slot_waiters() const;

  // Processes every queued frame, stops the workers and the fusion thread. Idempotent.
  void finish();

  // Per-client trajectories, each in the frame of its fused group.
  std::map<ClientId, Trajectory> trajectories() const;
  // Group id -> member clients (a client alone is a group of one).
  std::map<GroupId, std::vector<ClientId>> groups() const;
  // Sparse map points of a group's clients (every n-th point so that at most max_points come back).
  std::vector<ViewerPoint> map_points(GroupId group, std::size_t max_points = 50000) const;
  // Keyframe poses of one client in its group's frame.
  Trajectory keyframe_trajectory(ClientId client) const;
  // Every live keyframe of every client's maps with its current pose, sorted by id; each map is
  // read under its shared lock once (one consistent view per map).
  std::vector<KeyframePose> keyframe_poses() const;
  // Writes client_K.txt (each in its group's frame), fused_G.txt (all frames of a group of two or
  // more clients, time-ordered), keyframes_K.txt and stats.json into dir (created if needed).
  void write_outputs(const std::string& dir) const;

  // Persistence. export_state: every client's maps, groups and trajectory, each map read under
  // its shared lock for a short copy (serialising happens elsewhere). restore_state: registers
  // the snapshot's clients with their maps and groups; throws InputError naming `source` if a
  // client is already registered or the state is inconsistent (nothing is added then for it).
  SystemState export_state() const;
  void restore_state(const SystemState& state, const std::string& source);
  // A known client starts a new recording session: a new map and time base (fused by map fusion).
  void start_new_session(ClientId id);
  // Offers every keyframe of every map to map fusion again (merging restored snapshots offline).
  void offer_keyframes_to_fusion();

 private:
  // finish(), with the system mutex held: the session-end global BA of every map that is not
  // fused with another client's map.
  void final_global_ba_locked();

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cslam
