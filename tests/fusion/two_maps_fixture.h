#pragma once
// Two clients' maps of the small synthetic scene (robots 1 and 2 cross the same places), built
// offline with local mapping inline, plus their keyframes' ground truth; for seam and group-BA tests.
#include <memory>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "eval/pose_check.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "slam/map/map.h"
#include "slam/client_slam.h"
#include "slam/feed_dataset.h"

namespace cslam::test {

struct ClientMap {
  std::shared_ptr<Map> map;
  Trajectory groundtruth;
  SE3 T_gtworld_map;  // ground-truth pose of the map's origin keyframe
};

inline ClientMap build_client_map(const std::string& robot_dir, ClientId id,
                                  const std::shared_ptr<const Vocabulary>& voc) {
  const TumDataset ds = open_tum_dataset(robot_dir);
  ClientInfo info;
  info.id = id;
  info.camera = load_camera_file(robot_dir + "/camera.yaml");
  SlamConfig cfg;
  cfg.threaded = false;
  cfg.loop.enabled = false;
  ClientSlam slam(info, cfg, voc);
  feed_pairs(slam, id, ds.pairs);
  slam.finish();
  ClientMap out;
  out.map = slam.main_map();
  out.groundtruth = *ds.groundtruth;
  sort_by_time(out.groundtruth);
  std::shared_lock<std::shared_mutex> lock(out.map->mutex);
  out.T_gtworld_map =
      *interpolate_pose(out.groundtruth, out.map->origin()->timestamp()) * out.map->origin()->T_cam_world;
  return out;
}

// Keyframe trajectory of a map (camera-to-world) [shared lock].
inline Trajectory keyframe_trajectory(const Map& map) {
  Trajectory t;
  for (const auto& kf : map.keyframes())
    if (!kf->bad) t.push_back({kf->timestamp(), kf->T_world_cam()});
  sort_by_time(t);
  return t;
}

struct TwoMaps {
  ClientMap a, b;
};

// Renders the small synthetic scene into `dir` and maps robots 1 and 2 (clients 1 and 2).
inline TwoMaps build_two_maps(const TempDir& dir) {
  const auto r =
      run_program("cslam-synth", "--preset test-small --seed 5 --out " + (dir / "scene") + " --log-level warn");
  if (r.status != 0) throw std::runtime_error("cslam-synth failed: " + r.output);
  auto voc = std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path()));
  return {build_client_map(dir / "scene/robot_1", 1, voc), build_client_map(dir / "scene/robot_2", 2, voc)};
}

// Moves map b into map a's frame using ground truth, then by `T_error` (an imperfect fusion).
}  // namespace cslam::test
