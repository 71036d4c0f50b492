#pragma once
// Aggregation of the runs per configuration (median and min–max over repeats) and the report
// files: report.md (Tables II and III, runs, figures), results.csv and results.json.
#include <string>
#include <vector>

#include "experiment_config.h"
#include "machine_info.h"
#include "run_record.h"

namespace cslam::experiment {

struct ReportMeta {
  std::string title;
  std::vector<std::string> data_lines;  // what the data is (frames, ground truth, scene)
  std::string reproduce;                // the exact command line
  std::string revision, started, finished;
  MachineInfo machine;
  std::string load_before, load_after;
  double total_s = 0;
  const ExperimentOptions* options = nullptr;
  bool has_scene = false;
  std::vector<std::string> overview_figures;  // relative paths
};

struct ConfigSummary {
  const RunConfig* config = nullptr;
  std::vector<const RunRecord*> runs;  // every repeat, in order
  int ok = 0;
  const RunRecord* representative = nullptr;  // the run the figures show (median combined ATE RMSE)
  double time_ratio = kNaN;                   // median SLAM time / the single-client baseline's
  bool time_ratio_quiet = false;              // ... from runs without other load on both sides
  std::vector<std::string> figures;           // relative paths of its SVGs
};

// A run during which other processes took less than kQuietOtherCores cores: its SLAM time is
// not inflated by other work on the machine.
constexpr double kQuietOtherCores = 0.25;
bool is_quiet(const RunRecord& r);

std::vector<ConfigSummary> summarize(const std::vector<RunConfig>& configs, const std::vector<RunRecord>& records);

// A numeric column of the machine-readable results.
struct Metric {
  const char* name;
  int decimals;
  double (*get)(const RunRecord&);
};
const std::vector<Metric>& metrics();

// "1:330;2:12" (client:frame of its first fusion) and "c2@17<->c1@330 0.81s; ..." for one run.
std::string fused_frames_text(const RunRecord& r);
std::string fusion_events_text(const RunRecord& r);

void write_csv(const std::string& path, const std::vector<ConfigSummary>& summaries);
void write_json(const std::string& path, const ReportMeta& meta, const std::vector<ConfigSummary>& summaries);
void write_markdown(const std::string& path, const ReportMeta& meta, const std::vector<ConfigSummary>& summaries);

}  // namespace cslam::experiment
