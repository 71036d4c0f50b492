// report.md: Tables II and III as in the paper (medians over repeats with min–max), what the
// expectations of the issue measured, the figures and every run with its error if it failed.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "support/report/text_output.h"
#include "report_writer.h"

namespace cslam::experiment {

namespace {

using report::format_number;
using report::format_spread;
using report::spread;

report::Spread over_ok(const ConfigSummary& s, double (*get)(const RunRecord&)) {
  std::vector<double> v;
  for (const auto* r : s.runs)
    if (r->ok) v.push_back(get(*r));
  return spread(v);
}

std::string eta_cell(const RunConfig& c) {
  return std::isfinite(c.overlap_percent) ? overlap_text(c.overlap_percent) + " %" : "–";
}

std::string runs_cell(const ConfigSummary& s) {
  std::string out = std::to_string(s.ok) + "/" + std::to_string(s.runs.size());
  if (s.ok < int(s.runs.size())) out += " (" + std::to_string(int(s.runs.size()) - s.ok) + " failed)";
  return out;
}

std::string fused_cell(const ConfigSummary& s) {
  if (s.config->clients == 1) return "–";
  int fused = 0;
  for (const auto* r : s.runs) fused += r->ok && r->all_fused;
  const std::string n = " (" + std::to_string(fused) + "/" + std::to_string(s.ok) + ")";
  if (s.ok == 0) return "n/a";
  return (fused == s.ok ? "yes" : fused == 0 ? "**no**" : "**partly**") + n;
}

// Per client: the median frame of its first fusion over the runs where it fused.
std::string fused_at_cell(const ConfigSummary& s) {
  if (s.config->clients == 1) return "–";
  std::string out;
  for (const auto& spec : s.config->specs) {
    std::vector<double> v;
    for (const auto* r : s.runs)
      for (const auto& c : r->client_records)
        if (r->ok && c.id == spec.id && c.fused_at_frame > 0) v.push_back(c.fused_at_frame);
    out += (out.empty() ? "" : ", ") + ("c" + std::to_string(spec.id) + " ") +
           (v.empty() ? "never" : format_spread(spread(v), 0));
  }
  return out;
}

std::string failure_cell(const ConfigSummary& s) {
  for (const auto* r : s.runs)
    if (!r->ok) return "FAILED: " + r->error;
  return "";
}

std::string m(double v) { return format_number(v, 4); }

void table_two(std::ostream& md, const std::vector<ConfigSummary>& summaries) {
  report::Table t;
  t.header = {"simulation",
              "η",
              "runs ok",
              "SLAM time (s)",
              "SLAM time, no other load (s)",
              "CPU (s)",
              "time / single",
              "APE max (m)",
              "APE min (m)",
              "APE mean (m)",
              "APE RMSE (m)",
              "APE std (m)",
              "fused",
              "first fusion (s)",
              "fused at frame",
              "frames lost"};
  t.align = {'l', 'r', 'r', 'r', 'r', 'r', 'r', 'r', 'r', 'r', 'r', 'r', 'l', 'r', 'l', 'r'};
  for (const auto& s : summaries) {
    const RunConfig& c = *s.config;
    if (s.ok == 0) {
      t.rows.push_back({c.label, eta_cell(c), runs_cell(s), failure_cell(s)});
      continue;
    }
    std::vector<double> quiet;
    for (const auto* r : s.runs)
      if (r->ok && is_quiet(*r)) quiet.push_back(r->slam_time_s);
    const std::string quiet_cell = quiet.empty()
                                       ? "none"
                                       : format_spread(spread(quiet), 2) + " (" + std::to_string(quiet.size()) +
                                             " run" + (quiet.size() > 1 ? "s" : "") + ")";
    t.rows.push_back(
        {c.label, eta_cell(c), runs_cell(s),
         format_spread(over_ok(s, [](const RunRecord& r) { return r.slam_time_s; }), 2), quiet_cell,
         format_spread(over_ok(s, [](const RunRecord& r) { return r.slam_cpu_s; }), 1),
         format_number(s.time_ratio, 2) + (std::isfinite(s.time_ratio) && !s.time_ratio_quiet ? " †" : ""),
         format_spread(over_ok(s, [](const RunRecord& r) { return r.ate.max; }), 4),
         format_spread(over_ok(s, [](const RunRecord& r) { return r.ate.min; }), 4),
         format_spread(over_ok(s, [](const RunRecord& r) { return r.ate.mean; }), 4),
         format_spread(over_ok(s, [](const RunRecord& r) { return r.ate.rmse; }), 4),
         format_spread(over_ok(s, [](const RunRecord& r) { return r.ate.std; }), 4), fused_cell(s),
         c.clients == 1 ? "–"
                        : format_spread(over_ok(s,
                                                [](const RunRecord& r) {
                                                  return r.fusions.empty() ? kNaN : r.fusions.front().wall_time_s;
                                                }),
                                        2),
         fused_at_cell(s), format_spread(over_ok(s, [](const RunRecord& r) { return double(r.frames_lost); }), 0)});
  }
  md << report::to_markdown(t);
}

void table_three(std::ostream& md, const std::vector<ConfigSummary>& summaries, bool scene) {
  report::Table t;
  t.header = {"simulation",
              "η",
              "Hausdorff, bbox matched (m)",
              "C2C mean, bbox (m)",
              "C2C median, bbox (m)",
              "bbox scale",
              "Hausdorff, no bbox (m)",
              "C2C mean, no bbox (m)",
              "C2C median, no bbox (m)"};
  if (scene) {
    for (const char* h : {"vs scene.ply: C2C median (m)", "C2C mean (m)", "p95 (m)", "Hausdorff SLAM→scene (m)"})
      t.header.push_back(h);
  }
  bool live = false;
  for (const auto& s : summaries)
    for (const RunRecord* r : s.runs) live = live || r->cloud.live_points > 0;
  if (live)
    for (const char* h : {"live dense map: C2C median, no bbox (m)", "C2C p95, no bbox (m)", "Hausdorff, bbox (m)"})
      t.header.push_back(h);
  t.align.assign(t.header.size(), 'r');
  t.align[0] = 'l';
  for (const auto& s : summaries) {
    const RunConfig& c = *s.config;
    std::vector<std::string> row{c.label, eta_cell(c)};
    auto cell = [&](double (*get)(const RunRecord&), int d) { row.push_back(format_spread(over_ok(s, get), d)); };
    cell([](const RunRecord& r) { return r.cloud.hausdorff_bbox; }, 4);
    cell([](const RunRecord& r) { return r.cloud.c2c_mean_bbox; }, 4);
    cell([](const RunRecord& r) { return r.cloud.c2c_median_bbox; }, 4);
    cell([](const RunRecord& r) { return r.cloud.bbox_scale; }, 3);
    cell([](const RunRecord& r) { return r.cloud.hausdorff; }, 4);
    cell([](const RunRecord& r) { return r.cloud.c2c_mean; }, 4);
    cell([](const RunRecord& r) { return r.cloud.c2c_median; }, 4);
    if (scene) {
      cell([](const RunRecord& r) { return r.cloud.scene_median; }, 4);
      cell([](const RunRecord& r) { return r.cloud.scene_mean; }, 4);
      cell([](const RunRecord& r) { return r.cloud.scene_p95; }, 4);
      cell([](const RunRecord& r) { return r.cloud.scene_max; }, 4);
    }
    if (live) {
      cell([](const RunRecord& r) { return r.cloud.live_c2c_median; }, 4);
      cell([](const RunRecord& r) { return r.cloud.live_c2c_p95; }, 4);
      cell([](const RunRecord& r) { return r.cloud.live_hausdorff_bbox; }, 4);
    }
    t.rows.push_back(row);
  }
  md << report::to_markdown(t);
}

// The accuracy the clients reach alone: the single run of the whole sequence (split), or the
// single runs of the same datasets pooled over their poses, sqrt(sum n_i rmse_i^2 / sum n_i),
// each in its own alignment (one dataset per client).
double single_baseline_rmse(const std::vector<ConfigSummary>& summaries, const ConfigSummary& collab) {
  double sum_sq = 0, n = 0;
  for (const auto& s : summaries) {
    if (s.config->clients != 1) continue;
    const bool relevant =
        s.config->split || std::any_of(collab.config->specs.begin(), collab.config->specs.end(),
                                       [&](const ClientSpec& c) { return c.dataset == s.config->specs.at(0).dataset; });
    if (!relevant) continue;
    const auto rmse = over_ok(s, [](const RunRecord& r) { return r.ate.rmse; });
    const auto count = over_ok(s, [](const RunRecord& r) { return r.ate.n > 0 ? double(r.ate.n) : kNaN; });
    if (rmse.n == 0 || count.n == 0) return kNaN;
    sum_sq += count.median * rmse.median * rmse.median;
    n += count.median;
  }
  return n > 0 ? std::sqrt(sum_sq / n) : kNaN;
}

void expectations(std::ostream& md, const std::vector<ConfigSummary>& summaries) {
  const bool split = !summaries.empty() && summaries.front().config->split;
  std::vector<double> ratios;
  std::vector<std::string> not_fused;
  bool loaded = false;
  for (const auto& s : summaries) {
    if (s.config->clients < 2) continue;
    if (std::isfinite(s.time_ratio)) ratios.push_back(s.time_ratio);
    loaded = loaded || (std::isfinite(s.time_ratio) && !s.time_ratio_quiet);
    int fused = 0;
    for (const auto* r : s.runs) fused += r->ok && r->all_fused;
    if (fused < int(s.runs.size()))
      not_fused.push_back(
          s.config->label + (std::isfinite(s.config->overlap_percent) ? " η " + eta_cell(*s.config) : "") + " (" +
          std::to_string(int(s.runs.size()) - fused) + " of " + std::to_string(s.runs.size()) + " runs)");
  }
  const report::Spread r = spread(ratios);
  md << "- **SLAM time, collaborative / single** (time / single in Table II): ";
  if (r.n == 0)
    md << "n/a (no successful single-client baseline or collaborative run).\n";
  else
    md << "median over configurations " << format_number(r.median, 2) << " (" << format_number(r.min, 2) << "–"
       << format_number(r.max, 2) << "); "
       << (r.max < 1   ? "every collaborative configuration"
           : r.min < 1 ? "some collaborative configurations"
                       : "no collaborative configuration")
       << " finished faster than "
       << (split ? "the single-client run" : "the single runs of its datasets one after the other")
       << " on this machine"
       << (loaded ? " — **measured with other work on the machine** (ratios marked †), so this is indicative only; CPU "
                    "seconds in Table II do not depend on the load"
                  : "")
       << ".\n";
  int better_or_equal = 0, total = 0;
  std::string pairs;
  for (const auto& s : summaries) {
    if (s.config->clients < 2) continue;
    const auto a = over_ok(s, [](const RunRecord& x) { return x.ate.rmse; });
    const double base = single_baseline_rmse(summaries, s);
    if (a.n == 0 || !std::isfinite(base)) continue;
    ++total;
    better_or_equal += a.median <= base;
    pairs += (pairs.empty() ? "" : "; ") + s.config->label +
             (std::isfinite(s.config->overlap_percent) ? " η " + eta_cell(*s.config) : "") + " " + m(a.median) +
             " vs " + m(base);
  }
  if (total > 0)
    md << "- **Combined APE RMSE vs single-client** (median, metres; single: "
       << (split ? "the whole sequence by one client"
                 : "the same datasets run alone, pooled over their poses, each aligned on its own")
       << "): " << better_or_equal << " of " << total << " collaborative configurations are at or below it — " << pairs
       << ". See the min–max ranges in Table II for the noise.\n";
  md << "- **Fusion**: "
     << (not_fused.empty() ? std::string("every collaborative run fused all its clients into one group.")
                           : "not every client fused in: ")
     << "";
  for (std::size_t i = 0; i < not_fused.size(); ++i) md << (i ? "; " : "") << not_fused[i];
  md << (not_fused.empty() ? "\n"
                           : ". Their APE is then computed with one alignment per group (marked in results.csv).\n");
}

}  // namespace

void write_markdown(const std::string& path, const ReportMeta& meta, const std::vector<ConfigSummary>& summaries) {
  const ExperimentOptions& o = *meta.options;
  std::ostringstream md;
  md << "# " << meta.title << "\n\n";
  for (const auto& l : meta.data_lines) md << "- " << l << "\n";
  md << "\n**Reproduce** (revision " << meta.revision << "):\n\n```sh\n" << meta.reproduce << "\n```\n\n";
  md << "- Mode: **" << to_string(o.mode) << "**"
     << (o.mode == RunMode::kLive
             ? std::string(" — cslam-server and one cslam-client process per client over loopback, "
                           "streaming live (--live --preload: the dataset's clock, stale frames skipped)")
         : o.mode == RunMode::kNetwork
             ? " — cslam-server and one cslam-client process per client over loopback, --rate " + o.rate
             : " — cslam-slam in-process (one feeder thread per client)")
     << "; " << o.repeat
     << " repeat(s), run in rounds (every configuration once, then again) so that load changes spread "
     << "over all configurations" << (o.quick ? "; **--quick** (reduced matrix and reconstruction)" : "") << ".\n";
  md << "- Machine: " << meta.machine.cores << " cores, " << meta.machine.cpu_model << ", "
     << format_number(meta.machine.memory_gb, 1) << " GB, " << meta.machine.kernel
     << ". Load average (1/5/15 min) before: " << meta.load_before << ", after: " << meta.load_after << ".";
  std::vector<double> others;
  for (const auto& s : summaries)
    for (const auto* r : s.runs) others.push_back(r->other_cpu_cores);
  const auto os = spread(others);
  if (os.n)
    md << " CPU used by other processes while the SLAM ran (machine busy time minus the runs' own): "
       << format_spread(os, 2) << " cores (median, min–max over runs).";
  if (os.n && os.max > 0.25)
    md << " **Other work shared these cores during some runs**, so their times are pessimistic; compare the CPU "
          "seconds "
          "(All runs) and the `other_cpu_cores` column of results.csv.";
  md << "\n- Started " << meta.started << ", finished " << meta.finished << " ("
     << format_number(meta.total_s / 60.0, 1) << " min in total, including reconstruction and evaluation).\n";
  md << "- Reconstruction for Table III: voxel " << format_number(o.recon.voxel, 3) << " m, pixel stride "
     << o.recon.stride << " (every " << o.recon.stride << "th pixel in u and v), depth ≤ "
     << format_number(o.recon.max_depth, 1) << " m" << (o.recon.enabled ? "" : " (**off**)") << ".\n\n";
  md << "Definitions (details: `docs/experiments.md`): **SLAM time** = "
     << (o.mode != RunMode::kOffline
             ? "the server's wall time from listening (clients start right after) until every received "
               "frame is processed (`network_stats.json` `wall_s`)"
             : "cslam-slam's wall time from the first frame submitted until every frame is processed "
               "(`wall_time_s` / `slam_time_s`)")
     << "; **APE** = translation error after ONE SE3 alignment of all clients' poses together (the combined "
        "trajectory); "
     << "**fused at frame** = the frame (1-based, within the client's own frames) of the client's keyframe in the "
        "fusion "
     << "that first joined it to another client; **frames lost** = frames tracking failed on, summed over clients; "
     << "**Hausdorff** = symmetric Hausdorff distance between the cloud from SLAM poses (moved into the ground-truth "
        "frame "
     << "by one rigid transform per group fitted to camera positions and orientations) and the cloud from ground-truth "
     << "poses of the same frames, after the paper's bounding-box matching (centres + diagonal scale); C2C = "
     << "nearest-neighbour distances SLAM cloud → ground-truth cloud; **time / single** = median SLAM time over the "
     << "single-client baseline's"
     << (summaries.empty() || summaries.front().config->split
             ? ""
             : " (here the sum of the single runs of every dataset: one robot covering every path)")
     << ".\n\n";

  md << "## Table II — SLAM time and accuracy\n\nMedian over successful runs, (min–max) when they differ. "
     << "\"No other load\": runs during which other processes took less than " << format_number(kQuietOtherCores, 2)
     << " cores; time / single uses those runs when the configuration and the baseline both have some (else all runs, "
        "marked †). CPU = CPU seconds of all the run's processes.\n\n";
  table_two(md, summaries);
  bool any_failed = false;
  for (const auto& s : summaries)
    for (const auto* r : s.runs) any_failed = any_failed || !r->ok;
  if (any_failed) {
    md << "\n**Failed runs:**\n\n";
    for (const auto& s : summaries)
      for (const auto* r : s.runs)
        if (!r->ok)
          md << "- " << r->label << " " << eta_cell(*s.config) << ", repeat " << r->repeat << ": " << r->error << "\n";
  }
  md << "\n## Table III — reconstruction accuracy\n\n";
  table_three(md, summaries, meta.has_scene);
  std::vector<std::string> notes;
  for (const auto& s : summaries)
    for (const auto* r : s.runs)
      if (r->ok && !r->cloud.computed && !r->cloud.note.empty() &&
          std::find(notes.begin(), notes.end(), r->cloud.note) == notes.end())
        notes.push_back(r->cloud.note);
  for (const auto& n : notes) md << "\nn/a: " << n << "\n";

  md << "\n## Expectations of the issue, as measured\n\n";
  expectations(md, summaries);

  md << "\n## Figures\n\n";
  for (const auto& f : meta.overview_figures) md << "![overview](" << f << ")\n\n";
  for (const auto& s : summaries) {
    if (s.figures.empty()) continue;
    md << "### " << s.config->label << (std::isfinite(s.config->overlap_percent) ? ", η = " + eta_cell(*s.config) : "")
       << " (repeat " << s.representative->repeat << ", the median-APE run)\n\n";
    md << "![APE over time](" << s.figures[0] << ")\n\n";
    for (std::size_t i = 1; i < s.figures.size(); ++i)
      md << (i > 1 ? " · " : "") << "[" << (i == 1 ? "X-Y trajectories" : "x/y/z and rotation over time") << "]("
         << s.figures[i] << ")";
    md << "\n\n";
  }

  md << "## All runs\n\n";
  report::Table t;
  t.header = {"simulation",
              "η",
              "repeat",
              "status",
              "SLAM time (s)",
              "CPU (s)",
              "other processes (cores)",
              "APE RMSE (m)",
              "fused",
              "fusion events (query c@frame ↔ candidate c@frame, time)",
              "Hausdorff bbox (m)",
              "error"};
  for (const auto& s : summaries)
    for (const auto* r : s.runs)
      t.rows.push_back({r->label, eta_cell(*s.config), std::to_string(r->repeat), r->ok ? "ok" : "**failed**",
                        format_number(r->slam_time_s, 2), format_number(r->slam_cpu_s, 1),
                        format_number(r->other_cpu_cores, 2), m(r->ate.rmse),
                        r->ok ? (r->clients == 1 ? "–"
                                 : r->all_fused  ? "yes"
                                                 : "no")
                              : "",
                        fusion_events_text(*r), m(r->cloud.hausdorff_bbox), r->error.empty() ? r->ate.note : r->error});
  md << report::to_markdown(t);
  md << "\nMachine-readable: [results.csv](results.csv) (one row per run, then median/min/max rows per configuration), "
        "[results.json](results.json). Logs and outputs of every run: `runs/<configuration>/r<repeat>/`.\n";
  report::write_text_atomic(path, md.str());
}

}  // namespace cslam::experiment
