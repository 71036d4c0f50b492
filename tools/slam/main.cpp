// cslam-slam: runs one client's SLAM on a TUM-layout dataset (real or synthetic) as fast as
// possible and writes the frame trajectory, keyframes and timing statistics.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include <sys/resource.h>

#include <nlohmann/json.hpp>

#include "core/bounded_queue.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "frame/frame_check.h"
#include "core/stats.h"
#include "eval/stats_json.h"
#include "slam/features/opencv_threads.h"
#include "fusion/fusion_manager.h"
#include "system/loop_stats_json.h"
#include "geometry/camera_io.h"
#include "io/dataset_camera.h"
#include "io/tum_dataset.h"
#include "lean_sim.h"
#include "multi.h"
#include "slam/client_slam.h"
#include "io/dataset_frame.h"

using namespace cslam;

namespace {

double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;
}

int run(int argc, char** argv) {
  CliArgs args("cslam-slam", "Runs one client's RGB-D SLAM offline on a TUM-layout dataset.");
  args.option("dataset", "dataset folder (rgb.txt, depth.txt, ...)", "")
      .multi_option("datasets",
                    "multi-client mode: one dataset folder per client (e.g. cslam-synth robot_1 robot_2 ...)")
      .option("clients", "multi-client mode: split --dataset into K clients with the paper's ranges", "1")
      .option("overlap", "overlap rate eta of the split, e.g. 0.05 or 5%", "5%")
      .option("out-dir", "multi-client mode: output folder (client_K.txt, fused_G.txt, stats.json)", "")
      .option(
          "camera",
          "camera preset (tum1, tum2, tum2-corrected, tum3, synthetic) or file; default: DATASET/camera.yaml, else its "
          "calibration.txt (fx fy cx cy), else the TUM camera the folder name says (freiburg1..3, fr1..3), else tum1",
          "")
      .option("readout",
              "rolling-shutter readout time of the colour camera in seconds, first to last row (0: global shutter); "
              "default: the camera's (TUM presets 0.020, camera files' readout_time key, else 0)",
              "")
      .option("range", "frames a:b (1-based, inclusive, of the associated RGB-D pairs)", "")
      .option(
          "association",
          "colour-depth pairing: nearest (every colour frame, a depth image may serve two) | unique (TUM associate.py)",
          "nearest")
      .option("vocab", "vocabulary file", "")
      .option("out", "frame trajectory output (TUM format), single-client mode", "")
      .option("keyframes", "keyframe trajectory output (TUM format)", "")
      .option("stats", "timing statistics output (JSON)", "")
      .option("client", "client id", "1")
      .flag(
          "sync",
          "step every stage on one thread (local mapping, loop closing, fusion): the same input gives the same output")
      .flag("no-local-ba", "disable local bundle adjustment (ablation)")
      .flag("no-triangulation", "local mapping creates no points from keyframe pairs (ablation)")
      .flag("no-fusion",
            "disable map fusion (ablation): across clients, and of one client's maps after a long tracking loss")
      .flag("no-group-ba", "multi-client mode: no global BA over a fused group after fusion (ablation)")
      .flag("no-reencounter",
            "multi-client mode: maps of one fused group are not matched against each other again (ablation)")
      .flag("no-loop", "disable loop closing (ablation)")
      .flag("no-final-ba", "no global BA over each map at the end of the run (ablation)")
      .option("flow",
              "flow frames (KLT tracking between full frames, no ORB extraction): off, under-load (a live server "
              "falling behind; offline: never), always",
              "under-load")
      .flag("depth-time",
            "read keypoint depth where the predicted motion carried it over the depth image's time offset")
      .option("tracking-wait",
              "threaded: after a new keyframe, tracking waits until local mapping has fully processed it (keyframe: "
              "the same output as --sync, run after run), created and fused its points (new-points: the server's "
              "choice, lower latency) or not at all (none)",
              "keyframe")
      .option("depth-every",
              "full depth with every K-th frame only, as a lean stream sends it (the light frames between: "
              "--light-depth); 1: every frame",
              "1")
      .option("light-depth",
              "with --depth-every: the light frames carry depth at every S-th pixel of every S-th row (0: none)", "4")
      .option("depth-request-delay",
              "with --depth-every: frames between the frame whose tracking asked for full depth and the full frame "
              "that answers, minus one (0: the next frame, as cslam-client at 30 Hz measures it: "
              "depth_request_lag_frames 1.0-1.07; more: acks in flight)",
              "0")
      .flag("coded-colour",
            "colour through the client's codecs and back: --rgb-codec on full frames, the lean stream's H.264 on "
            "light frames (--depth-every)")
      .option("rgb-codec",
              "with --coded-colour: the full frames' colour codec, raw | jpeg | png | h264-intra | auto (cslam-client "
              "--rgb-codec: h264-intra with --depth-every > 1, else jpeg)",
              "auto")
      .option("jpeg-quality", "with --coded-colour: the full frames' JPEG quality (cslam-client --jpeg-quality)",
              std::to_string(CodecOptions().jpeg_quality))
      .option("h264-intra-crf", "with --coded-colour and --rgb-codec h264-intra: the pictures' CRF (cslam-client)",
              std::to_string(CodecOptions().h264_intra_crf))
      .option("colour-crf",
              "with --coded-colour and --depth-every: the light frames' H.264 CRF (cslam-client --colour-crf)",
              std::to_string(video::light_colour_stream().crf))
      .option("byte-budget",
              "with --coded-colour: the robot's byte budget in MB/s, spent on the full frames' colour as cslam-client "
              "--byte-budget does; 0: none",
              "0")
      .option("stream-rate", "with --byte-budget: the robot's frames per second (cslam-client --rate)", "30")
      .flag("quiet", "no progress output")
      .option("log-level", "trace, debug, info, warn, error, off", "info");
  if (!args.parse(argc, argv)) return 0;
  set_log_level(args.get("log-level"));
  if (!args.get_multi("datasets").empty() || args.get_int("clients") > 1) {
    if (!args.has("out-dir")) throw ConfigError("multi-client mode needs --out-dir");
    return run_multi_client(args);
  }
  if (!args.has("dataset") || !args.has("out")) throw ConfigError("single-client mode needs --dataset and --out");
  const std::string dir = args.get("dataset");
  const TumDataset ds = open_tum_dataset(dir, 0.02, parse_association(args.get("association")));
  ClientInfo info;
  info.id = ClientId(args.get_int("client"));
  info.name = std::filesystem::path(dir).filename().string();
  info.camera = camera_for(args, dir);
  std::vector<RgbdPair> pairs = ds.pairs;
  if (args.has("range")) {
    const auto [a, b] = parse_range(args.get("range"), int(pairs.size()));
    pairs = select_range(pairs, a, b);
  }
  const std::string vocab_path = args.has("vocab") ? args.get("vocab") : default_vocabulary_path();
  Stopwatch load_sw;
  auto vocabulary = std::make_shared<const Vocabulary>(Vocabulary::load(vocab_path));
  const double vocab_ms = load_sw.ms();

  SlamConfig config;
  config.threaded = !args.flag_set("sync");
  config.loop.enabled = !args.flag_set("no-loop");
  if (args.flag_set("no-final-ba")) config.final_global_ba_iterations = 0;
  config.rgbd.depth_time_compensation = args.flag_set("depth-time");
  config.tracker.flow.mode = parse_flow_mode(args.get("flow"));
  config.mapper.local_ba = !args.flag_set("no-local-ba");
  config.mapper.tracking_wait = parse_tracking_wait(args.get("tracking-wait"));
  config.mapper.triangulation.enabled = !args.flag_set("no-triangulation");
  // A long tracking loss starts a new map; map fusion joins it to the earlier ones when the
  // camera sees their places again (as on the server), so the trajectory covers both.
  FusionConfig fusion_config;
  fusion_config.threaded = config.threaded;
  fusion_config.enabled = !args.flag_set("no-fusion");
  FusionManager fusion(fusion_config, vocabulary);
  const MapFrameOf frame_of = [&fusion](const Map* m) { return fusion.group_of(m); };
  ClientSlam slam(
      info, config, vocabulary,
      [&fusion](ClientId c, const std::shared_ptr<Map>& m, const KeyFramePtr& kf) { fusion.notify(c, m, kf); });

  LeanStreamSim lean(lean_stream_config(args));  // checks its options before any thread starts

  // Images are decoded on a second thread, ahead of tracking.
  BoundedQueue<std::pair<RgbdPair, RgbdImages>> loaded(4);
  std::thread loader([&] {
    for (const auto& p : pairs) {
      RgbdImages im;
      try {
        im = load_rgbd(p);
      } catch (const InputError& e) {
        logger("slam")->error("{}", e.what());
      }
      if (!loaded.push({p, std::move(im)})) break;
    }
    loaded.close();
  });
  // A frame that throws below stops the loader and joins it before the error leaves.
  struct StopLoader {
    BoundedQueue<std::pair<RgbdPair, RgbdImages>>& queue;
    std::thread& thread;
    ~StopLoader() {
      queue.close();
      if (thread.joinable()) thread.join();
    }
  } stop_loader{loaded, loader};

  Stopwatch wall;
  int n = 0, lost = 0, rejected = 0;
  std::vector<double> inliers, features;
  const bool quiet = args.flag_set("quiet");
  while (auto item = loaded.pop()) {
    RgbdFrame frame = dataset_frame(item->first, std::move(item->second), info.id, std::uint64_t(n));
    if (const std::string why = frame_problem(frame, info.camera); !why.empty())  // the dataset is this tool's boundary
      throw InputError(args.get("dataset"),
                       "frame " + std::to_string(n) + ": " + why + " (does --camera match the dataset?)");
    lean.apply(frame, n);
    const ProcessResult r = slam.process(frame);
    lean.keyframe_hint(n, r.keyframe_due_in);
    if (r.wants_depth) lean.requested(n);
    inliers.push_back(r.inliers);
    features.push_back(r.features);
    if (std::getenv("CSLAM_TRACE"))
      std::fprintf(stderr, "frame %d feats %d inliers %d kf %d flow %d t %.6f\n", n, r.features, r.inliers,
                   int(r.new_keyframe), int(r.flow), frame.timestamp);
    ++n;
    if (r.fate == FrameFate::kLost) ++lost;
    if (r.fate == FrameFate::kRejected) {
      ++rejected;
      logger("slam")->warn("frame {} rejected: {}", n, r.reject_reason);
    }
    if (!quiet && (n % 50 == 0 || n == int(pairs.size()))) {
      const auto s = slam.snapshot();
      std::fprintf(stderr, "\r[cslam-slam] %d/%zu frames  %s  kf=%d mp=%d lost=%d  %.1f fps   ", n, pairs.size(),
                   to_string(r.fate), s.keyframes, s.map_points, lost, n / (wall.ms() / 1000.0));
    }
  }
  loader.join();
  slam.finish();
  fusion.finish();
  // Maps joined by fusion were refined together by the group BA after it (as on the server).
  const auto all_maps = slam.maps();
  auto fused = [&](const Map& m) {
    const GroupId g = fusion.group_of(&m);
    return g.valid() && std::count_if(all_maps.begin(), all_maps.end(),
                                      [&](const auto& o) { return fusion.group_of(o.get()) == g; }) > 1;
  };
  slam.final_global_ba(fused);
  const double wall_s = wall.ms() / 1000.0;
  if (!quiet) std::fprintf(stderr, "\n");

  const Trajectory traj = slam.trajectory(frame_of);
  write_tum_trajectory(args.get("out"), traj, "cslam-slam " + dir);
  if (args.has("keyframes"))
    write_tum_trajectory(args.get("keyframes"), slam.keyframe_trajectory(frame_of), "cslam-slam keyframes");
  const auto snap = slam.snapshot();
  const auto fusion_events = fusion.events();
  for (const auto& e : fusion_events)
    std::printf("map fusion: a map of this client joined another at frame time %.3f, %d inliers, %d + %d keyframes\n",
                e.query_timestamp, e.inliers, e.keyframes_moved, e.keyframes_kept);
  if (snap.frames_tracked > traj.size())
    logger("slam")->warn("{} tracked frames are in maps that map fusion did not join to the main one: not in {}",
                         snap.frames_tracked - traj.size(), args.get("out"));
  const auto t = slam.timings();
  std::vector<double> tracking_total;
  for (size_t i = 0; i < t.track_ms.size(); ++i) tracking_total.push_back(t.track_ms[i] + t.extract_ms[i]);
  nlohmann::json stats = {
      {"dataset", dir},
      {"frames", n},
      {"frames_tracked", snap.frames_tracked},
      {"frames_lost", lost},
      {"frames_rejected", rejected},
      {"frames_light", lean.light_frames()},
      {"frames_finer", lean.frames_finer()},
      {"frames_flow", snap.frames_flow},
      {"trajectory_poses", traj.size()},
      {"maps", snap.maps},
      {"map_fusions", fusion_events.size()},
      {"keyframes", snap.keyframes},
      {"map_points", snap.map_points},
      {"wall_time_s", wall_s},
      {"vocabulary_load_ms", vocab_ms},
      {"peak_rss_mb", peak_rss_mb()},
      {"extract_ms", summary_json(t.extract_ms)},
      {"track_ms", summary_json(t.track_ms)},
      {"extract_plus_track_ms", summary_json(tracking_total)},
      {"local_ba_ms", summary_json(t.mapper.ba_ms)},
      {"tracked_inliers", summary_json(inliers)},
      {"features_per_frame", summary_json(features)},
      {"local_mapping_step_ms", summary_json(t.mapper.step_ms)},
      {"keyframes_processed", t.mapper.keyframes_processed},
      {"keyframes_culled", t.mapper.keyframes_culled},
      {"points_triangulated", t.mapper.points_triangulated},
      {"points_fused", t.mapper.points_fused},
      {"points_culled", t.mapper.points_culled},
  };
  add_loop_stats(stats, t.loop);
  for (const auto& l : t.loop.loops)
    std::printf("loop: keyframe at %.3f -> keyframe at %.3f, %d inliers, correction %.3f m / %.2f deg, %.1f ms\n",
                l.query_timestamp, l.candidate_timestamp, l.inliers, l.T_correction.translation().norm(),
                l.T_correction.rotation_angle() * 180.0 / M_PI, l.correction_ms);
  if (args.has("stats")) std::ofstream(args.get("stats")) << stats.dump(2) << "\n";
  if (lean.light_frames() > 0)
    std::printf(
        "light frames %d of %d (full depth every %d, requests after %d, light depth 1/%d, %d full frames finer "
        "within the byte budget)\n",
        lean.light_frames(), n, args.get_int("depth-every"), args.get_int("depth-request-delay"),
        args.get_int("light-depth"), lean.frames_finer());
  std::printf(
      "frames %d tracked %llu (flow %llu) lost %d rejected %d | keyframes %d map points %d maps %d | wall %.2f s | "
      "extract+track median %.1f ms | local BA median %.1f ms | peak RSS %.0f MB\n",
      n, (unsigned long long)snap.frames_tracked, (unsigned long long)snap.frames_flow, lost, rejected, snap.keyframes,
      snap.map_points, snap.maps, wall_s, summarize(tracking_total).median, summarize(t.mapper.ba_ms).median,
      peak_rss_mb());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  cslam::run_opencv_on_calling_threads();
  return run_main("cslam-slam", argc, argv, run);
}
