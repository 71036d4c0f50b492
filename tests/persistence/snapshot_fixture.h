#pragma once
// A client's SLAM state on the small synthetic scene (robot 1, first `frames` frames, mapping
// inline, deterministic) for the snapshot tests, built once per test binary.
#include <memory>

#include "common/run_program.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "slam/client_slam.h"
#include "slam/client_slam_state.h"
#include "slam/feed_dataset.h"
#include "system/system_state.h"

namespace cslam::test {

struct SnapshotScene {
  TempDir dir{"cslam_snapshot_scene"};
  std::shared_ptr<const Vocabulary> vocabulary;
  TumDataset robot1;
  ClientInfo info;
  SlamConfig config;

  SnapshotScene() {
    const auto r = run_program(
        "cslam-synth", "--preset test-small --frames 120 --seed 5 --out " + (dir / "scene") + " --log-level warn");
    if (r.status != 0) throw std::runtime_error("cslam-synth failed: " + r.output);
    vocabulary = std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path()));
    robot1 = open_tum_dataset(dir / "scene/robot_1");
    info.id = 1;
    info.name = "robot1";
    info.camera = load_camera_file(dir / "scene/robot_1/camera.yaml");
    config.threaded = false;
    config.loop.enabled = false;
  }
  std::vector<RgbdPair> pairs(std::size_t first, std::size_t last) const {
    last = std::min(last, robot1.pairs.size());
    return {robot1.pairs.begin() + long(first), robot1.pairs.begin() + long(last)};
  }
};

// Feeds pairs with increasing sender seqs starting at first_seq.
inline void feed_with_seq(ClientSlam& slam, ClientId id, const std::vector<RgbdPair>& pairs, std::uint64_t first_seq) {
  std::uint64_t seq = first_seq;
  for (const auto& p : pairs) {
    const auto im = load_rgbd(p);
    RgbdFrame f;
    f.client = id;
    f.seq = seq++;
    f.timestamp = p.rgb_time;
    f.bgr = im.bgr;
    f.depth = im.depth;
    slam.process(f);
  }
}

}  // namespace cslam::test
