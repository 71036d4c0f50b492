#include "experiment_runner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "cloud_evaluation.h"
#include "core/error.h"
#include "core/progress.h"
#include "core/stopwatch.h"
#include "machine_info.h"
#include "process.h"
#include "support/report/text_output.h"
#include "report_plots.h"
#include "report_writer.h"
#include "run_evaluation.h"
#include "slam_runner.h"

#ifndef CSLAM_SOURCE_DIR
#define CSLAM_SOURCE_DIR "."
#endif

namespace cslam::experiment {

namespace fs = std::filesystem;

namespace {

struct ResolvedData {
  std::vector<std::string> dirs;
  std::vector<int> frame_counts;
  std::string scene;
  std::vector<std::string> lines;  // for the report
};

void generate_synthetic(const ExperimentOptions& o) {
  const std::string dir = o.synthetic_dir;
  if (fs::exists(dir + "/scene.ply")) return;
  if (fs::exists(dir))
    throw InputError(dir, "exists but holds no scene.ply (not a cslam-synth output); remove it or pick another folder");
  if (fs::path(dir).has_parent_path()) fs::create_directories(fs::path(dir).parent_path());
  fs::create_directories(o.out_dir);
  const std::string log = o.out_dir + "/synth.log";
  std::printf("generating the synthetic scene: cslam-synth --preset %s --out %s\n", o.synth_preset.c_str(),
              dir.c_str());
  std::fflush(stdout);
  ChildProcess synth({o.bin_dir + "/cslam-synth", "--preset", o.synth_preset, "--out", dir, "--log-level", "warn"},
                     log);
  const int r = wait_any({&synth}, Clock::now() + std::chrono::minutes(15));
  if (r != 0) stop_all({&synth}, 2.0);
  if (!synth.succeeded()) throw InputError(dir, "cslam-synth " + synth.status_text() + ": " + log_tail(log, 2));
}

ResolvedData resolve_data(const ExperimentOptions& o, DatasetStore& store) {
  ResolvedData d;
  if (!o.synthetic_dir.empty()) {
    generate_synthetic(o);
    for (const auto& e : fs::directory_iterator(o.synthetic_dir))
      if (e.is_directory() && e.path().filename().string().rfind("robot_", 0) == 0) d.dirs.push_back(e.path().string());
    std::sort(d.dirs.begin(), d.dirs.end());
    if (d.dirs.empty()) throw InputError(o.synthetic_dir, "no robot_K folders (not a cslam-synth multi-robot output)");
    d.scene = o.scene_ply.empty() ? o.synthetic_dir + "/scene.ply" : o.scene_ply;
    d.lines.push_back("Synthetic scene `" + o.synthetic_dir +
                      "` (cslam-synth, exact ground truth), one dataset per client, no split.");
  } else if (!o.datasets.empty()) {
    d.dirs = o.datasets;
    d.scene = o.scene_ply;
    d.lines.push_back("One dataset per client, no split.");
  } else {
    d.dirs = {o.dataset};
    d.scene = o.scene_ply;
    d.lines.push_back(
        "One sequence split into K clients with the paper's ranges (`cslam-eval split`), frames = associated RGB-D "
        "pairs.");
  }
  for (const auto& dir : d.dirs) {
    const TumDataset& ds = store.get(dir);
    if (ds.pairs.size() < 10)
      throw InputError(dir, "only " + std::to_string(ds.pairs.size()) + " associated RGB-D pairs");
    d.frame_counts.push_back(int(ds.pairs.size()));
    char buf[256];
    std::snprintf(buf, sizeof buf, ": %zu associated RGB-D pairs over %.1f s; ", ds.pairs.size(),
                  ds.pairs.back().rgb_time - ds.pairs.front().rgb_time);
    d.lines.push_back("`" + dir + "`" + buf +
                      (ds.groundtruth ? "ground truth: " + std::to_string(ds.groundtruth->size()) + " poses"
                                      : std::string("**no ground truth** (accuracy columns n/a)")));
  }
  if (!d.scene.empty()) d.lines.push_back("Exact surface for reconstruction accuracy: `" + d.scene + "`.");
  return d;
}

std::string ranges_line(const RunConfig& c) {
  std::string s =
      c.label + (std::isfinite(c.overlap_percent) ? " at η = " + overlap_text(c.overlap_percent) + " %" : "") + ": ";
  for (std::size_t i = 0; i < c.specs.size(); ++i)
    s += (i ? ", " : "") + ("c" + std::to_string(c.specs[i].id) + " frames ") + std::to_string(c.specs[i].first) + "–" +
         std::to_string(c.specs[i].last) + (c.split ? "" : " of " + fs::path(c.specs[i].dataset).filename().string());
  return s;
}

std::string progress_line(int index, int total, const RunRecord& r) {
  char buf[512];
  if (!r.ok) {
    std::snprintf(buf, sizeof buf, "[%d/%d] %s r%d: FAILED (%s)", index, total, r.config.c_str(), r.repeat,
                  r.error.c_str());
    return buf;
  }
  std::snprintf(buf, sizeof buf,
                "[%d/%d] %s r%d: SLAM %.2f s (CPU %.1f s), APE RMSE %s m, %s, frames lost %d, Hausdorff(bbox) %s m, "
                "other processes %.2f cores",
                index, total, r.config.c_str(), r.repeat, r.slam_time_s, r.slam_cpu_s,
                report::format_number(r.ate.rmse, 4).c_str(),
                r.clients == 1 ? "single"
                : r.all_fused  ? "fused"
                               : "NOT fused",
                r.frames_lost, report::format_number(r.cloud.hausdorff_bbox, 4).c_str(), r.other_cpu_cores);
  return buf;
}

}  // namespace

int run_experiment(const ExperimentOptions& o) {
  Stopwatch total;
  DatasetStore store;
  fs::create_directories(o.out_dir);
  install_interrupt_handler();
  const ResolvedData data = resolve_data(o, store);
  const std::vector<RunConfig> configs = build_matrix(o, data.dirs, data.frame_counts);

  ReportMeta meta;
  meta.options = &o;
  meta.title = "cslam experiment — " +
               fs::path(o.synthetic_dir.empty() ? data.dirs.front() : o.synthetic_dir).filename().string() + " (" +
               to_string(o.mode) + " mode)";
  meta.data_lines = data.lines;
  for (const auto& c : configs)
    if (c.clients > 1) meta.data_lines.push_back(ranges_line(c));
  meta.reproduce = o.command_line;
  meta.started = utc_now();
  meta.machine = machine_info();
  meta.load_before = load_average_text();
  meta.revision = source_revision(CSLAM_SOURCE_DIR, o.out_dir + "/.git_revision.tmp");
  meta.has_scene = !data.scene.empty();

  const int runs_total = int(configs.size()) * o.repeat;
  std::printf("cslam-experiment: %zu configurations x %d repeat(s) = %d runs, %s mode, report in %s\n", configs.size(),
              o.repeat, runs_total, to_string(o.mode), o.out_dir.c_str());
  std::printf("machine: %d cores, %s, load %s\n", meta.machine.cores, meta.machine.cpu_model.c_str(),
              meta.load_before.c_str());
  std::fflush(stdout);

  CloudEvaluator clouds(o.recon, data.scene, o.camera, o.out_dir + "/runs/gt_clouds");
  std::vector<RunRecord> records;
  records.reserve(std::size_t(runs_total));
  DetailMap details;
  auto write_partial = [&] {
    auto summaries = summarize(configs, records);
    meta.finished = utc_now();
    meta.total_s = total.ms() / 1000.0;
    meta.load_after = load_average_text();
    write_csv(o.out_dir + "/results.csv", summaries);
    write_json(o.out_dir + "/results.json", meta, summaries);
  };
  int index = 0, failed = 0;
  ProgressOptions progress_options;
  progress_options.interval_s = 0;  // runs take minutes: a line after each
  Progress progress("cslam-experiment:", std::uint64_t(runs_total), "runs", progress_options);
  try {
    for (int rep = 1; rep <= o.repeat; ++rep) {
      for (const auto& cfg : configs) {
        RunRecord rec;
        rec.config = cfg.name;
        rec.label = cfg.label;
        rec.clients = cfg.clients;
        rec.overlap_percent = cfg.overlap_percent;
        rec.repeat = rep;
        rec.mode = to_string(o.mode);
        rec.run_dir = o.out_dir + "/runs/" + cfg.name + "/r" + std::to_string(rep);
        fs::remove_all(rec.run_dir);
        fs::create_directories(rec.run_dir);
        rec.load_before = load_average_1min();
        const CpuSample cpu_before = cpu_sample();
        const RunOutcome outcome = run_slam(cfg, o, rec.run_dir);
        const CpuSample cpu_after = cpu_sample();
        rec.slam_cpu_s = own_cpu_seconds(cpu_before, cpu_after);
        rec.other_cpu_cores = other_cpu_cores(cpu_before, cpu_after);
        rec.process_wall_s = outcome.process_wall_s;
        rec.error = outcome.error;
        if (outcome.ok) {
          try {
            RunDetail detail;
            evaluate_run(cfg, o.mode, run_output_dir(rec.run_dir), store, rec, detail);
            rec.ok = true;
            const double rotation_gap = rec.cloud.alignment_rotation_deg;
            rec.cloud = clouds.evaluate(detail, cfg.specs, store, rec.run_dir);
            rec.cloud.alignment_rotation_deg = rotation_gap;
            details[{cfg.name, rep}] = std::move(detail);
          } catch (const std::exception& e) {
            rec.ok = false;
            rec.error = std::string("evaluation: ") + e.what();
          }
        }
        failed += !rec.ok;
        records.push_back(std::move(rec));
        progress.clear();
        std::printf("%s\n", progress_line(++index, runs_total, records.back()).c_str());
        std::fflush(stdout);
        progress.update(std::uint64_t(index), failed ? std::to_string(failed) + " failed" : "");
        write_partial();
        if (interrupt_requested()) throw Interrupted();
      }
    }
  } catch (const Interrupted&) {
    write_partial();
    throw;
  }
  progress.finish();

  auto summaries = summarize(configs, records);
  meta.overview_figures = write_figures(o.out_dir, summaries, details);
  meta.finished = utc_now();
  meta.total_s = total.ms() / 1000.0;
  meta.load_after = load_average_text();
  write_csv(o.out_dir + "/results.csv", summaries);
  write_json(o.out_dir + "/results.json", meta, summaries);
  write_markdown(o.out_dir + "/report.md", meta, summaries);

  std::printf("\n%-22s %6s %22s %8s %24s %8s\n", "configuration", "ok", "SLAM time (s)", "/single", "APE RMSE (m)",
              "fused");
  for (const auto& s : summaries) {
    std::vector<double> t, a;
    int fused = 0;
    for (const auto* r : s.runs) {
      if (!r->ok) continue;
      t.push_back(r->slam_time_s);
      a.push_back(r->ate.rmse);
      fused += r->all_fused;
    }
    std::printf("%-22s %3d/%-2zu %22s %8s %24s %5d/%d\n", s.config->name.c_str(), s.ok, s.runs.size(),
                report::format_spread(report::spread(t), 2).c_str(), report::format_number(s.time_ratio, 2).c_str(),
                report::format_spread(report::spread(a), 4).c_str(), fused, s.ok);
  }
  std::printf("\nreport: %s/report.md (%d of %d runs failed; %.1f min)\nreproduce: %s\n", o.out_dir.c_str(), failed,
              runs_total, total.ms() / 60000.0, o.command_line.c_str());
  return failed;
}

}  // namespace cslam::experiment
