#include "run_evaluation.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/stats.h"
#include "eval/trajectory_eval.h"

namespace cslam::experiment {

namespace fs = std::filesystem;

namespace {

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "missing (the run wrote no statistics)");
  try {
    return nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw InputError(path, std::string("malformed JSON: ") + e.what());
  }
}

Trajectory read_trajectory(const std::string& path) {
  if (!fs::exists(path)) throw InputError(path, "missing (the run wrote no trajectory)");
  return read_tum_trajectory(path);
}

Trajectory read_optional(const std::string& path) {
  return fs::exists(path) ? read_tum_trajectory(path) : Trajectory{};
}

template <typename T>
T value_or(const nlohmann::json& j, const char* key, T fallback) {
  return j.contains(key) && !j[key].is_null() ? j[key].get<T>() : fallback;
}

Trajectory time_window(const Trajectory& t, double from, double to) {
  Trajectory out;
  for (const auto& p : t)
    if (p.timestamp >= from && p.timestamp <= to) out.push_back(p);
  return out;
}

// SLAM time and the per-client statistics: the single-client format of cslam-slam or the
// collaborative system's stats.json (offline multi-client and cslam-server).
void read_statistics(const RunConfig& cfg, RunMode mode, const std::string& out, RunRecord& rec) {
  const bool single_offline = mode == RunMode::kOffline && cfg.clients == 1;
  const nlohmann::json stats = read_json(out + "/stats.json");
  if (single_offline) {
    rec.slam_time_s = stats.at("wall_time_s").get<double>();
    ClientRecord& c = rec.client_records.at(0);
    c.frames_processed = value_or(stats, "frames", -1);
    c.frames_lost = value_or(stats, "frames_lost", -1);
    c.keyframes = value_or(stats, "keyframes", -1);
    c.group = 1;
    return;
  }
  if (mode == RunMode::kOffline) {
    rec.slam_time_s = read_json(out + "/summary.json").at("slam_time_s").get<double>();
  } else {
    const nlohmann::json net = read_json(out + "/network_stats.json");
    rec.slam_time_s = net.at("wall_s").get<double>();
    rec.receive_span_s = value_or(net, "first_to_last_frame_s", kNaN);
  }
  for (const auto& cj : stats.at("clients")) {
    const int id = cj.at("id").get<int>();
    for (auto& c : rec.client_records) {
      if (c.id != id) continue;
      c.frames_processed = value_or(cj, "frames_processed", -1);
      c.frames_lost = value_or(cj, "frames_lost", -1);
      c.keyframes = value_or(cj, "keyframes", -1);
      c.group = value_or(cj, "group", -1);
      c.fused = value_or(cj, "fused", false);
    }
  }
  for (const auto& e : stats.at("fusion_events")) {
    if (value_or<std::string>(e, "kind", "fusion") != "fusion") continue;
    FusionRecord f;
    f.wall_time_s = value_or(e, "time_s", kNaN);
    f.client_a = value_or(e, "client_a", 0);
    f.client_b = value_or(e, "client_b", 0);
    f.query_timestamp = value_or(e, "query_timestamp", kNaN);
    f.candidate_timestamp = value_or(e, "candidate_timestamp", kNaN);
    f.inliers = value_or(e, "inliers", 0);
    f.duration_ms = value_or(e, "duration_ms", kNaN);
    rec.fusions.push_back(f);
  }
  std::sort(rec.fusions.begin(), rec.fusions.end(),
            [](const auto& a, const auto& b) { return a.wall_time_s < b.wall_time_s; });
}

// APE of every group with one SE3 alignment per group (one for all clients when all are fused);
// estimates in detail are moved into the ground-truth frame.
void evaluate_accuracy(const RunConfig& cfg, DatasetStore& datasets, RunRecord& rec, RunDetail& detail) {
  for (const auto& s : cfg.specs)
    if (!datasets.get(s.dataset).groundtruth) {
      rec.ate.note = "no ground truth in " + s.dataset;
      return;
    }
  std::map<int, std::vector<std::size_t>> groups;  // group -> indices into tracks
  for (std::size_t i = 0; i < rec.client_records.size(); ++i) groups[rec.client_records[i].group].push_back(i);
  std::vector<double> all_errors;
  double rotation_gap_deg = 0;
  try {
    std::vector<Trajectory> aligned(detail.tracks.size()), aligned_kf(detail.tracks.size());
    for (const auto& [g, members] : groups) {
      std::vector<std::pair<Trajectory, Trajectory>> pairs;
      for (std::size_t i : members) pairs.emplace_back(detail.tracks[i].groundtruth, detail.tracks[i].estimate);
      const AteResult joint = compute_ate_joint(pairs, Alignment::kSE3);
      const Sim3 T_cloud = pose_alignment(pairs);
      for (std::size_t i : members) {
        detail.tracks[i].T_gt_est_cloud = T_cloud;
        const Eigen::Matrix3d dR = T_cloud.R() * joint.T_gt_est.R().transpose();
        rotation_gap_deg = std::max(rotation_gap_deg, SE3(dR, Eigen::Vector3d::Zero()).rotation_angle() * 180.0 / M_PI);
        aligned[i] = detail.tracks[i].estimate;
        aligned_kf[i] = detail.tracks[i].keyframes;
        for (Trajectory* traj : {&aligned[i], &aligned_kf[i]})
          for (auto& p : *traj) p.T_world_cam = apply_sim3_to_pose(joint.T_gt_est, p.T_world_cam);
      }
    }
    for (std::size_t i = 0; i < detail.tracks.size(); ++i) {
      ClientTrack& t = detail.tracks[i];
      t.estimate = aligned[i];
      t.keyframes = aligned_kf[i];
      if (t.estimate.size() < 3) continue;  // a client that never initialised: no per-client figure
      const AteResult r = compute_ate(t.groundtruth, t.estimate, Alignment::kNone);
      t.ape_time = r.timestamps;
      t.ape = r.errors;
      rec.client_records[i].ate_rmse = r.stats.rmse;
      all_errors.insert(all_errors.end(), r.errors.begin(), r.errors.end());
    }
  } catch (const InputError& e) {
    rec.ate.note = e.what();
    return;
  }
  detail.aligned = true;
  rec.cloud.alignment_rotation_deg = rotation_gap_deg;
  const ErrorStats s = compute_stats(all_errors);
  rec.ate.n = s.n;
  rec.ate.max = s.max;
  rec.ate.min = s.min;
  rec.ate.mean = s.mean;
  rec.ate.median = s.median;
  rec.ate.rmse = s.rmse;
  rec.ate.std = s.std;
  rec.ate.alignment = groups.size() == 1
                          ? (cfg.clients == 1 ? "SE3" : "one SE3 for all clients")
                          : "one SE3 per group (" + std::to_string(groups.size()) + " groups: not all fused)";
}

}  // namespace

const TumDataset& DatasetStore::get(const std::string& dir) {
  auto it = datasets_.find(dir);
  if (it == datasets_.end()) it = datasets_.emplace(dir, open_tum_dataset(dir)).first;
  return it->second;
}

int frame_number_at(const TumDataset& dataset, int first, int last, double t, double max_dt) {
  if (!std::isfinite(t) || first < 1 || last > int(dataset.pairs.size()) || first > last) return -1;
  const auto begin = dataset.pairs.begin() + (first - 1), end = dataset.pairs.begin() + last;
  auto it = std::lower_bound(begin, end, t, [](const RgbdPair& p, double v) { return p.rgb_time < v; });
  auto best = end;
  double best_dt = max_dt;
  for (auto c : {it, it == begin ? end : it - 1}) {
    if (c == end) continue;
    const double dt = std::abs(c->rgb_time - t);
    if (dt <= best_dt) {
      best_dt = dt;
      best = c;
    }
  }
  return best == end ? -1 : int(best - begin) + 1;
}

Sim3 pose_alignment(const std::vector<std::pair<Trajectory, Trajectory>>& gt_est_pairs, double reach, double max_dt) {
  std::vector<Eigen::Vector3d> src, dst;
  for (const auto& [gt, est] : gt_est_pairs) {
    for (const auto& [i, j] : associate_trajectories(gt, est, max_dt)) {
      const SE3& G = gt[std::size_t(i)].T_world_cam;
      const SE3& E = est[std::size_t(j)].T_world_cam;
      dst.push_back(G.translation());
      src.push_back(E.translation());
      for (int axis = 0; axis < 3; ++axis) {
        const Eigen::Vector3d d = Eigen::Vector3d::Unit(axis) * reach;
        dst.push_back(G * d);
        src.push_back(E * d);
      }
    }
  }
  if (src.size() < 12) throw InputError("pose alignment", "fewer than 3 poses associate with ground truth");
  const UmeyamaResult u = umeyama(src, dst, false);
  if (!u.ok) throw InputError("pose alignment", "degenerate poses");
  return u.T_dst_src;
}

Trajectory groundtruth_at(const Trajectory& groundtruth, const std::vector<double>& timestamps, double max_dt) {
  Trajectory gt = groundtruth;
  sort_by_time(gt);
  Trajectory out;
  for (double t : timestamps) {
    StampedPose p;
    p.timestamp = t;
    if (const auto T = interpolate_pose(gt, t, 5 * max_dt)) {
      p.T_world_cam = *T;
    } else {  // across a gap in the ground truth: the nearest sample within max_dt, if any
      auto it =
          std::lower_bound(gt.begin(), gt.end(), t, [](const StampedPose& q, double v) { return q.timestamp < v; });
      const StampedPose* nearest = nullptr;
      if (it != gt.end() && it->timestamp - t <= max_dt) nearest = &*it;
      if (it != gt.begin() && t - (it - 1)->timestamp <= max_dt &&
          (!nearest || t - (it - 1)->timestamp < nearest->timestamp - t))
        nearest = &*(it - 1);
      if (!nearest) continue;
      p.T_world_cam = nearest->T_world_cam;
    }
    out.push_back(p);
  }
  return out;
}

void evaluate_run(const RunConfig& cfg, RunMode mode, const std::string& out, DatasetStore& datasets, RunRecord& rec,
                  RunDetail& detail) {
  const bool single_offline = mode == RunMode::kOffline && cfg.clients == 1;
  rec.client_records.clear();
  detail = RunDetail{};
  detail.time_origin = std::numeric_limits<double>::infinity();
  for (const auto& s : cfg.specs) {
    const TumDataset& ds = datasets.get(s.dataset);
    ClientRecord c;
    c.id = s.id;
    c.dataset = s.dataset;
    c.first = s.first;
    c.last = s.last;
    rec.client_records.push_back(c);
    ClientTrack t;
    t.id = s.id;
    const std::string id = std::to_string(s.id);
    t.estimate = read_trajectory(single_offline ? out + "/traj.txt" : out + "/client_" + id + ".txt");
    t.keyframes = read_optional(single_offline ? out + "/keyframes.txt" : out + "/keyframes_" + id + ".txt");
    const double t0 = ds.pairs.at(std::size_t(s.first - 1)).rgb_time,
                 t1 = ds.pairs.at(std::size_t(s.last - 1)).rgb_time;
    if (ds.groundtruth) t.groundtruth = time_window(*ds.groundtruth, t0 - 0.05, t1 + 0.05);
    detail.time_origin = std::min(detail.time_origin, cfg.split ? ds.pairs.front().rgb_time : t0);
    rec.client_records.back().poses = t.estimate.size();
    t.raw_estimate = t.estimate;
    detail.tracks.push_back(std::move(t));
  }
  read_statistics(cfg, mode, out, rec);

  // Fusion frames: each keyframe's position among its own client's frames.
  auto spec_of = [&](int id) -> const ClientSpec* {
    for (const auto& s : cfg.specs)
      if (s.id == id) return &s;
    return nullptr;
  };
  for (auto& f : rec.fusions) {
    if (const ClientSpec* a = spec_of(f.client_a))
      f.frame_a = frame_number_at(datasets.get(a->dataset), a->first, a->last, f.query_timestamp);
    if (const ClientSpec* b = spec_of(f.client_b))
      f.frame_b = frame_number_at(datasets.get(b->dataset), b->first, b->last, f.candidate_timestamp);
  }
  for (auto& c : rec.client_records) {
    for (const auto& f : rec.fusions) {  // time order: the first one that involves the client
      if (f.client_a == c.id || f.client_b == c.id) {
        c.fused_at_frame = f.client_a == c.id ? f.frame_a : f.frame_b;
        break;
      }
    }
  }
  std::set<int> groups;
  rec.frames_lost = 0;
  for (const auto& c : rec.client_records) {
    groups.insert(c.group);
    rec.frames_lost += std::max(0, c.frames_lost);
  }
  rec.groups = int(groups.size());
  rec.all_fused = groups.size() == 1;
  evaluate_accuracy(cfg, datasets, rec, detail);
}

}  // namespace cslam::experiment
