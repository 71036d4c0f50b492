#pragma once
// Writes synthetic RGB-D sequences in the TUM RGB-D layout, so every tool reads them exactly like
// a real dataset:
//   OUT/robot_<k>/{rgb/, depth/, rgb.txt, depth.txt, groundtruth.txt, camera.yaml}  (k = 1..K)
//   OUT/whole/...                           (instead of robot_<k>, in whole-sequence mode)
//   OUT/scene.ply                           ground-truth surface (see surface_sampling.h)
//   OUT/scene.json                          seed, every parameter, furniture, robot paths
// Everything is first written to OUT.tmp-<pid> and renamed to OUT at the end, so a partly
// written folder never looks complete.
#include <cstdint>
#include <string>
#include <vector>

#include "support/synth/renderer.h"
#include "support/synth/synth_config.h"

namespace cslam::synth {

struct DatasetResult {
  std::string out_dir;
  std::vector<std::string> sequences;  // folders written (absolute or as given)
  int frames = 0;                      // RGB-D frames in all sequences
  size_t surface_points = 0;
  double seconds = 0;
};

// Renders one trajectory into `dir` (created) in the TUM layout with camera.yaml. Frames are
// rendered by `threads` workers (joined before returning). Noise (if enabled in the renderer) is
// seeded per frame from noise_seed. Throws InputError naming the file on a write failure.
void write_sequence(const std::string& dir, const Renderer& renderer, const Trajectory& trajectory,
                    std::uint64_t noise_seed, int threads = 1, int png_compression = 1);

// Writes the whole dataset of an already built scene and plan (atomically, see above).
// Throws InputError if OUT exists (unless overwrite) or cannot be written, ConfigError on bad options.
DatasetResult write_dataset(const Scene& scene, const TrajectoryPlan& plan, const SynthConfig& config);

// make_scene + plan_trajectories + write_dataset.
DatasetResult generate_dataset(const SynthConfig& config);

}  // namespace cslam::synth
