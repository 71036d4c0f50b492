// cslam-recon: dense coloured reconstruction from one or more trajectories over TUM-layout
// datasets (poses matched to RGB-D pairs by timestamp), voxel-filtered cloud (PLY or PCD) and
// optionally a TSDF mesh (PLY).
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>

#include "cloud/pcd_io.h"
#include "cloud/ply_io.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/progress.h"
#include "dense/trajectory_recon.h"
#include "io/dataset_camera.h"
#include "eval/trajectory_eval.h"
#include "io/trajectory_io.h"

using namespace cslam;

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

void print_counts(const DenseCounts& c) {
  std::fprintf(stderr,
               "frames used %d; skipped: no image within the time gap %d, non-finite pose %d, bad/unreadable image %d, "
               "wrong image size %d, no valid depth %d\n",
               c.used, c.no_image, c.bad_pose, c.bad_image, c.wrong_size, c.no_valid_depth);
}

int run(int argc, char** argv) {
  CliArgs args(
      "cslam-recon",
      "Dense reconstruction: back-projects each posed RGB-D frame, voxel-filters per chunk, writes a coloured "
      "cloud (binary PLY, or PCD if --out ends in .pcd) and optionally a TSDF mesh. With one --dataset every "
      "trajectory refers to it (client lists are merged, any order); with several, trajectory k goes with dataset k.");
  args.multi_option("dataset", "TUM-layout dataset folder(s) (rgb.txt, depth.txt)")
      .multi_option("poses", "trajectory file(s), TUM format 'timestamp x y z qx qy qz qw', camera-to-world")
      .option("out", "output cloud (.ply or .pcd)")
      .option("pcd", "also write the cloud as PCD to this path", "")
      .option("mesh", "also fuse a TSDF and write its marching-cubes mesh (PLY) here", "")
      .option("voxel", "voxel-grid leaf size (m)", "0.01")
      .option("stride", "back-project every n-th pixel in u and v", "2")
      .option("min-depth", "minimum depth (m)", "0.3")
      .option("max-depth", "maximum depth (m)", "4.0")
      .option("max-dt", "maximum pose/image timestamp gap (s)", "0.02")
      .option("chunk", "frames per filtering chunk", "30")
      .option("threads", "worker threads (>= 2: loading and filtering beside back-projection)", "2")
      .flag("outliers", "statistical outlier removal on the final cloud")
      .flag("no-depth-time", "place each depth image at its colour image's pose, not at its own time (ablation)")
      .option("outlier-k", "neighbours for outlier removal", "20")
      .option("outlier-std", "standard-deviation multiplier for outlier removal", "2.0")
      .option("tsdf-voxel", "TSDF voxel size (m)", "0.01")
      .option("tsdf-trunc", "TSDF truncation distance (m)", "0.04")
      .option("tsdf-every", "fuse every n-th used frame into the TSDF", "1")
      .option("camera",
              "camera preset or file for every dataset (default: each DIR/camera.yaml, else its calibration.txt (fx fy "
              "cx cy), else the TUM camera its folder name says (freiburg1..3, fr1..3), else tum1)",
              "")
      .option("align-to",
              "evaluation aid: SE3-align the poses to this ground-truth trajectory first (Umeyama over "
              "timestamp-associated positions), so SLAM-pose and ground-truth-pose clouds share a frame",
              "")
      .option("log-level", "trace|debug|info|warn|error|off", "info");
  if (!args.parse(argc, argv)) return 0;
  set_log_level(args.get("log-level"));
  const auto datasets = args.get_multi("dataset");
  const auto pose_files = args.get_multi("poses");
  if (datasets.empty()) throw ConfigError("--dataset is required (see --help)");
  if (pose_files.empty()) throw ConfigError("--poses is required (see --help)");
  if (datasets.size() > 1 && datasets.size() != pose_files.size())
    throw ConfigError("with several --dataset folders give one --poses file per dataset");

  DenseConfig cfg;
  cfg.voxel_size = args.get_double("voxel");
  cfg.stride = args.get_int("stride");
  cfg.min_depth = args.get_double("min-depth");
  cfg.max_depth = args.get_double("max-depth");
  cfg.max_time_gap = args.get_double("max-dt");
  cfg.chunk_frames = args.get_int("chunk");
  cfg.threads = args.get_int("threads");
  cfg.remove_outliers = args.flag_set("outliers");
  cfg.depth_time_compensation = !args.flag_set("no-depth-time");
  cfg.outliers.mean_k = args.get_int("outlier-k");
  cfg.outliers.stddev_mul = args.get_double("outlier-std");
  const std::string mesh_path = args.get("mesh");
  cfg.build_mesh = !mesh_path.empty();
  cfg.tsdf.voxel_size = float(args.get_double("tsdf-voxel"));
  cfg.tsdf.truncation = float(args.get_double("tsdf-trunc"));
  cfg.tsdf.every = args.get_int("tsdf-every");
  cfg.tsdf.threads = cfg.threads;
  cfg.validate();
  const std::string out = args.get("out");
  if (!ends_with(out, ".ply") && !ends_with(out, ".pcd")) throw ConfigError("--out must end in .ply or .pcd");

  std::vector<DatasetPoses> sources;
  size_t total_poses = 0;
  for (size_t k = 0; k < datasets.size(); ++k) {
    DatasetPoses s;
    s.dataset_dir = datasets[k];
    s.camera = dataset_camera(datasets[k], args.get("camera")).camera;
    if (datasets.size() == 1) {
      for (const auto& f : pose_files) {
        const Trajectory t = read_tum_trajectory(f);
        s.poses.insert(s.poses.end(), t.begin(), t.end());
      }
    } else {
      s.poses = read_tum_trajectory(pose_files[k]);
    }
    total_poses += s.poses.size();
    sources.push_back(std::move(s));
  }
  if (!args.get("align-to").empty()) {
    const Trajectory gt = read_tum_trajectory(args.get("align-to"));
    for (auto& s : sources) {
      const AteResult ate = compute_ate(gt, s.poses, Alignment::kSE3, cfg.max_time_gap);
      for (auto& p : s.poses) p.T_world_cam = apply_sim3_to_pose(ate.T_gt_est, p.T_world_cam);
      std::fprintf(stderr, "aligned %s to %s: ATE rmse %.4f m over %d poses\n", s.dataset_dir.c_str(),
                   args.get("align-to").c_str(), ate.stats.rmse, ate.stats.n);
    }
  }
  std::fprintf(stderr, "cslam-recon: %zu poses from %zu trajectory file(s), %zu dataset(s)\n", total_poses,
               pose_files.size(), datasets.size());

  std::optional<Progress> progress;  // created at the first frame, when the frame count is known
  const DenseResult r = reconstruct_from_trajectories(sources, cfg, [&](const DenseProgress& p) {
    if (!progress) progress.emplace("cslam-recon: integrated", std::uint64_t(p.total), "frames");
    progress->update(std::uint64_t(p.done), "used " + std::to_string(p.used));
    if (p.done == p.total) progress->finish();
  });
  print_counts(r.counts);
  if (r.cloud.empty())
    throw InputError(datasets.front(), "no points reconstructed (" + std::to_string(r.counts.used) +
                                           " frames used of " + std::to_string(total_poses) +
                                           " poses); nothing written");
  if (ends_with(out, ".pcd"))
    write_pcd(out, r.cloud);
  else
    write_ply(out, r.cloud);
  if (!args.get("pcd").empty()) write_pcd(args.get("pcd"), r.cloud);
  const BoundingBox bb = bounding_box(r.cloud.points);
  std::fprintf(stderr, "cloud: %zu points (from %zu raw), bbox [%.2f %.2f %.2f] - [%.2f %.2f %.2f] m -> %s\n",
               r.cloud.size(), r.raw_points, bb.min.x(), bb.min.y(), bb.min.z(), bb.max.x(), bb.max.y(), bb.max.z(),
               out.c_str());
  if (cfg.build_mesh) {
    if (r.mesh.triangles.empty())
      throw InputError(datasets.front(), "TSDF produced an empty mesh; nothing written to " + mesh_path);
    write_ply_mesh(mesh_path, r.mesh);
    std::fprintf(stderr, "mesh: %zu vertices, %zu triangles, %zu TSDF blocks (%.1f MB) -> %s\n", r.mesh.vertices.size(),
                 r.mesh.triangles.size(), r.tsdf_blocks, r.tsdf_bytes / 1e6, mesh_path.c_str());
  }
  const DenseTiming& t = r.timing;
  std::fprintf(stderr,
               "time (ms): total %.0f | load %.0f, back-projection %.0f, filtering %.0f, outliers %.0f, tsdf %.0f, "
               "mesh %.0f | %.1f frames/s\n",
               t.total, t.load, t.backproject, t.filter, t.outliers, t.tsdf, t.mesh,
               t.total > 0 ? 1000.0 * (r.counts.used + r.counts.skipped() - r.counts.no_image) / t.total : 0.0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-recon", argc, argv, run); }
