#pragma once
// The report's figures (SVG, src/support/report/svg_plot): per configuration, from its representative
// run, APE over time with the fusion points, X-Y trajectories of every client against ground
// truth (keyframes as dots), x/y/z and roll/pitch/yaw over time; one overview of SLAM time and
// APE RMSE against the overlap rate (or the number of clients).
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "report_writer.h"
#include "run_record.h"

namespace cslam::experiment {

using DetailMap = std::map<std::pair<std::string, int>, RunDetail>;  // (config, repeat) -> detail

// Writes OUT_DIR/figures/*.svg, sets each summary's figures (paths relative to OUT_DIR) and
// returns the overview figures' paths. max_points: points kept per plotted line.
std::vector<std::string> write_figures(const std::string& out_dir, std::vector<ConfigSummary>& summaries,
                                       const DetailMap& details, std::size_t max_points = 400);

// Rotation vector (axis times angle, degrees; angle in [0, 180]) of a rotation.
Eigen::Vector3d rotation_vector_deg(const Eigen::Quaterniond& q);

// Roll, pitch, yaw (degrees) of R = Rz(yaw) Ry(pitch) Rx(roll).
struct Rpy {
  double roll = 0, pitch = 0, yaw = 0;
};
Rpy roll_pitch_yaw_deg(const SE3& T);

}  // namespace cslam::experiment
