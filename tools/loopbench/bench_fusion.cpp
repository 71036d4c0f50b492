// cslam-bench-fusion: time of a map fusion on two complete maps of a chosen size.
// Two clients' maps are built offline (local mapping inline, loop closing off); the newest
// keyframe of map B whose BoW query of map A's database gives a verified candidate is the
// detection hit. From there the fusion does what FusionManager does between a hit and a fused
// map: verification (RANSAC, refinement, projection check), moving map B into A's frame and the
// seam (linking the shared points, cross-map covisibility); then, in the background, the group
// global BA over both maps. Each is repeated --runs times (map B is moved back between runs);
// median, min and max of wall-clock and process CPU ms are printed.
#include <sys/resource.h>

#include <cstdio>
#include <shared_mutex>

#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "fusion/fusion_manager.h"
#include "slam/loop/place_candidates.h"
#include "fusion/seam.h"
#include "geometry/camera_io.h"
#include "slam/loop/global_ba.h"
#include "io/tum_dataset.h"
#include "slam/map/map_locks.h"
#include "slam/client_slam.h"
#include "slam/feed_dataset.h"

using namespace cslam;

namespace {

std::shared_ptr<Map> build_map(const std::string& dir, const std::string& range, const std::string& camera, ClientId id,
                               const std::shared_ptr<const Vocabulary>& voc) {
  const TumDataset ds = open_tum_dataset(dir);
  ClientInfo info;
  info.id = id;
  info.camera = camera.empty() ? load_camera_file(dir + "/camera.yaml") : load_camera(camera);
  SlamConfig cfg;
  cfg.threaded = false;
  cfg.loop.enabled = false;
  ClientSlam slam(info, cfg, voc);
  const auto [first, last] = parse_range(range, int(ds.pairs.size()));
  feed_pairs(slam, id, select_range(ds.pairs, first, last));
  slam.finish();
  return slam.main_map();
}

void print(const char* name, const std::vector<double>& wall, const std::vector<double>& cpu) {
  const Summary w = summarize(wall), c = summarize(cpu);
  std::printf("%-34s wall median %8.1f ms (min %8.1f, max %8.1f) | CPU median %8.1f ms\n", name, w.median, w.min, w.max,
              c.median);
}

int run(int argc, char** argv) {
  CliArgs args("cslam-bench-fusion",
               "Time of a map fusion (hit to fused map) and of the group global BA on two complete maps.");
  args.option("dataset-a", "dataset of client A (the map that stays)")
      .option("dataset-b", "dataset of client B (the map that moves)")
      .option("range-a", "frames of A, a:b (1-based)", "1:")
      .option("range-b", "frames of B", "1:")
      .option("camera", "camera preset or file for both (default: each DATASET/camera.yaml)", "")
      .option("runs", "repetitions", "5")
      .option("group-ba-runs", "repetitions of the group global BA", "3");
  if (!args.parse(argc, argv)) return 0;
  set_log_level("warn");
  auto voc = std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path()));
  auto a = build_map(args.get("dataset-a"), args.get("range-a"), args.get("camera"), 1, voc);
  auto b = build_map(args.get("dataset-b"), args.get("range-b"), args.get("camera"), 2, voc);
  std::printf("map A: %zu keyframes, %zu points; map B: %zu keyframes, %zu points\n", a->num_keyframes(),
              a->num_map_points(), b->num_keyframes(), b->num_map_points());

  // The detection hit: newest keyframe of B with a verified candidate in A.
  KeyFramePtr query, candidate;
  OverlapVerifyConfig vcfg;
  {
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({a.get(), b.get()});
    auto kfs = b->keyframes();
    std::sort(kfs.begin(), kfs.end(), [](const auto& x, const auto& y) { return x->id.seq > y->id.seq; });
    for (const auto& kf : kfs) {
      if (kf->bad || kf->covisibles().empty()) continue;
      const auto groups =
          query_candidate_groups(*a, kf->data->bow, min_covisible_score(*kf), [](KeyFrameId) { return false; });
      for (const auto& g : groups) {
        KeyFramePtr c = a->keyframe(g.candidate);
        if (!c || c->bad) continue;
        if (verify_overlap(*kf, *c, c->best_covisibles(10), vcfg).accepted) {
          query = kf;
          candidate = c;
          break;
        }
      }
      if (query) break;
    }
  }
  if (!query) throw InputError("cslam-bench-fusion", "no verified overlap between the two maps");
  std::printf("hit: B keyframe %u (t=%.3f) -> A keyframe %u (t=%.3f)\n", query->id.seq, query->timestamp(),
              candidate->id.seq, candidate->timestamp());

  const int runs = args.get_int("runs");
  std::vector<double> wv, cv, wt, ct, ws, cs, wtot, ctot;
  int seam_points = 0;
  for (int r = 0; r < runs; ++r) {
    Stopwatch total;
    const double c0 = process_cpu_ms();
    Stopwatch sw;
    OverlapVerifyResult v;
    SE3 T_a_b;
    {
      auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({a.get(), b.get()});
      v = verify_overlap(*query, *candidate, candidate->best_covisibles(10), vcfg);
      // T_wb_wa = T_wb_q * S_q_c * T_c_wa: A into B's frame; B moves into A's by the inverse.
      T_a_b = (query->T_world_cam() * v.S_query_candidate.to_se3() * candidate->T_cam_world).inverse();
    }
    wv.push_back(sw.ms());
    const double c1 = process_cpu_ms();
    cv.push_back(c1 - c0);
    sw.reset();
    transform_map(*b, T_a_b);
    wt.push_back(sw.ms());
    const double c2 = process_cpu_ms();
    ct.push_back(c2 - c1);
    sw.reset();
    {
      auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({a.get(), b.get()});
      seam_points = int(connect_seam(*a, *candidate, *b, *query).points.size());
    }
    ws.push_back(sw.ms());
    const double c3 = process_cpu_ms();
    cs.push_back(c3 - c2);
    wtot.push_back(total.ms());
    ctot.push_back(c3 - c0);
    transform_map(*b, T_a_b.inverse());  // back for the next run (not timed)
  }
  std::printf("seam points %d; %d runs\n", seam_points, runs);
  print("verification", wv, cv);
  print("move map B", wt, ct);
  print("seam (link points, edges)", ws, cs);
  print("fusion total (hit to fused map)", wtot, ctot);

  // Group global BA over both maps (background part), in A's frame with the seam links.
  {
    SE3 T_a_b;
    {
      auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({a.get(), b.get()});
      const auto v = verify_overlap(*query, *candidate, candidate->best_covisibles(10), vcfg);
      T_a_b = (query->T_world_cam() * v.S_query_candidate.to_se3() * candidate->T_cam_world).inverse();
    }
    transform_map(*b, T_a_b);
    std::vector<std::pair<MapPointPtr, MapPointPtr>> links;
    {
      auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({a.get(), b.get()});
      for (const auto& l : connect_seam(*a, *candidate, *b, *query).points) links.emplace_back(l.kept, l.moved);
    }
    std::vector<double> wg, cg;
    std::size_t points = 0;
    for (int r = 0; r < args.get_int("group-ba-runs"); ++r) {
      Stopwatch sw;
      const double c0 = process_cpu_ms();
      GlobalBa gba;
      {
        auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({a.get(), b.get()});
        gba.snapshot({a.get(), b.get()}, links);
      }
      const BaResult res = gba.solve(FusionConfig().group_ba_iterations, nullptr);
      {
        auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({a.get(), b.get()});
        gba.apply(res);
      }
      wg.push_back(sw.ms());
      cg.push_back(process_cpu_ms() - c0);
      points = gba.num_points();
    }
    std::printf("group global BA: %zu keyframes, %zu points, %zu linked pairs\n",
                a->num_keyframes() + b->num_keyframes(), points, links.size());
    print("group global BA", wg, cg);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-fusion", argc, argv, run); }
