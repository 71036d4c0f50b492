// Offline multi-client mode of cslam-slam: splits one sequence with the paper's ranges (or takes
// one dataset per client) and runs the collaborative system in-process, as cslam-server does
// over the network.
#include "multi.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <thread>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "eval/split.h"
#include "eval/trajectory_eval.h"
#include "frame/frame_done.h"
#include "geometry/camera_io.h"
#include "io/dataset_camera.h"
#include "io/tum_dataset.h"
#include "system/collaborative_system.h"
#include "io/dataset_frame.h"

namespace cslam {

namespace {

struct ClientJob {
  ClientInfo info;
  std::vector<RgbdPair> pairs;
  std::optional<Trajectory> groundtruth;
  std::unique_ptr<LeanStreamSim> lean;
};

}  // namespace

PinholeCamera camera_for(const CliArgs& args, const std::string& dir) {
  PinholeCamera camera = dataset_camera(dir, args.get("camera")).camera;
  if (args.has("readout")) {
    camera.readout_time = args.get_double("readout");
    camera.validate();
  }
  return camera;
}

LeanStreamConfig lean_stream_config(const CliArgs& args) {
  LeanStreamConfig c;
  c.depth_every = args.get_int("depth-every");
  c.request_delay = args.get_int("depth-request-delay");
  c.light_depth = args.get_int("light-depth");
  c.coded_colour = args.flag_set("coded-colour");
  c.full_colour.rgb = parse_rgb_codec(args.get("rgb-codec"), c.depth_every > 1);
  c.full_colour.jpeg_quality = args.get_int("jpeg-quality");
  c.full_colour.h264_intra_crf = args.get_int("h264-intra-crf");
  c.light_colour.crf = args.get_int("colour-crf");
  if (c.coded_colour) c.budget.bytes_per_s = args.get_double("byte-budget") * 1e6;
  c.budget.frame_rate = args.get_double("stream-rate");
  return c;
}

int run_multi_client(const CliArgs& args) {
  std::vector<ClientJob> jobs;
  auto datasets = args.get_multi("datasets");
  if (!datasets.empty()) {
    for (size_t k = 0; k < datasets.size(); ++k) {
      const TumDataset ds = open_tum_dataset(datasets[k], 0.02, parse_association(args.get("association")));
      ClientJob j;
      j.info.id = ClientId(k + 1);
      j.info.name = std::filesystem::path(datasets[k]).filename().string();
      j.info.camera = camera_for(args, datasets[k]);
      j.pairs = ds.pairs;
      j.groundtruth = ds.groundtruth;
      jobs.push_back(std::move(j));
    }
  } else {
    const std::string dir = args.get("dataset");
    const TumDataset ds = open_tum_dataset(dir, 0.02, parse_association(args.get("association")));
    const int k = args.get_int("clients");
    const SplitResult split = split_sequence(int(ds.pairs.size()), k, parse_overlap_rate(args.get("overlap")));
    for (int c = 0; c < k; ++c) {
      ClientJob j;
      j.info.id = ClientId(c + 1);
      j.info.name = "client" + std::to_string(c + 1);
      j.info.camera = camera_for(args, dir);
      j.pairs = select_range(ds.pairs, split.ranges[c].first, split.ranges[c].last);
      j.groundtruth = ds.groundtruth;
      std::printf("client %d: frames %d-%d (%d)\n", c + 1, split.ranges[c].first, split.ranges[c].last,
                  split.ranges[c].count());
      jobs.push_back(std::move(j));
    }
  }

  for (auto& j : jobs) j.lean = std::make_unique<LeanStreamSim>(lean_stream_config(args));

  SystemConfig config;
  // Tracking wanted full depth on a light frame: that client's robot sends it once the request
  // has come back (LeanStreamSim's delay stands for the acks in flight).
  config.on_frame_done = [&jobs](const FrameDone& done) {
    for (auto& j : jobs) {
      if (j.info.id != done.client) continue;
      j.lean->keyframe_hint(int(done.seq), done.keyframe_due_in);
      if (done.wants_depth) j.lean->requested(int(done.seq));
    }
  };
  config.vocabulary_path = args.get("vocab");
  // --sync: one thread steps every client frame by frame (round robin, as robots streaming at
  // once) with local mapping, loop closing and fusion run inline: the same input gives the same
  // output. Otherwise each client has its worker threads and fusion its own thread.
  const bool stepped = args.flag_set("sync");
  config.stepped = stepped;
  config.slam.threaded = !stepped;
  config.fusion.threaded = !stepped;
  config.slam.mapper.local_ba = !args.flag_set("no-local-ba");
  config.slam.mapper.tracking_wait = parse_tracking_wait(args.get("tracking-wait"));
  config.slam.mapper.triangulation.enabled = !args.flag_set("no-triangulation");
  config.slam.loop.enabled = !args.flag_set("no-loop");
  if (args.flag_set("no-final-ba")) config.slam.final_global_ba_iterations = 0;
  config.slam.rgbd.depth_time_compensation = args.flag_set("depth-time");
  config.slam.tracker.flow.mode = parse_flow_mode(args.get("flow"));
  config.fusion.enabled = !args.flag_set("no-fusion");
  config.fusion.group_ba = !args.flag_set("no-group-ba");
  config.fusion.reencounter.enabled = !args.flag_set("no-reencounter");
  CollaborativeSystem system(config);
  for (const auto& j : jobs) system.add_client(j.info);

  // Submits frame i of a client; false once the system stops taking frames.
  auto feed = [&system](const ClientJob& j, std::size_t i) {
    const RgbdPair& p = j.pairs[i];
    try {
      RgbdFrame frame = load_dataset_frame(p, j.info.id, std::uint64_t(i));
      j.lean->apply(frame, int(i));
      return system.submit(std::move(frame));
    } catch (const InputError& e) {
      logger("slam")->error("client {}: {}", j.info.id, e.what());
      return true;
    }
  };
  Stopwatch wall;
  if (stepped) {
    std::size_t longest = 0;
    for (const auto& j : jobs) longest = std::max(longest, j.pairs.size());
    for (std::size_t i = 0; i < longest; ++i)
      for (const auto& j : jobs)
        if (i < j.pairs.size()) feed(j, i);
  } else {
    // One feeder thread per client, as K robots streaming at once.
    std::vector<std::thread> feeders;
    for (const auto& j : jobs)
      feeders.emplace_back([&feed, &j] {
        for (std::size_t i = 0; i < j.pairs.size(); ++i)
          if (!feed(j, i)) break;
      });
    for (auto& t : feeders) t.join();
  }
  system.finish();
  const double slam_time = wall.ms() / 1000.0;

  const std::string out = args.get("out-dir");
  system.write_outputs(out);
  const auto trajs = system.trajectories();
  const auto groups = system.groups();
  const auto snap = system.snapshot();
  nlohmann::json summary = {{"slam_time_s", slam_time}, {"clients", jobs.size()}};
  std::printf("SLAM time %.2f s for %zu clients\n", slam_time, jobs.size());
  for (const auto& j : jobs)
    if (j.lean->light_frames() > 0)
      std::printf("client %u: light frames %d of %zu, %d full frames finer within the byte budget\n", j.info.id,
                  j.lean->light_frames(), j.pairs.size(), j.lean->frames_finer());
  for (const auto& e : snap.events)
    std::printf(
        "fusion: client %u + client %u -> group %d at %.2f s (frame time %.3f), %d inliers, %d + %d keyframes, "
        "%d seam points, %d cross-map edges, %.1f ms\n",
        e.client_a, e.client_b, e.group.value(), e.wall_time_s, e.query_timestamp, e.inliers, e.keyframes_moved,
        e.keyframes_kept, e.seam_points, e.seam_edges, e.duration_ms);
  if (snap.group_ba.started > 0) {
    const Summary gba = summarize(snap.group_ba.ms);
    std::printf("group global BA: %d started, %d completed, %d discarded, median %.0f ms\n", snap.group_ba.started,
                snap.group_ba.completed, snap.group_ba.discarded, gba.median);
  }
  // Accuracy per client and per fused group, where ground truth exists.
  for (const auto& j : jobs) {
    if (!j.groundtruth) continue;
    try {
      const auto r = compute_ate(*j.groundtruth, trajs.at(j.info.id), Alignment::kSE3);
      std::printf("client %u ATE rmse %.4f m (n=%d)\n", j.info.id, r.stats.rmse, r.stats.n);
      summary["ate_rmse_client_" + std::to_string(j.info.id)] = r.stats.rmse;
    } catch (const InputError& e) {
      std::printf("client %u ATE n/a: %s\n", j.info.id, e.what());
    }
  }
  for (const auto& [g, members] : groups) {
    if (members.size() < 2) continue;
    std::vector<std::pair<Trajectory, Trajectory>> pairs;
    for (ClientId c : members)
      for (const auto& j : jobs)
        if (j.info.id == c && j.groundtruth) pairs.emplace_back(*j.groundtruth, trajs.at(c));
    if (pairs.size() != members.size()) continue;
    try {
      const auto r = compute_ate_joint(pairs, Alignment::kSE3);
      std::printf("fused group %d (%zu clients) combined ATE rmse %.4f m (n=%d)\n", g.value(), members.size(),
                  r.stats.rmse, r.stats.n);
      summary["ate_rmse_group_" + std::to_string(g.value())] = r.stats.rmse;
    } catch (const InputError& e) {
      std::printf("group %d ATE n/a: %s\n", g.value(), e.what());
    }
  }
  std::ofstream(out + "/summary.json") << summary.dump(2) << "\n";
  std::printf("outputs in %s (client_K.txt, fused_G.txt, stats.json, summary.json)\n", out.c_str());
  return 0;
}

}  // namespace cslam
