// cslam-bench-snapshot: snapshot costs on a real map. Maps a TUM sequence offline (one client,
// local mapping inline), then repeats: the copy under each map's shared lock (the longest time a
// tracking thread can wait for it), encoding, the crash-safe write, reading and decoding, and the
// restore into a new client (BoW recomputed). Prints median and min-max of each, and the size.
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <optional>
#include <fstream>
#include <shared_mutex>
#include <thread>
#include <condition_variable>

#include <nlohmann/json.hpp>

#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "proto/snapshot_adapter.h"
#include "proto/snapshot_file.h"
#include "slam/client_slam_state.h"
#include "slam/feed_dataset.h"
#include "system/system_state.h"

using namespace cslam;

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(q * double(v.size())))];
}

// Tracking stall: per-frame ClientSlam::process() time (threaded SLAM, as the server runs it;
// images preloaded) over the sequence, and the tracker's wait for the map's exclusive lock at
// each keyframe insertion (MapWriteLock with record_wait: from asking for the lock to holding
// it), without snapshots, with a background snapshot copy (export_state, yielding to writers)
// every `period_s`, and with a copy of every map that does not yield (each map copied under
// one shared lock as before the yielding copy). Prints median, p99 and max of each.
int stall_test(const ClientInfo& info, const std::shared_ptr<const Vocabulary>& vocabulary,
               const std::vector<RgbdPair>& pairs, double period_s, bool with_blocking) {
  std::vector<RgbdFrame> frames;
  frames.reserve(pairs.size());
  for (const auto& p : pairs) frames.push_back(load_dataset_frame(p, info.id));
  SlamConfig config;  // threaded
  enum Mode { kNone, kYielding, kBlocking };
  std::vector<Mode> modes = {kNone, kYielding};
  if (with_blocking) modes.push_back(kBlocking);
  for (const Mode mode : modes) {
    const bool with_snapshots = mode != kNone;
    ClientSlam slam(info, config, vocabulary);
    std::uint64_t yields = 0, forced = 0;
    std::mutex m;
    std::condition_variable cv;
    bool stop = false;
    std::vector<double> copy_ms;
    using Span = std::pair<std::chrono::steady_clock::time_point, std::chrono::steady_clock::time_point>;
    std::vector<Span> copy_spans, holds;  // whole export_state calls; the copy's shared-lock holds
    std::thread snapshotter;
    if (with_snapshots)
      snapshotter = std::thread([&] {
        std::unique_lock<std::mutex> lock(m);
        while (!cv.wait_for(lock, std::chrono::duration<double>(period_s), [&] { return stop; })) {
          lock.unlock();
          Stopwatch sw;
          const auto copy_start = std::chrono::steady_clock::now();
          std::uint64_t y = 0, f = 0;
          if (mode == kYielding) {
            const ClientSlamState state = slam.export_state();
            for (const auto& ms : state.maps) {
              y += std::uint64_t(ms.export_yields);
              f += ms.export_forced ? 1 : 0;
              holds.insert(holds.end(), ms.export_holds.begin(), ms.export_holds.end());
            }
          } else {
            for (const auto& map : slam.maps()) {
              std::shared_lock<std::shared_mutex> map_lock(map->mutex);
              const auto start = std::chrono::steady_clock::now();
              MapState ms = export_map_state(*map);
              map_lock.unlock();
              holds.emplace_back(start, std::chrono::steady_clock::now());
            }
          }
          const double ms = sw.ms();
          lock.lock();
          copy_ms.push_back(ms);
          copy_spans.emplace_back(copy_start, std::chrono::steady_clock::now());
          yields += y;
          forced += f;
        }
      });
    std::vector<double> frame_ms;
    for (const auto& f : frames) {
      Stopwatch sw;
      slam.process(f);
      frame_ms.push_back(sw.ms());
    }
    {
      std::lock_guard<std::mutex> lock(m);
      stop = true;
    }
    cv.notify_all();
    if (snapshotter.joinable()) snapshotter.join();
    slam.finish();
    // All waits; those overlapping a snapshot copy and the others; and, per wait, how long a
    // snapshot copy held the shared lock during it (the part of the wait the snapshot caused).
    std::vector<double> wait_ms, overlapping_ms, apart_ms, held_during_ms;
    for (const auto& map : slam.maps()) {
      std::shared_lock<std::shared_mutex> map_lock(map->mutex);
      for (const auto& w : map->recorded_write_waits()) {
        wait_ms.push_back(w.ms);
        const auto end = w.asked + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                       std::chrono::duration<double, std::milli>(w.ms));
        const bool overlaps = std::any_of(copy_spans.begin(), copy_spans.end(),
                                          [&](const auto& c) { return c.first < end && w.asked < c.second; });
        (overlaps ? overlapping_ms : apart_ms).push_back(w.ms);
        double held = 0;
        for (const auto& h : holds)
          if (h.first < end && w.asked < h.second)
            held +=
                std::chrono::duration<double, std::milli>(std::min(end, h.second) - std::max(w.asked, h.first)).count();
        held_during_ms.push_back(held);
      }
    }
    const Summary s = summarize(frame_ms);
    const char* name = mode == kNone       ? "without snapshots"
                       : mode == kYielding ? "with snapshots (yielding)"
                                           : "with snapshots (not yielding)";
    std::printf("%-30s frames %zu: process() median %.2f ms, p99 %.2f ms, max %.2f ms\n", name, frame_ms.size(),
                s.median, percentile(frame_ms, 0.99), s.max);
    const Summary w = summarize(wait_ms.empty() ? std::vector<double>{0.0} : wait_ms);
    const auto over5 = std::count_if(wait_ms.begin(), wait_ms.end(), [](double v) { return v > 5.0; });
    std::printf(
        "%-30s tracker exclusive-lock wait (%zu keyframe insertions): median %.3f ms, p99 %.3f ms, max %.3f ms, %ld "
        "over 5 ms\n",
        "", wait_ms.size(), w.median, percentile(wait_ms, 0.99), w.max, long(over5));
    if (with_snapshots) {
      auto max_of = [](const std::vector<double>& v) {
        return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
      };
      std::printf("%-30s of these, %zu overlapped a snapshot copy (max %.3f ms), %zu did not (max %.3f ms)\n", "",
                  overlapping_ms.size(), max_of(overlapping_ms), apart_ms.size(), max_of(apart_ms));
      std::printf("%-30s snapshot shared-lock hold within a wait: max %.3f ms (%zu holds, longest %.3f ms)\n", "",
                  max_of(held_during_ms), holds.size(), [&] {
                    double m = 0;
                    for (const auto& h : holds)
                      m = std::max(m, std::chrono::duration<double, std::milli>(h.second - h.first).count());
                    return m;
                  }());
      const Summary c = summarize(copy_ms.empty() ? std::vector<double>{0.0} : copy_ms);
      std::printf("%-30s %zu snapshot copies every %.2f s, copy median %.1f ms, max %.1f ms", "", copy_ms.size(),
                  period_s, c.median, c.max);
      if (mode == kYielding)
        std::printf(", %llu yields, %llu forced copies", (unsigned long long)yields, (unsigned long long)forced);
      std::printf("\n");
    }
  }
  return 0;
}

int run(int argc, char** argv) {
  CliArgs args("cslam-bench-snapshot", "Measures snapshot copy, encode, write, load and restore times on a real map.");
  args.option("dataset", "TUM-layout folder", "")
      .option("snapshot", "take the map from this snapshot (client of the file) instead of mapping --dataset", "")
      .option("camera", "camera preset or file", "tum1")
      .option("range", "frames a:b (1-based, inclusive)", "1:")
      .option("repeats", "measurements of each step", "10")
      .option("state-dir", "folder for the snapshot files", "/tmp/cslam-bench-snapshot")
      .option("json", "also write the figures to this JSON file", "")
      .option("stall-test",
              "instead: per-frame tracking time of threaded SLAM over --dataset without and with a "
              "snapshot copy every this many seconds",
              "0")
      .option("stall-blocking", "with --stall-test: also a run whose copies do not yield to writers (yes/no)", "no")
      .option("log-level", "trace, debug, info, warn, error, off", "warn");
  if (!args.parse(argc, argv)) return 0;
  set_log_level(args.get("log-level"));
  ClientInfo info;
  info.id = 1;
  info.name = "bench";
  info.camera = load_camera(args.get("camera"));
  SlamConfig config;
  config.threaded = false;
  auto vocabulary = std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path()));
  std::vector<RgbdPair> pairs;
  std::optional<SystemState> given;
  if (!args.get("snapshot").empty()) {
    given = snapshot::read_file(args.get("snapshot"));
    if (given->clients.empty()) throw InputError(args.get("snapshot"), "no client in the snapshot");
    info = given->clients[0].info;
  } else {
    const TumDataset ds = open_tum_dataset(args.get("dataset"));
    const auto [a, b] = parse_range(args.get("range"), int(ds.pairs.size()));
    pairs = select_range(ds.pairs, a, b);
  }
  if (args.get_double("stall-test") > 0) {
    if (pairs.empty()) throw ConfigError("--stall-test needs --dataset");
    return stall_test(info, vocabulary, pairs, args.get_double("stall-test"), args.get("stall-blocking") == "yes");
  }
  ClientSlam slam(info, config, vocabulary);
  Stopwatch mapping;
  if (given) {
    slam.restore_state(given->clients[0], args.get("snapshot"));
    std::printf("map restored from %s in %.1f s\n", args.get("snapshot").c_str(), mapping.ms() / 1000.0);
  } else {
    feed_pairs(slam, info.id, pairs);
    std::printf("mapped %zu frames in %.1f s\n", pairs.size(), mapping.ms() / 1000.0);
  }

  const int repeats = std::max(1, args.get_int("repeats"));
  const std::string dir = args.get("state-dir");
  std::vector<double> hold_ms, hold_cpu_ms, export_ms, encode_ms, write_ms, decode_ms, restore_ms;
  std::size_t bytes = 0, keyframes = 0, points = 0, poses = 0;
  for (int i = 0; i < repeats; ++i) {
    // The lock hold alone, as the snapshotter takes it for each map.
    double hold = 0, hold_cpu = 0;
    for (const auto& map : slam.maps()) {
      Stopwatch sw;
      const double cpu0 = thread_cpu_ms();
      std::shared_lock<std::shared_mutex> lock(map->mutex);
      MapState ms = export_map_state(*map);
      hold = std::max(hold, sw.ms());
      hold_cpu = std::max(hold_cpu, thread_cpu_ms() - cpu0);
      lock.unlock();
      tidy_map_state(ms);
      keyframes = ms.keyframes.size();
      points = ms.points.size();
    }
    hold_ms.push_back(hold);
    hold_cpu_ms.push_back(hold_cpu);
    Stopwatch sw;
    SystemState state;
    state.clients.push_back(slam.export_state());
    export_ms.push_back(sw.ms());
    poses = state.clients[0].records.size();
    sw.reset();
    const std::string data = snapshot::encode(state);
    encode_ms.push_back(sw.ms());
    bytes = data.size();
    sw.reset();
    snapshot::write_atomic(dir, data);
    write_ms.push_back(sw.ms());
    sw.reset();
    const SystemState loaded = snapshot::read_file(snapshot::current_path(dir));
    decode_ms.push_back(sw.ms());
    sw.reset();
    ClientSlam restored(info, config, vocabulary);
    restored.restore_state(loaded.clients[0], snapshot::current_path(dir));
    restore_ms.push_back(sw.ms());
  }
  nlohmann::json j = {{"frames", poses}, {"keyframes", keyframes}, {"points", points},
                      {"poses", poses},  {"bytes", bytes},         {"repeats", repeats}};
  auto line = [&](const char* name, const std::vector<double>& v) {
    const Summary s = summarize(v);
    std::printf("%-34s median %8.1f ms   min %8.1f   max %8.1f\n", name, s.median, s.min, s.max);
    j[name] = {{"median_ms", s.median}, {"min_ms", s.min}, {"max_ms", s.max}};
  };
  std::printf("map: %zu keyframes, %zu points, %zu frame poses; snapshot %.2f MB\n", keyframes, points, poses,
              double(bytes) / 1e6);
  line("lock_hold (tracking stall bound)", hold_ms);
  line("lock_hold thread CPU time", hold_cpu_ms);
  line("copy (export_state)", export_ms);
  line("encode", encode_ms);
  line("write (fsync + rename)", write_ms);
  std::vector<double> total_write;
  for (std::size_t i = 0; i < export_ms.size(); ++i) total_write.push_back(export_ms[i] + encode_ms[i] + write_ms[i]);
  line("write total (copy+encode+write)", total_write);
  line("read + decode", decode_ms);
  line("restore (incl. BoW)", restore_ms);
  std::vector<double> total_load;
  for (std::size_t i = 0; i < decode_ms.size(); ++i) total_load.push_back(decode_ms[i] + restore_ms[i]);
  line("load total (read+decode+restore)", total_load);
  if (!args.get("json").empty()) std::ofstream(args.get("json")) << j.dump(2) << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-snapshot", argc, argv, run); }
