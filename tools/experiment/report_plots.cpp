#include "report_plots.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "support/report/svg_plot.h"
#include "support/report/text_output.h"

namespace cslam::experiment {

namespace {

using report::client_color;
using report::Panel;
using report::Series;

std::string title_of(const ConfigSummary& s) {
  std::string t = s.config->label;
  if (std::isfinite(s.config->overlap_percent)) t += ", η = " + overlap_text(s.config->overlap_percent) + " %";
  return t + " — repeat " + std::to_string(s.representative->repeat);
}

// Nearest sample of a time series (NaN if empty).
double value_at(const std::vector<double>& times, const std::vector<double>& values, double t) {
  double best = kNaN, best_dt = 1e300;
  for (std::size_t i = 0; i < times.size(); ++i)
    if (std::abs(times[i] - t) < best_dt) {
      best_dt = std::abs(times[i] - t);
      best = values[i];
    }
  return best;
}

const StampedPose* pose_at(const Trajectory& traj, double t) {
  const StampedPose* best = nullptr;
  for (const auto& p : traj)
    if (!best || std::abs(p.timestamp - t) < std::abs(best->timestamp - t)) best = &p;
  return best && std::abs(best->timestamp - t) < 0.1 ? best : nullptr;
}

const ClientTrack* track_of(const RunDetail& d, int id) {
  for (const auto& t : d.tracks)
    if (t.id == id) return &t;
  return nullptr;
}

// Ground truth to draw: one line for a split sequence (clients share it), else one per client.
std::vector<Trajectory> groundtruth_lines(const RunDetail& d, bool split) {
  std::vector<Trajectory> out;
  if (!split) {
    for (const auto& t : d.tracks) out.push_back(t.groundtruth);
    return out;
  }
  Trajectory all;
  for (const auto& t : d.tracks) all.insert(all.end(), t.groundtruth.begin(), t.groundtruth.end());
  sort_by_time(all);
  all.erase(
      std::unique(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.timestamp == b.timestamp; }),
      all.end());
  out.push_back(all);
  return out;
}

// A trajectory component over time: position x/y/z, or the rotation relative to the reference
// camera pose as its rotation vector's components along that camera's x, y, z axes (3, 4, 5).
// Unlike Euler angles these have no gimbal lock; past 180 degrees in total they wrap, and the
// line breaks there (NaN).
Series component(const Trajectory& traj, double origin, int which, const SE3& reference, const std::string& color,
                 const std::string& label) {
  Series s;
  s.color = color;
  s.label = label;
  Eigen::Vector3d previous(kNaN, kNaN, kNaN);
  for (const auto& p : traj) {
    double v;
    if (which < 3) {
      v = p.T_world_cam.translation()[which];
    } else {
      const Eigen::Vector3d r = rotation_vector_deg(reference.rotation().conjugate() * p.T_world_cam.rotation());
      v = r[which - 3];
      // Past 180 degrees the rotation vector flips to the other side: break the line there.
      if (previous.allFinite() && (r - previous).norm() > 90) {
        s.x.push_back(kNaN);
        s.y.push_back(kNaN);
      }
      previous = r;
    }
    s.x.push_back(p.timestamp - origin);
    s.y.push_back(v);
  }
  return s;
}

// X-Y positions of a trajectory (a line, or dots for keyframes).
Series xy_series(const Trajectory& traj, const std::string& color, const std::string& label) {
  Series s;
  s.color = color;
  s.label = label;
  for (const auto& p : traj) {
    s.x.push_back(p.T_world_cam.translation().x());
    s.y.push_back(p.T_world_cam.translation().y());
  }
  return s;
}

void add_fusion_vlines(Panel& p, const RunRecord& r, double origin) {
  for (std::size_t i = 0; i < r.fusions.size(); ++i)
    p.vlines.push_back({r.fusions[i].query_timestamp - origin, "#444444", "F" + std::to_string(i + 1)});
}

std::string client_label(const RunRecord& r, int id) {
  for (const auto& c : r.client_records)
    if (c.id == id)
      return "client " + std::to_string(id) + " (" + std::to_string(c.first) + "–" + std::to_string(c.last) + ")";
  return "client " + std::to_string(id);
}

Panel ape_panel(const ConfigSummary& s, const RunDetail& d) {
  const RunRecord& r = *s.representative;
  Panel p;
  p.title = d.aligned ? "APE per pose (" + r.ate.alignment + "), F = map fusion (query keyframe time)"
                      : "APE: no ground truth";
  p.x_label = "time since the sequence start (s)";
  p.y_label = "APE (m)";
  p.y_from_zero = true;
  for (const auto& t : d.tracks) {
    Series se;
    se.label = client_label(r, t.id);
    se.color = client_color(t.id);
    for (std::size_t i = 0; i < t.ape.size(); ++i) {
      se.x.push_back(t.ape_time[i] - d.time_origin);
      se.y.push_back(t.ape[i]);
    }
    p.series.push_back(se);
  }
  add_fusion_vlines(p, r, d.time_origin);
  for (std::size_t i = 0; i < r.fusions.size(); ++i) {
    const auto& f = r.fusions[i];
    for (const auto& [id, t] :
         {std::pair{f.client_a, f.query_timestamp}, std::pair{f.client_b, f.candidate_timestamp}}) {
      const ClientTrack* tr = track_of(d, id);
      if (!tr || tr->ape.empty()) continue;
      p.markers.push_back(
          {t - d.time_origin, value_at(tr->ape_time, tr->ape, t), client_color(id), "F" + std::to_string(i + 1)});
    }
  }
  return p;
}

Panel xy_panel(const ConfigSummary& s, const RunDetail& d) {
  const RunRecord& r = *s.representative;
  Panel p;
  p.title = d.aligned ? "X-Y, ground-truth frame (" + r.ate.alignment + "); dots = keyframes"
                      : "X-Y in the SLAM frame (no ground truth)";
  p.x_label = "x (m)";
  p.y_label = "y (m)";
  p.equal_aspect = true;
  bool first = true;
  for (const auto& gt : groundtruth_lines(d, s.config->split)) {
    Series g = xy_series(gt, report::kGroundTruthColor, first && !gt.empty() ? "ground truth" : "");
    g.width = 1.0;
    g.dashed = true;
    first = first && gt.empty();
    p.series.push_back(g);
  }
  for (const auto& t : d.tracks) {
    p.series.push_back(xy_series(t.estimate, client_color(t.id), client_label(r, t.id)));
    Series k = xy_series(t.keyframes, client_color(t.id), "");
    k.line = false;
    k.marker_radius = 1.8;
    p.series.push_back(k);
  }
  for (std::size_t i = 0; i < r.fusions.size(); ++i) {
    const auto& f = r.fusions[i];
    for (const auto& [id, t] :
         {std::pair{f.client_a, f.query_timestamp}, std::pair{f.client_b, f.candidate_timestamp}}) {
      const ClientTrack* tr = track_of(d, id);
      const StampedPose* pose = tr ? pose_at(tr->estimate, t) : nullptr;
      if (pose)
        p.markers.push_back({pose->T_world_cam.translation().x(), pose->T_world_cam.translation().y(), client_color(id),
                             "F" + std::to_string(i + 1)});
    }
  }
  return p;
}

std::vector<Panel> pose_panels(const ConfigSummary& s, const RunDetail& d) {
  static const char* kNames[] = {"x (m)",
                                 "y (m)",
                                 "z (m)",
                                 "rotation about camera x (tilt)",
                                 "rotation about camera y (pan)",
                                 "rotation about camera z (roll)"};
  const RunRecord& r = *s.representative;
  // Rotations relative to the first ground-truth pose (or the first estimate without ground truth).
  SE3 reference;
  for (const auto& t : d.tracks) {
    const Trajectory& src = !t.groundtruth.empty() && d.aligned ? t.groundtruth : t.estimate;
    if (!src.empty()) {
      reference = src.front().T_world_cam;
      break;
    }
  }
  std::vector<Panel> panels;
  for (int which : {0, 3, 1, 4, 2, 5}) {  // two columns: position left, rotation right
    Panel p;
    p.title =
        which < 3 ? std::string(kNames[which]) : std::string(kNames[which]) + " since the first pose, rotation vector";
    p.x_label = "time since the sequence start (s)";
    static const char* kShort[] = {"x (m)", "y (m)", "z (m)", "tilt (deg)", "pan (deg)", "roll (deg)"};
    p.y_label = kShort[which];
    bool first = true;
    for (const auto& gt : groundtruth_lines(d, s.config->split)) {
      Series g = component(gt, d.time_origin, which, reference, report::kGroundTruthColor, first ? "ground truth" : "");
      g.width = 1.0;
      g.dashed = true;
      first = false;
      p.series.push_back(g);
    }
    for (const auto& t : d.tracks)
      p.series.push_back(
          component(t.estimate, d.time_origin, which, reference, client_color(t.id), "client " + std::to_string(t.id)));
    add_fusion_vlines(p, r, d.time_origin);
    panels.push_back(p);
  }
  return panels;
}

// SLAM time and APE RMSE against the overlap rate (split) or the number of clients (datasets).
std::vector<Panel> overview_panels(const std::vector<ConfigSummary>& summaries) {
  bool split = false;
  for (const auto& s : summaries) split = split || std::isfinite(s.config->overlap_percent);
  std::vector<Panel> panels(2);
  panels[0].title = "SLAM time (median, bars: min–max; runs without other load if any)";
  panels[0].y_label = "SLAM time (s)";
  panels[1].title = "combined APE RMSE (median, bars: min–max)";
  panels[1].y_label = "APE RMSE (m)";
  double x_lo = 1e300, x_hi = -1e300;
  for (const auto& s : summaries)
    if (std::isfinite(s.config->overlap_percent)) {
      x_lo = std::min(x_lo, s.config->overlap_percent);
      x_hi = std::max(x_hi, s.config->overlap_percent);
    }
  int k_max = 1;
  for (const auto& s : summaries) k_max = std::max(k_max, s.config->clients);
  for (int which = 0; which < 2; ++which) {
    Panel& p = panels[std::size_t(which)];
    p.x_label = split ? "overlap rate η (%)" : "number of clients";
    p.x_min = split ? 0.0 : 0.5;
    p.x_max = split ? (x_hi > 0 ? x_hi * 1.1 : 1.0) : k_max + 0.5;
    p.y_from_zero = true;
    std::map<int, Series> by_k;
    for (const auto& s : summaries) {
      // SLAM time from the runs without other load when there are any (as time / single).
      bool any_quiet = false;
      for (const auto* r : s.runs) any_quiet = any_quiet || (r->ok && is_quiet(*r));
      std::vector<double> v;
      for (const auto* r : s.runs)
        if (r->ok && (which == 1 || !any_quiet || is_quiet(*r))) v.push_back(which == 0 ? r->slam_time_s : r->ate.rmse);
      const report::Spread sp = report::spread(v);
      if (sp.n == 0) continue;
      const int k = s.config->clients;
      Series& se = by_k[split ? k : 0];
      se.color = split ? client_color(k) : "#1f77b4";
      se.label = split ? (k == 1 ? "single" : std::to_string(k) + " clients") : "median";
      se.marker_radius = 3.5;
      se.line = split && k > 1;
      if (split && k == 1) {  // the single-client run as a dashed level across the η range
        se.line = true;
        se.dashed = true;
        se.marker_radius = 0;
        for (double x : {x_lo, x_hi}) {
          se.x.push_back(x);
          se.y.push_back(sp.median);
          se.y_low.push_back(kNaN);
          se.y_high.push_back(kNaN);
        }
        continue;
      }
      se.x.push_back(split ? s.config->overlap_percent : double(k));
      se.y.push_back(sp.median);
      se.y_low.push_back(sp.min);
      se.y_high.push_back(sp.max);
    }
    for (auto& [k, se] : by_k) p.series.push_back(se);
  }
  return panels;
}

}  // namespace

Eigen::Vector3d rotation_vector_deg(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0) q.coeffs() *= -1;
  const double n = q.vec().norm();
  if (n < 1e-12) return 2.0 * q.vec() * 180.0 / M_PI;
  return q.vec() / n * (2.0 * std::atan2(n, q.w()) * 180.0 / M_PI);
}

Rpy roll_pitch_yaw_deg(const SE3& T) {
  const Eigen::Matrix3d R = T.R();
  constexpr double kDeg = 180.0 / M_PI;
  Rpy r;
  r.yaw = std::atan2(R(1, 0), R(0, 0)) * kDeg;
  r.pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0)) * kDeg;
  r.roll = std::atan2(R(2, 1), R(2, 2)) * kDeg;
  return r;
}

std::vector<std::string> write_figures(const std::string& out_dir, std::vector<ConfigSummary>& summaries,
                                       const DetailMap& details, std::size_t max_points) {
  std::filesystem::create_directories(out_dir + "/figures");
  for (auto& s : summaries) {
    s.figures.clear();
    if (!s.representative) continue;
    const auto it = details.find({s.representative->config, s.representative->repeat});
    if (it == details.end()) continue;
    const RunDetail& d = it->second;
    const std::string base = "figures/" + s.config->name;
    report::FigureOptions o;
    o.max_points = max_points;
    o.title = "APE over time — " + title_of(s);
    o.panel_height = 320;
    report::write_svg(out_dir + "/" + base + "_ape.svg", {ape_panel(s, d)}, o);
    o.title = "X-Y trajectories — " + title_of(s);
    o.panel_height = 560;
    o.width = 760;
    report::write_svg(out_dir + "/" + base + "_xy.svg", {xy_panel(s, d)}, o);
    o.title = "Position and rotation over time — " + title_of(s);
    o.panel_height = 230;
    o.width = 1100;
    o.columns = 2;
    o.max_points = std::min<std::size_t>(max_points, 300);
    report::write_svg(out_dir + "/" + base + "_pose.svg", pose_panels(s, d), o);
    s.figures = {base + "_ape.svg", base + "_xy.svg", base + "_pose.svg"};
  }
  report::FigureOptions o;
  o.title = "Overview: SLAM time and combined APE per configuration";
  o.columns = 2;
  o.width = 1100;
  o.panel_height = 320;
  report::write_svg(out_dir + "/figures/overview.svg", overview_panels(summaries), o);
  return {"figures/overview.svg"};
}

}  // namespace cslam::experiment
