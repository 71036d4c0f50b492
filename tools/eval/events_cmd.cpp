// cslam-eval events: every loop closure and map fusion a run accepted, checked against ground truth.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/cli.h"
#include "core/error.h"
#include "eval/pose_check.h"
#include "io/trajectory_io.h"

namespace cslam {

namespace {

struct Event {
  std::string kind;  // loop | fusion
  int client_query = 0, client_candidate = 0;
  double query_time = 0, candidate_time = 0;
  SE3 T_query_candidate;
  int inliers = 0;
};

SE3 parse_transform(const std::string& text, const std::string& source) {
  std::istringstream in(text);
  double v[8];
  for (double& x : v)
    if (!(in >> x)) throw InputError(source, "T_query_candidate is not 'stamp x y z qx qy qz qw': '" + text + "'");
  const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
  if (q.norm() < 1e-9) throw InputError(source, "T_query_candidate has a zero quaternion");
  return SE3(q, Eigen::Vector3d(v[1], v[2], v[3]));
}

Event parse_event(const nlohmann::json& j, const std::string& kind, int client, const std::string& source) {
  Event e;
  e.kind = kind;
  e.client_query = kind != "loop" ? j.at("client_a").get<int>() : client;
  e.client_candidate = kind != "loop" ? j.at("client_b").get<int>() : client;
  e.query_time = j.at("query_timestamp").get<double>();
  e.candidate_time = j.at("candidate_timestamp").get<double>();
  e.T_query_candidate = parse_transform(j.at("T_query_candidate").get<std::string>(), source);
  e.inliers = j.value("inliers", 0);
  return e;
}

// Loop events of cslam-slam (top level) and of multi-client runs (per client), fusion events.
std::vector<Event> read_events(const std::string& path, int single_client) {
  std::ifstream f(path);
  if (!f) throw InputError(path, "cannot open");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(f);
  } catch (const std::exception& e) {
    throw InputError(path, std::string("not JSON: ") + e.what());
  }
  std::vector<Event> out;
  try {
    for (const auto& e : j.value("loop_events", nlohmann::json::array()))
      out.push_back(parse_event(e, "loop", single_client, path));
    for (const auto& c : j.value("clients", nlohmann::json::array()))
      for (const auto& e : c.value("loop_events", nlohmann::json::array()))
        out.push_back(parse_event(e, "loop", c.at("id").get<int>(), path));
    for (const auto& e : j.value("fusion_events", nlohmann::json::array()))
      out.push_back(parse_event(e, e.value("kind", "fusion"), 0, path));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, std::string("unexpected event layout: ") + e.what());
  }
  return out;
}

}  // namespace

int cmd_events(int argc, char** argv) {
  CliArgs args("cslam-eval events",
               "Checks every accepted loop closure and map fusion of a run (stats.json of cslam-slam or cslam-server)\n"
               "against ground truth: the measured camera-to-camera transform vs the interpolated ground-truth one.");
  args.positional("STATS", "stats.json with loop_events / clients[].loop_events / fusion_events")
      .option("gt", "ground truth of every client (a split of one sequence)", "")
      .multi_option("client-gt", "per-client ground truth instead: K PATH [K PATH ...] (robots of one synthetic scene)")
      .option("client", "client id of a single-client run's loop events", "1")
      .option("offset", "seconds added to event timestamps to read ground truth, or 'auto' (estimated from --est)", "0")
      .option("est", "estimated trajectory for --offset auto (against --gt)", "")
      .option("max-rotation", "rotation error bound (deg)", "2")
      .option("max-translation", "translation error bound (m)", "0.05")
      .flag("json", "print JSON instead of a table");
  if (!args.parse(argc, argv, 2)) return 0;
  std::map<int, Trajectory> gt_of;
  Trajectory shared_gt;
  if (!args.get("gt").empty()) shared_gt = read_tum_trajectory(args.get("gt"));
  const auto client_gt = args.get_multi("client-gt");
  if (client_gt.size() % 2 != 0) throw ConfigError("--client-gt takes pairs: K PATH [K PATH ...]");
  for (size_t i = 0; i < client_gt.size(); i += 2)
    gt_of[std::stoi(client_gt[i])] = read_tum_trajectory(client_gt[i + 1]);
  if (shared_gt.empty() && gt_of.empty()) throw ConfigError("give --gt or --client-gt");
  for (auto& [k, t] : gt_of) sort_by_time(t);
  sort_by_time(shared_gt);
  auto gt_for = [&](int client) -> const Trajectory& {
    auto it = gt_of.find(client);
    if (it != gt_of.end()) return it->second;
    if (shared_gt.empty()) throw ConfigError("no ground truth for client " + std::to_string(client));
    return shared_gt;
  };
  double offset = 0;
  TimeOffsetResult estimated;
  if (args.get("offset") == "auto") {
    if (args.get("est").empty() || shared_gt.empty()) throw ConfigError("--offset auto needs --est and --gt");
    estimated = estimate_time_offset(shared_gt, read_tum_trajectory(args.get("est")));
    offset = estimated.offset_s;
  } else {
    offset = args.get_double("offset");
  }
  const double max_rot = args.get_double("max-rotation"), max_trans = args.get_double("max-translation");
  const auto events = read_events(args.positionals()[0], args.get_int("client"));
  nlohmann::json out;
  out["offset_s"] = offset;
  if (estimated.ok)
    out["offset_estimate"] = {{"median_relative_rotation_deg", estimated.median_rotation_deg},
                              {"median_relative_rotation_deg_at_zero", estimated.median_rotation_deg_at_zero},
                              {"pairs", estimated.pairs}};
  int within = 0, checked = 0;
  out["events"] = nlohmann::json::array();
  for (const auto& e : events) {
    const auto r = relative_pose_error(gt_for(e.client_query), e.query_time, gt_for(e.client_candidate),
                                       e.candidate_time, e.T_query_candidate, offset);
    const bool ok = r.valid && r.rotation_deg < max_rot && r.translation_m < max_trans;
    checked += r.valid ? 1 : 0;
    within += ok ? 1 : 0;
    nlohmann::json je = {{"kind", e.kind},
                         {"client_query", e.client_query},
                         {"client_candidate", e.client_candidate},
                         {"query_timestamp", e.query_time},
                         {"candidate_timestamp", e.candidate_time},
                         {"inliers", e.inliers},
                         {"has_ground_truth", r.valid},
                         {"within_bounds", ok}};
    if (r.valid) {
      je["rotation_error_deg"] = r.rotation_deg;
      je["translation_error_m"] = r.translation_m;
    }
    out["events"].push_back(je);
  }
  out["events_total"] = events.size();
  out["events_with_ground_truth"] = checked;
  out["events_within_bounds"] = within;
  out["bounds"] = {{"rotation_deg", max_rot}, {"translation_m", max_trans}};
  if (args.flag_set("json")) {
    std::cout << out.dump(2) << "\n";
  } else {
    std::printf("time offset %+.3f s", offset);
    if (estimated.ok)
      std::printf(" (estimated: median 0.5 s relative rotation error %.2f deg, %.2f deg at 0)",
                  estimated.median_rotation_deg, estimated.median_rotation_deg_at_zero);
    std::printf("\n%-11s %7s %17s %17s %8s %9s %9s %s\n", "kind", "clients", "query_t", "candidate_t", "inliers",
                "rot_deg", "trans_m", "ok");
    for (const auto& je : out["events"]) {
      const bool v = je["has_ground_truth"].get<bool>();
      std::printf("%-11s %3d->%-3d %17.3f %17.3f %8d %9s %9s %s\n", je["kind"].get<std::string>().c_str(),
                  je["client_query"].get<int>(), je["client_candidate"].get<int>(), je["query_timestamp"].get<double>(),
                  je["candidate_timestamp"].get<double>(), je["inliers"].get<int>(),
                  v ? std::to_string(je["rotation_error_deg"].get<double>()).substr(0, 6).c_str() : "n/a",
                  v ? std::to_string(je["translation_error_m"].get<double>()).substr(0, 6).c_str() : "n/a",
                  je["within_bounds"].get<bool>() ? "yes" : "NO");
    }
    std::printf("%d events, %d with ground truth, %d within %.1f deg / %.3f m\n", int(events.size()), checked, within,
                max_rot, max_trans);
  }
  return 0;
}

}  // namespace cslam
