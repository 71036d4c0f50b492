// cslam-map: reads, exports and merges cslam map snapshots (see docs/persistence.md).
//   cslam-map info FILE [--json]
//   cslam-map export-ply FILE -o OUT.ply       sparse map points, each group in its own frame
//   cslam-map export-tum FILE -o DIR           client_K.txt, keyframes_K.txt, fused_G.txt
//   cslam-map merge A B -o C                   both snapshots in one, overlapping maps fused
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <thread>

#include <nlohmann/json.hpp>

#include "cloud/ply_io.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "io/trajectory_io.h"
#include "proto/snapshot_adapter.h"
#include "proto/snapshot_file.h"
#include "system/collaborative_system.h"
#include "system/system_state.h"

using namespace cslam;

namespace {

int group_of(const ClientSlamState& c, int map_index) {
  if (map_index < 0) return -1;
  const int g = c.maps[std::size_t(map_index)].group;
  return g >= 0 ? g : GroupId::of_map(c.info.id, map_index).value();
}

int cmd_info(int argc, char** argv) {
  CliArgs args("cslam-map info", "Summary of a snapshot: version, clients, maps, groups, trajectories.");
  args.positional("FILE", "snapshot file").flag("json", "print JSON");
  if (!args.parse(argc, argv, 2)) return 0;
  const std::string path = args.positionals()[0];
  snapshot::FileInfo fi;
  const SystemState s = snapshot::read_file(path, &fi);
  nlohmann::json j = {{"file", path},
                      {"format_version", fi.version},
                      {"payload_bytes", fi.payload_bytes},
                      {"crc32", fi.crc32},
                      {"producer", fi.producer},
                      {"created_unix_s", fi.created_unix_s},
                      {"clients", nlohmann::json::array()}};
  std::map<int, std::vector<int>> groups;
  for (const auto& c : s.clients) {
    int main_map = -1;
    const Trajectory t = state_trajectory(c, &main_map);
    nlohmann::json cj = {{"id", c.info.id},
                         {"name", c.info.name},
                         {"camera", c.info.camera.name},
                         {"last_seq", c.last_seq},
                         {"frames_processed", c.frames_processed},
                         {"trajectory_poses", t.size()},
                         {"main_map", main_map},
                         {"group", group_of(c, main_map)},
                         {"maps", nlohmann::json::array()}};
    for (const auto& m : c.maps) {
      std::size_t obs = 0;
      for (const auto& p : m.points) obs += p.observations.size();
      cj["maps"].push_back({{"index", m.index},
                            {"group", group_of(c, m.index)},
                            {"keyframes", m.keyframes.size()},
                            {"points", m.points.size()},
                            {"observations", obs}});
    }
    groups[group_of(c, main_map)].push_back(c.info.id);
    j["clients"].push_back(cj);
  }
  j["groups"] = nlohmann::json::array();
  for (const auto& [g, members] : groups) j["groups"].push_back({{"group", g}, {"clients", members}});
  if (args.flag_set("json")) {
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::printf("%s: cslam snapshot version %u, %.1f MB, written by %s\n", path.c_str(), fi.version,
              double(fi.payload_bytes) / 1e6, fi.producer.c_str());
  for (const auto& cj : j["clients"]) {
    std::printf("client %d '%s': %zu poses (resume after seq %llu), main map %d in group %d\n", cj["id"].get<int>(),
                cj["name"].get<std::string>().c_str(), cj["trajectory_poses"].get<std::size_t>(),
                (unsigned long long)cj["last_seq"].get<std::uint64_t>(), cj["main_map"].get<int>(),
                cj["group"].get<int>());
    for (const auto& m : cj["maps"])
      std::printf("  map %d (group %d): %zu keyframes, %zu points\n", m["index"].get<int>(), m["group"].get<int>(),
                  m["keyframes"].get<std::size_t>(), m["points"].get<std::size_t>());
  }
  for (const auto& [g, members] : groups) {
    std::printf("group %d:", g);
    for (int c : members) std::printf(" %d", c);
    std::printf("\n");
  }
  return 0;
}

int cmd_export_ply(int argc, char** argv) {
  CliArgs args("cslam-map export-ply", "Writes the sparse map points of a snapshot as a coloured PLY.");
  args.positional("FILE", "snapshot file")
      .option("out", "output PLY file (-o)")
      .option("group", "only this group's maps (default: every map)", "");
  if (!args.parse(argc, argv, 2)) return 0;
  const SystemState s = snapshot::read_file(args.positionals()[0]);
  const std::string only = args.get("group");
  ColoredCloud cloud;
  for (const auto& c : s.clients)
    for (const auto& m : c.maps) {
      if (!only.empty() && group_of(c, m.index) != std::stoi(only)) continue;
      for (const auto& p : m.points) {
        cloud.points.push_back(p.position.cast<float>());
        cloud.colors.push_back({p.color[2], p.color[1], p.color[0]});
      }
    }
  if (cloud.empty()) throw InputError(args.positionals()[0], "no map points to export");
  write_ply(args.get("out"), cloud);
  std::printf("%zu points written to %s\n", cloud.size(), args.get("out").c_str());
  return 0;
}

int cmd_export_tum(int argc, char** argv) {
  CliArgs args("cslam-map export-tum", "Writes the trajectories of a snapshot in the TUM format.");
  args.positional("FILE", "snapshot file").option("out", "output folder (-o)");
  if (!args.parse(argc, argv, 2)) return 0;
  const SystemState s = snapshot::read_file(args.positionals()[0]);
  const std::string dir = args.get("out");
  std::filesystem::create_directories(dir);
  std::map<int, Trajectory> fused;
  std::map<int, int> members;
  for (const auto& c : s.clients) {
    int main_map = -1;
    const Trajectory t = state_trajectory(c, &main_map);
    const std::string id = std::to_string(c.info.id);
    const int g = group_of(c, main_map);
    write_tum_trajectory(dir + "/client_" + id + ".txt", t, "client " + id + ", frame of group " + std::to_string(g));
    if (main_map >= 0)
      write_tum_trajectory(dir + "/keyframes_" + id + ".txt", state_keyframes(c.maps[std::size_t(main_map)]),
                           "client " + id + " keyframes");
    fused[g].insert(fused[g].end(), t.begin(), t.end());
    ++members[g];
    std::printf("client %s: %zu poses (group %d)\n", id.c_str(), t.size(), g);
  }
  for (auto& [g, t] : fused) {
    if (members[g] < 2) continue;
    sort_by_time(t);
    write_tum_trajectory(dir + "/fused_" + std::to_string(g) + ".txt", t, "fused group " + std::to_string(g));
  }
  return 0;
}

int cmd_merge(int argc, char** argv) {
  CliArgs args("cslam-map merge",
               "Loads two snapshots (clients with different ids) into one system, lets map fusion look at every "
               "keyframe, and writes the result as one snapshot.");
  args.positional("A", "first snapshot")
      .positional("B", "second snapshot")
      .option("out", "output snapshot file (-o)")
      .option("vocab", "vocabulary file (default: the project's)", "")
      .flag("no-group-ba", "skip the global BA over a newly fused group")
      .option("log-level", "trace, debug, info, warn, error, off", "info");
  if (!args.parse(argc, argv, 2)) return 0;
  set_log_level(args.get("log-level"));
  const std::string a = args.positionals()[0], b = args.positionals()[1], out = args.get("out");
  const SystemState sa = snapshot::read_file(a), sb = snapshot::read_file(b);
  for (const auto& ca : sa.clients)
    for (const auto& cb : sb.clients)
      if (ca.info.id == cb.info.id)
        throw InputError(b,
                         "client " + std::to_string(cb.info.id) + " is also in " + a + " (ids must differ to merge)");
  SystemConfig config;
  config.vocabulary_path = args.get("vocab");
  config.fusion.queue_capacity = std::size_t(1) << 24;  // every keyframe is offered at once
  config.fusion.group_ba = !args.flag_set("no-group-ba");
  config.slam.threaded = true;
  CollaborativeSystem system(config);
  system.restore_state(sa, a);
  system.restore_state(sb, b);
  system.offer_keyframes_to_fusion();
  system.finish();  // fusion processes every queued keyframe, group BA completes
  const SystemState merged = system.export_state();
  snapshot::EncodeOptions options;
  options.producer = "cslam-map merge";
  snapshot::write_file_atomic(out, snapshot::encode(merged, options));
  const auto groups = system.groups();
  std::printf("merged %zu + %zu clients into %s: %zu group(s)\n", sa.clients.size(), sb.clients.size(), out.c_str(),
              groups.size());
  for (const auto& [g, members] : groups) {
    std::printf("group %d:", g.value());
    for (ClientId c : members) std::printf(" %d", int(c));
    std::printf("\n");
  }
  return 0;
}

int run(int argc, char** argv) {
  const std::string usage =
      "usage: cslam-map info FILE [--json] | export-ply FILE -o OUT.ply | export-tum FILE -o DIR | merge A B -o C";
  if (argc < 2) throw ConfigError(usage);
  // "-o FILE" is the short form of "--out FILE" (the shared parser knows long options only).
  std::vector<std::string> storage(argv, argv + argc);
  for (auto& a : storage)
    if (a == "-o") a = "--out";
  std::vector<char*> args;
  for (auto& a : storage) args.push_back(a.data());
  argv = args.data();
  const std::string cmd = argv[1];
  if (cmd == "info") return cmd_info(argc, argv);
  if (cmd == "export-ply") return cmd_export_ply(argc, argv);
  if (cmd == "export-tum") return cmd_export_tum(argc, argv);
  if (cmd == "merge") return cmd_merge(argc, argv);
  if (cmd == "--help" || cmd == "-h") {
    std::cout << usage << "\n";
    return 0;
  }
  throw ConfigError("unknown command '" + cmd + "'; " + usage);
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-map", argc, argv, run); }
