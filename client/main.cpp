// cslam-client: replays a TUM-layout RGB-D dataset to cslam-server, as one client robot.
#include <algorithm>
#include <cstdio>
// Lossless (--rate N | max): every frame waits for a credit. Live (--live): frames come on the
// dataset's own clock like a camera's; without a credit only the newest is kept.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include "client/frame_sender.h"
#include "client/pose_log.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/progress.h"
#include "core/stopwatch.h"
#include "proto/keys/curve_keys.h"
#include "geometry/camera_io.h"
#include "io/dataset_camera.h"
#include "io/tum_dataset.h"
#include "io/dataset_frame.h"

namespace {

// The stream's frames per second for the byte budget: the dataset's own when live, --rate
// otherwise (30 with --rate max, the cameras' usual rate).
double nominal_rate(bool live, double rate, const std::vector<cslam::RgbdPair>& pairs) {
  if (!live) return rate > 0 ? rate : 30.0;
  const double span = pairs.size() > 1 ? pairs.back().rgb_time - pairs.front().rgb_time : 0.0;
  return span > 0 ? std::min(1000.0, double(pairs.size() - 1) / span) : 30.0;
}

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-client", "Replays a TUM-layout RGB-D dataset to cslam-server as one client robot.");
  cli.option("server", "server endpoint", "tcp://127.0.0.1:5555")
      .option("id", "client id (0..65535)")
      .option("name", "client name shown by the server", "")
      .option("dataset", "TUM-layout folder (rgb.txt, depth.txt, images)")
      .option("range", "frames a:b, 1-based inclusive ('a:' = to the end)", "1:")
      .option("rate", "lossless mode: frames per second, or 'max' to send as fast as credits allow", "30")
      .flag("live", "live mode: frames on the dataset's own clock; no credit -> keep only the newest (--rate ignored)")
      .option("poses-out", "write the poses received in acks (TUM) and FILE.feedback.csv (state, latency per ack)", "")
      .option("start-at",
              "wall-clock time (Unix seconds) to start streaming at, after loading (benchmarks start robots together)",
              "0")
      .option("summary-out", "write a JSON summary (frames sent/dropped/skipped, pose latency p50/p99)", "")
      .option(
          "camera",
          "tum1 | tum2 | tum2-corrected | tum3 | synthetic | camera file (default: DIR/camera.yaml, else its "
          "calibration.txt (fx fy cx cy), else the TUM camera the folder name says (freiburg1..3, fr1..3), else tum1)",
          "")
      .option("rgb-codec",
              "raw | jpeg | png | h264-intra (each image a standalone H.264 picture) | auto (h264-intra in a lean or "
              "adaptive stream, else jpeg)",
              "auto")
      .option("jpeg-quality", "JPEG quality 1..100", std::to_string(cslam::CodecOptions().jpeg_quality))
      .option("h264-intra-crf", "with --rgb-codec h264-intra: the pictures' constant rate factor 0..51",
              std::to_string(cslam::CodecOptions().h264_intra_crf))
      .option("depth-codec", "raw | png | rvl | zstd (all lossless)", "zstd")
      .option("depth-every",
              "lean stream: depth (with --rgb-codec colour) on every K-th frame and when the server asks; the light "
              "frames between send colour as an H.264 stream and depth subsampled (--light-depth); 1: every frame full",
              "1")
      .option("light-depth",
              "lean stream: light frames carry depth at every S-th pixel of every S-th row (lossless); 0: no depth",
              "4")
      .option("colour-crf", "lean stream: H.264 constant rate factor of the colour stream (lower: better, larger)",
              std::to_string(cslam::client::SenderConfig().colour_stream.crf))
      .option("colour-preset", "lean stream: x264 preset of the colour stream (ultrafast .. placebo)",
              cslam::client::SenderConfig().colour_stream.preset)
      .flag("adapt",
            "adapt the stream to the link: when acks come back later than the link's base latency (a queue builds) or "
            "a live frame is dropped, send full frames less often (lean stream, depth every --depth-every .. 30 "
            "frames); back up when the link is calm")
      .option(
          "byte-budget",
          "MB/s this robot's stream may take (its share of the link): full frames' colour becomes the finest JPEG "
          "(q95, q90, q85) the budget has room for, else --rgb-codec's (never coarser; in a lean stream only on the "
          "full frames the server's acks expect to become keyframes; counted at --rate, the "
          "dataset's rate with --live, 30 with --rate max); 0: off. Leave the link headroom: robots that fill a "
          "shared link queue behind each other",
          "0")
      .flag("new-session",
            "start a new recording session (a new map, fused by the server) even if the server knows this id")
      .flag("preload",
            "load and encode every frame before sending (measures the network path only; a lean stream preloads "
            "decoded frames and encodes each as it leaves)")
      .option("reply-timeout", "seconds without any reply before reconnecting", "10")
      .option("resend-buffer",
              "MB of sent frames kept for a server that resumes behind (restarted from a snapshot); 0: none", "128")
      .option("progress-interval", "seconds between progress lines", "2")
      .option("log-level", "trace, debug, info, warn, error, off", "info")
      .option("server-key", "the server's CURVE public key file (cslam-keygen); needs --curve-secret", "")
      .option("curve-secret", "this robot's CURVE key file (its .pub must be in the server's --clients-allowed)", "");
  if (!cli.parse(argc, argv)) return 0;
  cslam::set_log_level(cli.get("log-level"));
  auto log = cslam::logger("client");

  const int id = cli.get_int("id");
  if (id < 0 || id > 65535) throw cslam::ConfigError("cslam-client: --id must be in 0..65535");
  const std::string dir = cli.get("dataset");
  const cslam::TumDataset dataset = cslam::open_tum_dataset(dir);
  const auto [first, last] = cslam::parse_range(cli.get("range"), int(dataset.pairs.size()));
  const std::vector<cslam::RgbdPair> pairs = cslam::select_range(dataset.pairs, first, last);
  const std::string rate_text = cli.get("rate");
  const double rate = rate_text == "max" ? 0.0 : cli.get_double("rate");
  if (rate_text != "max" && rate <= 0) throw cslam::ConfigError("cslam-client: --rate must be positive or 'max'");

  cslam::client::SenderConfig config;
  config.server = cli.get("server");
  config.info.id = cslam::ClientId(id);
  config.info.name = cli.has("name") ? cli.get("name") : "client" + std::to_string(id);
  config.info.camera = cslam::dataset_camera(dir, cli.get("camera")).camera;
  config.codecs.jpeg_quality = cli.get_int("jpeg-quality");
  config.codecs.h264_intra_crf = cli.get_int("h264-intra-crf");
  config.codecs.depth = cslam::parse_depth_codec(cli.get("depth-codec"));
  config.depth_every = cli.get_int("depth-every");
  config.colour_stream.crf = cli.get_int("colour-crf");
  config.colour_stream.preset = cli.get("colour-preset");
  config.light_depth_subsample = cli.get_int("light-depth");
  config.adapt.enabled = cli.flag_set("adapt");
  config.codecs.rgb = cslam::parse_rgb_codec(cli.get("rgb-codec"), config.colour_stream_on());
  config.budget.bytes_per_s = cli.get_double("byte-budget") * 1e6;
  config.budget.frame_rate = nominal_rate(cli.flag_set("live"), rate, pairs);
  config.reply_timeout_s = cli.get_double("reply-timeout");
  {
    const double mb = cli.get_double("resend-buffer");
    if (!(mb >= 0) || mb > 65536) throw cslam::ConfigError("--resend-buffer must be 0..65536 MB");
    config.resend_buffer_bytes = std::size_t(mb * 1024 * 1024);
  }
  if (cli.get("server-key").empty() != cli.get("curve-secret").empty())
    throw cslam::ConfigError("cslam-client: --server-key and --curve-secret go together");
  if (!cli.get("server-key").empty()) {
    config.server_public_key = cslam::auth::read_public_file(cli.get("server-key")).public_key;
    const cslam::auth::CurveKeyPair own = cslam::auth::read_secret_file(cli.get("curve-secret"));
    config.public_key = own.public_key;
    config.secret_key = own.secret_key;
  }
  config.new_session = cli.flag_set("new-session");
  const double progress_interval = cli.get_double("progress-interval");

  cslam::client::FrameSender sender(config);
  std::vector<cslam::wire::RgbdFrame> preloaded;
  std::vector<cslam::RgbdFrame> preloaded_raw;  // a lean stream encodes each frame when it leaves
  if (cli.flag_set("preload")) {
    for (const auto& pair : pairs) {
      if (config.colour_stream_on())
        preloaded_raw.push_back(cslam::load_dataset_frame(pair, config.info.id));
      else
        preloaded.push_back(sender.encode(cslam::load_dataset_frame(pair, config.info.id)));
    }
    log->info("client {}: preloaded {} {} frames", id, pairs.size(), config.colour_stream_on() ? "decoded" : "encoded");
  }
  sender.connect();
  log->info("client {}: sending frames {}..{} ({} frames) of {} at {}, codecs {}/{}", id, first, last, pairs.size(),
            dir, rate_text, cslam::to_string(config.codecs.rgb), cslam::to_string(config.codecs.depth));

  const bool live = cli.flag_set("live");
  const double start_at = cli.get_double("start-at");
  if (start_at > 0) {
    const auto when = std::chrono::system_clock::time_point(
        std::chrono::duration_cast<std::chrono::system_clock::duration>(std::chrono::duration<double>(start_at)));
    while (std::chrono::system_clock::now() < when)  // stay connected while waiting
      sender.keep_alive(std::min(1.0, std::chrono::duration<double>(when - std::chrono::system_clock::now()).count()));
  }
  cslam::client::PoseLog pose_log;
  sender.set_pose_callback([&pose_log](const cslam::wire::PoseFeedback& f) { pose_log.add(f); });
  const auto start = std::chrono::steady_clock::now();
  cslam::ProgressOptions progress_options;
  progress_options.interval_s = progress_interval;
  cslam::Progress progress("client " + std::to_string(id) + ": sent", pairs.size(), "frames", progress_options);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (live) {
      // The camera's clock: frame i is captured at its dataset time after the first frame's.
      const auto due = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                   std::chrono::duration<double>(pairs[i].rgb_time - pairs[0].rgb_time));
      if (config.colour_stream_on()) {  // the lean stream encodes a frame when it leaves
        const cslam::RgbdFrame frame =
            preloaded_raw.empty() ? cslam::load_dataset_frame(pairs[i], config.info.id) : preloaded_raw[i];
        sender.service_until(due);
        sender.offer_frame(frame, due);
      } else {
        cslam::wire::RgbdFrame frame =
            preloaded.empty() ? sender.encode(cslam::load_dataset_frame(pairs[i], config.info.id)) : preloaded[i];
        sender.service_until(due);
        sender.offer_encoded(std::move(frame), due);
      }
    } else {
      if (rate > 0) std::this_thread::sleep_until(start + std::chrono::duration<double>(double(i) / rate));
      if (!preloaded_raw.empty()) {
        sender.send_frame(preloaded_raw[i]);
      } else if (preloaded.empty()) {
        sender.send_frame(cslam::load_dataset_frame(pairs[i], config.info.id));
      } else {
        sender.send_encoded(preloaded[i]);
      }
    }
    const auto& s = sender.stats();
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    char extra[256];
    int used = std::snprintf(extra, sizeof extra, "%.2f MB/s, %.1f KB/frame",
                             double(s.bytes_sent) / std::max(elapsed, 1e-9) / 1e6,
                             double(s.bytes_sent) / double(s.frames_sent) / 1e3);
    if (config.colour_stream_on() && used > 0)
      used += std::snprintf(extra + used, sizeof extra - std::size_t(used), ", %llu light, %llu depth requests",
                            (unsigned long long)s.frames_light, (unsigned long long)s.depth_requests);
    if (config.budget.bytes_per_s > 0 && used > 0 && std::size_t(used) < sizeof extra)
      used += std::snprintf(extra + used, sizeof extra - std::size_t(used), ", %llu finer (budget)",
                            (unsigned long long)s.frames_finer);
    if (config.adapt.enabled && used > 0 && std::size_t(used) < sizeof extra)
      std::snprintf(extra + used, sizeof extra - std::size_t(used), ", depth every %d (%llu down, %llu up)",
                    s.depth_every, (unsigned long long)s.rate_steps_down, (unsigned long long)s.rate_steps_up);
    progress.update(s.frames_sent, extra);
  }
  progress.finish();
  const bool all_acked = sender.goodbye();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto& s = sender.stats();
  std::uint64_t errors = 0;
  for (const auto& [code, n] : s.errors) errors += n;
  const nlohmann::json summary = pose_log.summary(s, wall, pairs.size());
  log->info(
      "client {}: done, {} frames in {:.2f} s ({:.1f} fps), {:.1f} KB/frame, {:.2f} MB/s, {} acks, {} errors, {} "
      "reconnects",
      id, s.frames_sent, wall, double(s.frames_sent) / wall,
      s.frames_sent ? double(s.bytes_sent) / double(s.frames_sent) / 1e3 : 0.0, double(s.bytes_sent) / wall / 1e6,
      s.acks, errors, s.reconnects);
  log->info("client {}: pose feedback {}, {} dropped without credit, latency p50 {:.1f} ms p99 {:.1f} ms", id,
            summary["states"].dump(), s.frames_dropped_live, summary["latency_ms"]["p50"].get<double>(),
            summary["latency_ms"]["p99"].get<double>());
  if (config.colour_stream_on())
    log->info(
        "client {}: lean stream: {} of {} frames light ({:.1f} KB each), {} full ({:.1f} KB each), {} depth "
        "requests, {} key packets, {} stream gaps",
        id, s.frames_light, s.frames_sent, s.frames_light ? double(s.bytes_light) / double(s.frames_light) / 1e3 : 0.0,
        s.frames_sent - s.frames_light,
        s.frames_sent > s.frames_light
            ? double(s.bytes_sent - s.bytes_light) / double(s.frames_sent - s.frames_light) / 1e3
            : 0.0,
        s.depth_requests, s.colour_key_packets, s.stream_gaps);
  if (config.budget.bytes_per_s > 0)
    log->info("client {}: byte budget {:.2f} MB/s at {:.1f} Hz: {} full frames' colour finer than {}", id,
              config.budget.bytes_per_s / 1e6, config.budget.frame_rate, s.frames_finer,
              cslam::to_string(config.codecs.rgb));
  if (config.adapt.enabled)
    log->info("client {}: adaptive rate: {} steps down, {} up, depth every {} at the end", id, s.rate_steps_down,
              s.rate_steps_up, s.depth_every);
  if (!cli.get("poses-out").empty()) pose_log.write(cli.get("poses-out"));
  if (!cli.get("summary-out").empty()) std::ofstream(cli.get("summary-out")) << summary.dump(2) << "\n";
  // Session-level errors the sender recovered from (e.g. a frame that reached a restarted server
  // before the resumed hello; it is sent again) do not fail the run; a frame the server refused,
  // never acknowledged, or lost beyond the re-send buffer does (live mode drops frames by design).
  if (s.frames_resent > 0)
    log->info("client {}: {} frame(s) sent again after the server resumed behind", id, s.frames_resent);
  return all_acked && s.frames_refused == 0 && (live || s.frames_lost == 0) ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) { return cslam::run_main("cslam-client", argc, argv, run); }
