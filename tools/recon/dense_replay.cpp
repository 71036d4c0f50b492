// cslam-dense-replay: the server's live dense map rebuilt offline from keyframe trajectories
// (the server's keyframes_<client>.txt, or any TUM trajectory) over a TUM-layout dataset, through
// the same LiveDenseMap the server runs: TSDF submaps per window of a client's keyframes, meshed,
// then the group cloud (one point per voxel of the submaps' vertices) and mesh as the server
// writes them. Separates the dense map's own accuracy from the poses it was given and from the
// server's timing (every keyframe at its final pose, depth at the colour image's pose).
#include <cstdio>
#include <map>
#include <optional>

#include "cloud/ply_io.h"
#include "core/cli.h"
#include "core/error.h"
#include "dense/live_dense_map.h"
#include "dense/mesh_lod.h"
#include "eval/trajectory_eval.h"
#include "io/dataset_camera.h"
#include "io/trajectory_io.h"
#include "io/tum_dataset.h"

using namespace cslam;

namespace {

// The RGB-D pair nearest to t (by colour time), if within max_dt.
const RgbdPair* pair_at(const TumDataset& ds, double t, double max_dt) {
  const RgbdPair* best = nullptr;
  for (const RgbdPair& p : ds.pairs)
    if (std::abs(p.rgb_time - t) <= max_dt && (!best || std::abs(p.rgb_time - t) < std::abs(best->rgb_time - t)))
      best = &p;
  return best;
}

int run(int argc, char** argv) {
  CliArgs args("cslam-dense-replay",
               "Rebuilds the live dense map offline: each --keyframes file is one client's keyframe trajectory (TUM, "
               "camera-to-world) over --dataset; writes the group cloud (--out) and mesh (--mesh) as the server does.");
  args.option("dataset", "TUM-layout dataset folder (rgb.txt, depth.txt)")
      .multi_option("keyframes", "keyframe trajectory file(s), one per client")
      .option("out", "output cloud (PLY)")
      .option("mesh", "also write the merged mesh (PLY) here", "")
      .option("align-to", "evaluation aid: SE3-align all keyframes to this ground-truth trajectory first", "")
      .option("voxel", "TSDF voxel of the submaps (m)", "0.02")
      .option("submap-keyframes", "keyframes per submap", "8")
      .option("max-dt", "maximum pose/image timestamp gap (s)", "0.02");
  if (!args.parse(argc, argv)) return 0;
  const TumDataset ds = open_tum_dataset(args.get("dataset"));
  const PinholeCamera camera = dataset_camera(args.get("dataset")).camera;
  LiveDenseConfig config;
  config.tsdf.voxel_size = float(args.get_double("voxel"));
  config.tsdf.truncation = 4 * config.tsdf.voxel_size;
  config.keyframes_per_submap = args.get_int("submap-keyframes");
  config.integration_delay_s = 0;
  LiveDenseMap map(config);

  std::vector<Trajectory> clients;
  for (const auto& f : args.get_multi("keyframes")) clients.push_back(read_tum_trajectory(f));
  if (!args.get("align-to").empty()) {
    Trajectory all;
    for (const auto& t : clients) all.insert(all.end(), t.begin(), t.end());
    const AteResult ate = compute_ate(read_tum_trajectory(args.get("align-to")), all, Alignment::kSE3, 0.02);
    for (auto& t : clients)
      for (auto& p : t) p.T_world_cam = apply_sim3_to_pose(ate.T_gt_est, p.T_world_cam);
    std::fprintf(stderr, "aligned %zu keyframes: ATE rmse %.4f m\n", all.size(), ate.stats.rmse);
  }
  std::vector<KeyframePose> poses;
  std::map<KeyFrameId, const RgbdPair*> pairs;
  for (std::size_t c = 0; c < clients.size(); ++c) {
    const ClientId client = ClientId(c + 1);
    map.set_camera(client, camera);
    std::uint32_t seq = 0;
    for (const auto& p : clients[c]) {
      const RgbdPair* pair = pair_at(ds, p.timestamp, args.get_double("max-dt"));
      if (!pair) continue;
      const KeyFrameId id{client, ++seq};
      poses.push_back({id, 100, 0, p.T_world_cam});
      pairs[id] = pair;
      map.add_keyframe(id, std::nullopt, 0.0);
    }
  }
  const DenseImageLoader loader = [&](KeyFrameId id) -> std::optional<DenseImages> {
    const RgbdImages im = load_rgbd(*pairs.at(id));
    return DenseImages{im.bgr, im.depth};
  };
  const DenseStepResult r = map.flush(poses, loader);
  const auto view = map.view();
  std::vector<PlacedMesh> placed;
  for (const auto& s : view->submaps)
    if (s.mesh && !s.mesh->vertices.empty()) placed.push_back({s.mesh.get(), s.T_world_submap});
  const ColoredCloud cloud = mesh_vertices_cloud(placed, config.tsdf.voxel_size);
  write_ply(args.get("out"), cloud);
  if (!args.get("mesh").empty()) write_ply_mesh(args.get("mesh"), merge_meshes(placed));
  std::printf("%zu keyframes integrated into %zu submaps (%d without images); cloud %zu points -> %s\n",
              view->keyframes_integrated, view->submaps.size(), r.missing_images, cloud.size(),
              args.get("out").c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-dense-replay", argc, argv, run); }
