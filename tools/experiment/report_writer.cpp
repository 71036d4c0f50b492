// Aggregation and the machine-readable outputs (results.csv, results.json).
#include "report_writer.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "support/report/text_output.h"

namespace cslam::experiment {

namespace {

double first_fusion_s(const RunRecord& r) { return r.fusions.empty() ? kNaN : r.fusions.front().wall_time_s; }

nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json record_json(const RunRecord& r) {
  nlohmann::json j;
  j["config"] = r.config;
  j["label"] = r.label;
  j["clients"] = r.clients;
  j["overlap_percent"] = number(r.overlap_percent);
  j["repeat"] = r.repeat;
  j["mode"] = r.mode;
  j["status"] = r.ok ? "ok" : "failed";
  j["error"] = r.error;
  j["run_dir"] = r.run_dir;
  for (const Metric& m : metrics()) j[m.name] = number(m.get(r));
  j["ate_alignment"] = r.ate.alignment;
  j["ate_note"] = r.ate.note;
  j["cloud_note"] = r.cloud.note;
  j["all_fused"] = r.all_fused;
  j["client_records"] = nlohmann::json::array();
  for (const auto& c : r.client_records)
    j["client_records"].push_back({{"id", c.id},
                                   {"dataset", c.dataset},
                                   {"first_frame", c.first},
                                   {"last_frame", c.last},
                                   {"frames_processed", c.frames_processed},
                                   {"frames_lost", c.frames_lost},
                                   {"keyframes", c.keyframes},
                                   {"poses", c.poses},
                                   {"group", c.group},
                                   {"fused", c.fused},
                                   {"fused_at_frame", c.fused_at_frame},
                                   {"ate_rmse_m", number(c.ate_rmse)}});
  j["fusion_events"] = nlohmann::json::array();
  for (const auto& f : r.fusions)
    j["fusion_events"].push_back({{"time_s", number(f.wall_time_s)},
                                  {"query_client", f.client_a},
                                  {"candidate_client", f.client_b},
                                  {"query_frame", f.frame_a},
                                  {"candidate_frame", f.frame_b},
                                  {"query_timestamp", number(f.query_timestamp)},
                                  {"candidate_timestamp", number(f.candidate_timestamp)},
                                  {"inliers", f.inliers},
                                  {"duration_ms", number(f.duration_ms)}});
  return j;
}

}  // namespace

const std::vector<Metric>& metrics() {
  static const std::vector<Metric> kMetrics = {
      {"slam_time_s", 2, [](const RunRecord& r) { return r.slam_time_s; }},
      {"process_wall_s", 2, [](const RunRecord& r) { return r.process_wall_s; }},
      {"receive_span_s", 2, [](const RunRecord& r) { return r.receive_span_s; }},
      {"load_before", 2, [](const RunRecord& r) { return r.load_before; }},
      {"slam_cpu_s", 2, [](const RunRecord& r) { return r.slam_cpu_s; }},
      {"other_cpu_cores", 2, [](const RunRecord& r) { return r.other_cpu_cores; }},
      {"frames_lost", 0, [](const RunRecord& r) { return r.ok ? double(r.frames_lost) : kNaN; }},
      {"groups", 0, [](const RunRecord& r) { return r.ok ? double(r.groups) : kNaN; }},
      {"fusions", 0, [](const RunRecord& r) { return r.ok ? double(r.fusions.size()) : kNaN; }},
      {"first_fusion_s", 2, first_fusion_s},
      {"ate_n", 0, [](const RunRecord& r) { return r.ate.n > 0 ? double(r.ate.n) : kNaN; }},
      {"ate_max_m", 4, [](const RunRecord& r) { return r.ate.max; }},
      {"ate_min_m", 4, [](const RunRecord& r) { return r.ate.min; }},
      {"ate_mean_m", 4, [](const RunRecord& r) { return r.ate.mean; }},
      {"ate_median_m", 4, [](const RunRecord& r) { return r.ate.median; }},
      {"ate_rmse_m", 4, [](const RunRecord& r) { return r.ate.rmse; }},
      {"ate_std_m", 4, [](const RunRecord& r) { return r.ate.std; }},
      {"hausdorff_bbox_m", 4, [](const RunRecord& r) { return r.cloud.hausdorff_bbox; }},
      {"hausdorff_bbox_slam_to_gt_m", 4, [](const RunRecord& r) { return r.cloud.hausdorff_bbox_slam_to_gt; }},
      {"c2c_mean_bbox_m", 4, [](const RunRecord& r) { return r.cloud.c2c_mean_bbox; }},
      {"c2c_median_bbox_m", 4, [](const RunRecord& r) { return r.cloud.c2c_median_bbox; }},
      {"live_hausdorff_bbox_m", 4, [](const RunRecord& r) { return r.cloud.live_hausdorff_bbox; }},
      {"live_c2c_median_bbox_m", 4, [](const RunRecord& r) { return r.cloud.live_c2c_median_bbox; }},
      {"live_c2c_median_m", 4, [](const RunRecord& r) { return r.cloud.live_c2c_median; }},
      {"live_c2c_p95_m", 4, [](const RunRecord& r) { return r.cloud.live_c2c_p95; }},
      {"bbox_scale", 4, [](const RunRecord& r) { return r.cloud.bbox_scale; }},
      {"hausdorff_m", 4, [](const RunRecord& r) { return r.cloud.hausdorff; }},
      {"c2c_mean_m", 4, [](const RunRecord& r) { return r.cloud.c2c_mean; }},
      {"c2c_median_m", 4, [](const RunRecord& r) { return r.cloud.c2c_median; }},
      {"scene_c2c_median_m", 4, [](const RunRecord& r) { return r.cloud.scene_median; }},
      {"scene_c2c_mean_m", 4, [](const RunRecord& r) { return r.cloud.scene_mean; }},
      {"scene_c2c_p95_m", 4, [](const RunRecord& r) { return r.cloud.scene_p95; }},
      {"scene_hausdorff_slam_to_scene_m", 4, [](const RunRecord& r) { return r.cloud.scene_max; }},
      {"gt_cloud_scene_c2c_median_m", 4, [](const RunRecord& r) { return r.cloud.gt_scene_median; }},
      {"cloud_alignment_vs_ate_alignment_deg", 2, [](const RunRecord& r) { return r.cloud.alignment_rotation_deg; }},
      {"slam_cloud_points", 0,
       [](const RunRecord& r) { return r.cloud.computed ? double(r.cloud.slam_points) : kNaN; }},
      {"gt_cloud_points", 0, [](const RunRecord& r) { return r.cloud.computed ? double(r.cloud.gt_points) : kNaN; }},
      {"recon_eval_s", 1, [](const RunRecord& r) { return r.cloud.seconds; }},
  };
  return kMetrics;
}

std::vector<ConfigSummary> summarize(const std::vector<RunConfig>& configs, const std::vector<RunRecord>& records) {
  std::vector<ConfigSummary> out;
  for (const auto& c : configs) {
    ConfigSummary s;
    s.config = &c;
    for (const auto& r : records)
      if (r.config == c.name) s.runs.push_back(&r);
    std::vector<const RunRecord*> ok;
    for (const auto* r : s.runs)
      if (r->ok) ok.push_back(r);
    s.ok = int(ok.size());
    // The figures show the run with the median combined ATE (lower median), else median SLAM time.
    std::vector<const RunRecord*> ranked;
    for (const auto* r : ok)
      if (std::isfinite(r->ate.rmse)) ranked.push_back(r);
    auto key = [](const RunRecord* r) { return std::isfinite(r->ate.rmse) ? r->ate.rmse : r->slam_time_s; };
    if (ranked.empty()) ranked = ok;
    std::stable_sort(ranked.begin(), ranked.end(), [&](auto* a, auto* b) { return key(a) < key(b); });
    if (!ranked.empty()) s.representative = ranked[(ranked.size() - 1) / 2];
    out.push_back(std::move(s));
  }
  // SLAM-time ratio to the single-client baseline: the "single" run of the whole sequence, or
  // with one dataset per client the sum of the single runs (one robot covering every path).
  // Runs without other load are used when every configuration involved has some.
  auto times = [](const ConfigSummary& s, bool quiet_only) {
    std::vector<double> v;
    for (const auto* r : s.runs)
      if (r->ok && (!quiet_only || is_quiet(*r))) v.push_back(r->slam_time_s);
    return report::spread(v);
  };
  // The single-client configurations a configuration is compared with: the whole-sequence run
  // (split), or the single runs of exactly the datasets it uses (one dataset per client).
  auto baseline_of = [&out](const ConfigSummary& c) {
    std::vector<const ConfigSummary*> base;
    for (const auto& s : out) {
      if (s.config->clients != 1) continue;
      if (c.config->clients == 1 ? &s == &c
                                 : s.config->split || std::any_of(c.config->specs.begin(), c.config->specs.end(),
                                                                  [&](const ClientSpec& x) {
                                                                    return x.dataset == s.config->specs.at(0).dataset;
                                                                  }))
        base.push_back(&s);
    }
    return base;
  };
  for (bool quiet : {true, false}) {
    for (auto& s : out) {
      if (std::isfinite(s.time_ratio)) continue;
      const auto base = baseline_of(s);
      const auto t = times(s, quiet);
      double baseline = 0;
      bool complete = !base.empty() && t.n > 0;
      for (const auto* b : base) {
        const auto bt = times(*b, quiet);
        complete = complete && bt.n > 0;
        baseline += bt.median;
      }
      if (!complete || baseline <= 0) continue;
      s.time_ratio = t.median / baseline;
      s.time_ratio_quiet = quiet;
    }
  }
  return out;
}

bool is_quiet(const RunRecord& r) { return std::isfinite(r.other_cpu_cores) && r.other_cpu_cores < kQuietOtherCores; }

std::string fused_frames_text(const RunRecord& r) {
  std::string out;
  for (const auto& c : r.client_records)
    if (c.fused_at_frame > 0)
      out += (out.empty() ? "" : ";") + std::to_string(c.id) + ":" + std::to_string(c.fused_at_frame);
  return out;
}

std::string fusion_events_text(const RunRecord& r) {
  std::string out;
  char buf[160];
  for (const auto& f : r.fusions) {
    std::snprintf(buf, sizeof buf, "c%d@%d<->c%d@%d %.2fs", f.client_a, f.frame_a, f.client_b, f.frame_b,
                  f.wall_time_s);
    out += (out.empty() ? "" : "; ") + std::string(buf);
  }
  return out;
}

void write_csv(const std::string& path, const std::vector<ConfigSummary>& summaries) {
  report::Table t;
  t.header = {"row",    "config", "label",     "clients",         "overlap_percent", "repeat",
              "status", "error",  "all_fused", "fused_at_frames", "fusion_events",   "ate_alignment"};
  for (const Metric& m : metrics()) t.header.push_back(m.name);
  for (const auto& s : summaries) {
    for (const auto* r : s.runs) {
      std::vector<std::string> row{"run",
                                   r->config,
                                   r->label,
                                   std::to_string(r->clients),
                                   report::format_number(r->overlap_percent, 2),
                                   std::to_string(r->repeat),
                                   r->ok ? "ok" : "failed",
                                   r->error,
                                   r->ok ? (r->all_fused ? "yes" : "no") : "",
                                   fused_frames_text(*r),
                                   fusion_events_text(*r),
                                   r->ate.alignment};
      for (const Metric& m : metrics()) row.push_back(report::format_number(m.get(*r), m.decimals == 0 ? 0 : 6));
      t.rows.push_back(row);
    }
    for (int which = 0; which < 3; ++which) {
      const char* stat = which == 0 ? "median" : which == 1 ? "min" : "max";
      std::vector<std::string> row{stat,
                                   s.config->name,
                                   s.config->label,
                                   std::to_string(s.config->clients),
                                   report::format_number(s.config->overlap_percent, 2),
                                   "",
                                   std::to_string(s.ok) + "/" + std::to_string(s.runs.size()) + " ok",
                                   "",
                                   "",
                                   "",
                                   "",
                                   ""};
      for (const Metric& m : metrics()) {
        std::vector<double> v;
        for (const auto* r : s.runs)
          if (r->ok) v.push_back(m.get(*r));
        const report::Spread sp = report::spread(v);
        const double x = sp.n == 0 ? kNaN : which == 0 ? sp.median : which == 1 ? sp.min : sp.max;
        row.push_back(report::format_number(x, m.decimals == 0 ? 0 : 6));
      }
      t.rows.push_back(row);
    }
  }
  report::write_text_atomic(path, report::to_csv(t));
}

void write_json(const std::string& path, const ReportMeta& meta, const std::vector<ConfigSummary>& summaries) {
  nlohmann::json j;
  const ExperimentOptions& o = *meta.options;
  j["title"] = meta.title;
  j["reproduce"] = meta.reproduce;
  j["revision"] = meta.revision;
  j["started"] = meta.started;
  j["finished"] = meta.finished;
  j["total_s"] = meta.total_s;
  j["machine"] = {{"cores", meta.machine.cores},     {"cpu", meta.machine.cpu_model},
                  {"kernel", meta.machine.kernel},   {"memory_gb", meta.machine.memory_gb},
                  {"load_before", meta.load_before}, {"load_after", meta.load_after}};
  j["data"] = meta.data_lines;
  j["options"] = {{"mode", to_string(o.mode)},
                  {"repeat", o.repeat},
                  {"quick", o.quick},
                  {"rate", o.rate},
                  {"timeout_s", o.timeout_s},
                  {"recon_voxel_m", o.recon.voxel},
                  {"recon_stride", o.recon.stride},
                  {"recon_max_depth_m", o.recon.max_depth},
                  {"recon", o.recon.enabled}};
  j["configs"] = nlohmann::json::array();
  j["runs"] = nlohmann::json::array();
  for (const auto& s : summaries) {
    nlohmann::json c = {
        {"config", s.config->name},
        {"label", s.config->label},
        {"clients", s.config->clients},
        {"overlap_percent", number(s.config->overlap_percent)},
        {"runs", s.runs.size()},
        {"ok", s.ok},
        {"slam_time_ratio_to_single", number(s.time_ratio)},
        {"slam_time_ratio_basis",
         std::isfinite(s.time_ratio) ? (s.time_ratio_quiet ? "runs without other load" : "all runs") : ""},
        {"figures", s.figures},
        {"representative_repeat", s.representative ? s.representative->repeat : 0}};
    int fused = 0;
    for (const auto* r : s.runs) fused += r->ok && r->all_fused && r->clients > 1;
    c["fused_runs"] = fused;
    for (const Metric& m : metrics()) {
      std::vector<double> v;
      for (const auto* r : s.runs)
        if (r->ok) v.push_back(m.get(*r));
      const report::Spread sp = report::spread(v);
      c[m.name] = sp.n == 0 ? nlohmann::json(nullptr)
                            : nlohmann::json{{"median", sp.median}, {"min", sp.min}, {"max", sp.max}, {"n", sp.n}};
    }
    j["configs"].push_back(c);
    for (const auto* r : s.runs) j["runs"].push_back(record_json(*r));
  }
  report::write_text_atomic(path, j.dump(2) + "\n");
}

}  // namespace cslam::experiment
