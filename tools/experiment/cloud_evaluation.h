#pragma once
// Table III: dense reconstruction of a run from its SLAM poses (already in the ground-truth frame
// through the ATE alignment) and from the ground-truth poses of the same frames, compared with
// the paper's bounding-box matching, without it, and against the exact surface when there is one.
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "cloud/point_cloud.h"
#include "dense/reconstructor.h"
#include "experiment_config.h"
#include "run_evaluation.h"
#include "run_record.h"

namespace cslam::experiment {

class CloudEvaluator {
 public:
  // scene_ply may be empty. camera: preset or file for every dataset; empty: io/dataset_camera.h.
  CloudEvaluator(ReconOptions options, std::string scene_ply, std::string camera, std::string cache_dir);

  // Never throws for bad data: a cloud that cannot be built or compared gives figures with a note.
  CloudFigures evaluate(const RunDetail& detail, const std::vector<ClientSpec>& specs, DatasetStore& datasets,
                        const std::string& run_dir);

 private:
  const ColoredCloud& groundtruth_cloud(const RunDetail& detail, const std::vector<ClientSpec>& specs,
                                        DatasetStore& datasets, std::string& key);
  const std::vector<Eigen::Vector3f>& scene_points();
  // Network runs: the server's live dense cloud against the same ground-truth cloud.
  void evaluate_live(const RunDetail& detail, const ColoredCloud& gt, const std::string& run_dir, CloudFigures& f);
  // The SLAM poses' cloud, built in the SLAM's frame and moved into the ground truth's.
  DenseResult slam_cloud(const RunDetail& detail, const std::vector<ClientSpec>& specs) const;

  ReconOptions options_;
  std::string scene_ply_, camera_, cache_dir_;
  std::optional<std::vector<Eigen::Vector3f>> scene_;
  std::map<std::string, ColoredCloud> gt_clouds_;  // by the frames they were built from
  std::map<std::string, double> gt_scene_median_;
};

}  // namespace cslam::experiment
