#pragma once
// Reads one run's outputs (trajectories, stats.json, summary.json / network_stats.json) and
// measures them against ground truth: SLAM time, frames lost, fusion events and the frames they
// happened at, and the APE of the combined trajectory (one SE3 alignment for all clients).
#include <map>
#include <string>

#include "experiment_config.h"
#include "io/tum_dataset.h"
#include "run_record.h"

namespace cslam::experiment {

// Opens each dataset once (the association of RGB-D pairs is reused by every run).
class DatasetStore {
 public:
  const TumDataset& get(const std::string& dir);

 private:
  std::map<std::string, TumDataset> datasets_;
};

// Fills everything in record except `cloud`, and the figures' data in detail. Throws InputError
// naming the file if an output is missing or malformed (the run then counts as failed).
void evaluate_run(const RunConfig& config, RunMode mode, const std::string& out_dir, DatasetStore& datasets,
                  RunRecord& record, RunDetail& detail);

// The 1-based position, among frames [first, last] of the dataset, of the pair whose RGB
// timestamp is nearest to t (within max_dt); -1 if none is.
int frame_number_at(const TumDataset& dataset, int first, int last, double t, double max_dt = 0.02);

// Rigid (SE3) alignment of several estimates to their ground truth using camera positions and
// points `reach` metres along each camera axis, so that orientations count as well as positions.
// A position-only fit (the APE alignment) leaves the rotation about a nearly straight path, or
// every rotation of a camera turning in place, badly constrained; a cloud rendered with such
// an alignment is tilted even if the positions fit. Throws InputError if < 3 poses associate.
Sim3 pose_alignment(const std::vector<std::pair<Trajectory, Trajectory>>& gt_est_pairs, double reach = 1.0,
                    double max_dt = 0.02);

// Ground-truth poses at the given timestamps (linear/slerp interpolation between the samples
// around t, or the nearest sample within max_dt at the ends); timestamps without ground truth
// are skipped. Used for the ground-truth-pose reconstruction of exactly the frames SLAM posed.
Trajectory groundtruth_at(const Trajectory& groundtruth, const std::vector<double>& timestamps, double max_dt = 0.02);

}  // namespace cslam::experiment
