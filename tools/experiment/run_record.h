#pragma once
// What one run of one configuration produced, as measured by the harness: the row of the
// machine-readable results (RunRecord) and the per-pose data behind the figures (RunDetail).
#include <limits>
#include <string>
#include <vector>

#include "experiment_config.h"
#include "io/trajectory_io.h"

namespace cslam::experiment {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct FusionRecord {
  double wall_time_s = kNaN;       // seconds after the SLAM system started
  int client_a = 0, client_b = 0;  // a: the client whose new keyframe found the overlap (query)
  double query_timestamp = kNaN, candidate_timestamp = kNaN;
  int frame_a = -1, frame_b = -1;  // those keyframes' frame numbers within each client's own frames (1-based)
  int inliers = 0;
  double duration_ms = kNaN;
};

struct ClientRecord {
  int id = 0;
  std::string dataset;
  int first = 0, last = 0;  // frames of the dataset (1-based, inclusive)
  int frames_processed = -1, frames_lost = -1, keyframes = -1;
  std::size_t poses = 0;  // poses in the written trajectory
  int group = -1;
  bool fused = false;
  int fused_at_frame = -1;  // this client's keyframe in the first fusion that joined it (1-based), -1: never
  double ate_rmse = kNaN;   // under the combined alignment
};

struct AteFigures {
  int n = 0;
  double max = kNaN, min = kNaN, mean = kNaN, median = kNaN, rmse = kNaN, std = kNaN;
  std::string alignment;  // "one SE3 for all clients", "one SE3 per group (not all fused)", ""
  std::string note;       // why n/a
};

struct CloudFigures {
  bool computed = false;
  std::string note;  // why n/a
  std::size_t slam_points = 0, gt_points = 0;
  double bbox_scale = kNaN;
  // SLAM-pose cloud (TEST) vs ground-truth-pose cloud (REF) after the paper's bbox matching.
  double hausdorff_bbox = kNaN, hausdorff_bbox_slam_to_gt = kNaN, c2c_mean_bbox = kNaN, c2c_median_bbox = kNaN;
  // The same without bbox matching (poses in the ground-truth frame through the ATE alignment).
  double hausdorff = kNaN, c2c_mean = kNaN, c2c_median = kNaN;
  // SLAM-pose cloud against the exact surface (synthetic scenes), one-sided TEST -> scene.
  double scene_median = kNaN, scene_mean = kNaN, scene_p95 = kNaN, scene_max = kNaN;
  double gt_scene_median = kNaN;  // the ground-truth-pose cloud against the surface, for reference
  // Network mode: the server's live dense map (dense_cloud_G.ply of the clients' one fused group,
  // built from the keyframes it received), moved by the same alignment, vs the ground-truth cloud.
  std::size_t live_points = 0;
  double live_hausdorff_bbox = kNaN, live_c2c_mean_bbox = kNaN, live_c2c_median_bbox = kNaN, live_scene_median = kNaN;
  double live_c2c_median = kNaN, live_c2c_p95 = kNaN;  // without bbox matching (its extent differs: keyframes only)
  double alignment_rotation_deg = kNaN;                // pose alignment vs the APE (position-only) alignment
  double seconds = kNaN;                               // reconstruction + metrics time
};

struct RunRecord {
  std::string config, label;
  int clients = 1;
  double overlap_percent = kNaN;
  int repeat = 1;
  std::string mode;
  bool ok = false;
  std::string error;  // why the run failed (exit status, timeout, missing output)
  std::string run_dir;
  double load_before = kNaN;      // 1-minute load average when the run started (includes the previous run)
  double slam_cpu_s = kNaN;       // CPU seconds of the run's processes (all threads, user + system)
  double other_cpu_cores = kNaN;  // cores used by everything else on the machine meanwhile
  double slam_time_s = kNaN;      // see docs/experiments.md: start of SLAM to the last frame processed
  double process_wall_s = kNaN;   // harness clock: first process started to last process exited
  double receive_span_s = kNaN;   // network: first to last frame accepted by the server
  std::vector<ClientRecord> client_records;
  std::vector<FusionRecord> fusions;
  bool all_fused = false;  // every client in one group (always true for one client)
  int groups = 0;
  int frames_lost = 0;  // summed over clients
  AteFigures ate;
  CloudFigures cloud;
};

// Per-pose data of one run for the figures, in the ground-truth frame when ground truth exists.
struct ClientTrack {
  int id = 0;
  Trajectory estimate, keyframes, groundtruth;  // groundtruth: the client's own time span
  std::vector<double> ape_time, ape;            // per associated pose
  // The estimate as written (SLAM frame) and the rigid transform that puts it into the
  // ground-truth frame for the reconstructions: fitted to positions AND orientations (see
  // pose_alignment in run_evaluation.h), one per group.
  Trajectory raw_estimate;
  Sim3 T_gt_est_cloud;
};
struct RunDetail {
  std::vector<ClientTrack> tracks;
  double time_origin = 0;  // subtracted from timestamps on the plots' time axes
  bool aligned = false;    // trajectories in the ground-truth frame
};

}  // namespace cslam::experiment
