// cslam-bench-dense: speed of dense reconstruction on a TUM sequence with ground-truth poses
// (each RGB-D pair matched to the nearest ground-truth pose within 0.02 s).
//  1. image decoding per frame (JPEG + 16-bit PNG), for reference;
//  2. back-projection + per-chunk voxel filtering over frames decoded beforehand (repeats);
//  3. TSDF integration per frame and marching-cubes mesh extraction.
// Wall-clock and process CPU time are both reported (other jobs may share the machine).
#include <sys/resource.h>

#include <cstdio>
#include <iostream>

#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "dense/reconstructor.h"
#include "dense/trajectory_recon.h"
#include "io/dataset_camera.h"
#include "dense/tsdf_volume.h"
#include "core/stats.h"
#include "io/tum_dataset.h"

using namespace cslam;

namespace {

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;
}
void print_summary(const char* what, const Summary& s, const char* unit) {
  std::printf("%-44s median %9.2f  min %9.2f  max %9.2f  %s (n=%d)\n", what, s.median, s.min, s.max, unit, s.n);
}

struct Frame {
  SE3 T_world_cam;
  cv::Mat bgr, depth;
};

int run(int argc, char** argv) {
  CliArgs args(
      "cslam-bench-dense",
      "Benchmark of back-projection + voxel filtering and TSDF fusion on a TUM sequence with ground-truth poses.");
  args.option("dataset", "TUM dataset folder with groundtruth.txt")
      .option("frames", "number of frames (0 = all associated)", "0")
      .option("repeats", "repetitions of the back-projection + filter run", "3")
      .option("stride", "pixel stride", "2")
      .option("voxel", "voxel-grid leaf (m)", "0.01")
      .option("threads", "threads", "2")
      .option("camera",
              "camera preset or file (default: DATASET/camera.yaml, else its calibration.txt (fx fy cx cy), else the "
              "TUM camera the folder name says, else tum1)",
              "")
      .option("tsdf-voxel", "TSDF voxel (m)", "0.01")
      .option("tsdf-trunc", "TSDF truncation (m)", "0.04")
      .option("tsdf-frames", "frames fused in the TSDF run (0 = all loaded)", "0")
      .flag("no-tsdf", "skip the TSDF run");
  if (!args.parse(argc, argv)) return 0;
  const TumDataset ds = open_tum_dataset(args.get("dataset"));
  if (!ds.groundtruth) throw InputError(args.get("dataset"), "no groundtruth.txt");
  const PinholeCamera cam = dataset_camera(args.get("dataset"), args.get("camera")).camera;
  std::vector<double> times;
  for (const auto& p : ds.pairs) times.push_back(p.rgb_time);
  const PoseFrameMatch m = match_poses_to_frames(*ds.groundtruth, times, 0.02);
  size_t n = m.matches.size();
  if (args.get_int("frames") > 0) n = std::min(n, size_t(args.get_int("frames")));
  std::printf("dataset %s: %zu RGB-D pairs, %zu matched to ground truth, using %zu\n", args.get("dataset").c_str(),
              ds.pairs.size(), m.matches.size(), n);

  std::vector<Frame> frames;
  std::vector<double> decode_ms;
  for (size_t i = 0; i < n; ++i) {
    Stopwatch sw;
    RgbdImages im = load_rgbd(ds.pairs[size_t(m.matches[i].second)]);
    decode_ms.push_back(sw.ms());
    frames.push_back({m.matches[i].first.T_world_cam, std::move(im.bgr), std::move(im.depth)});
  }
  print_summary("decode JPEG+PNG per frame (not in fps below)", summarize(decode_ms), "ms");

  DenseConfig cfg;
  cfg.stride = args.get_int("stride");
  cfg.voxel_size = args.get_double("voxel");
  cfg.threads = args.get_int("threads");
  std::vector<double> fps, cpu_per_frame;
  size_t points = 0;
  for (int r = 0; r < args.get_int("repeats"); ++r) {
    const double c0 = process_cpu_ms();
    Stopwatch sw;
    DenseReconstructor recon(cfg);
    for (const Frame& f : frames) recon.integrate(f.T_world_cam, f.bgr, f.depth, cam);
    const DenseResult res = recon.finish();
    const double wall = sw.ms(), cpu = process_cpu_ms() - c0;
    fps.push_back(1000.0 * double(n) / wall);
    cpu_per_frame.push_back(cpu / double(n));
    points = res.cloud.size();
    std::printf(
        "  run %d: %.1f frames/s wall, %.2f CPU-ms/frame, back-projection %.0f ms, filtering %.0f ms (filter thread), "
        "%zu raw -> %zu points, peak buffered %zu\n",
        r + 1, fps.back(), cpu_per_frame.back(), res.timing.backproject, res.timing.filter, res.raw_points, points,
        res.peak_buffered_points);
  }
  char what[128];
  std::snprintf(what, sizeof what, "back-projection + voxel filter (stride %d, %d thr)", cfg.stride, cfg.threads);
  print_summary(what, summarize(fps), "frames/s wall");
  print_summary("  CPU time per frame (all threads)", summarize(cpu_per_frame), "ms");
  std::printf("  => CPU-bound throughput on 2 cores: %.1f frames/s\n", 2000.0 / summarize(cpu_per_frame).median);

  if (!args.flag_set("no-tsdf")) {
    TsdfConfig tc;
    tc.voxel_size = float(args.get_double("tsdf-voxel"));
    tc.truncation = float(args.get_double("tsdf-trunc"));
    tc.threads = cfg.threads;
    TsdfVolume volume(tc);
    const RayTable rays(cam);
    size_t nt = frames.size();
    if (args.get_int("tsdf-frames") > 0) nt = std::min(nt, size_t(args.get_int("tsdf-frames")));
    std::vector<double> ms;
    const double c0 = process_cpu_ms();
    for (size_t i = 0; i < nt; ++i) {
      Stopwatch sw;
      volume.integrate(frames[i].bgr, frames[i].depth, rays, frames[i].T_world_cam, cfg.min_depth, cfg.max_depth);
      ms.push_back(sw.ms());
    }
    const double cpu = process_cpu_ms() - c0;
    const Summary s = summarize(ms);
    print_summary("TSDF integration per frame", s, "ms wall");
    std::printf("  TSDF: %zu frames, %.1f frames/s wall (mean), %.1f CPU-ms/frame, %zu blocks, %.1f MB\n", nt,
                1000.0 / s.mean, cpu / double(nt), volume.block_count(), volume.memory_bytes() / 1e6);
    Stopwatch sw;
    const TriangleMesh mesh = volume.extract_mesh();
    std::printf("  mesh extraction: %.0f ms, %zu vertices, %zu triangles\n", sw.ms(), mesh.vertices.size(),
                mesh.triangles.size());
  }
  std::printf("peak RSS %.0f MB (includes the %zu decoded frames held in memory)\n", peak_rss_mb(), frames.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-dense", argc, argv, run); }
