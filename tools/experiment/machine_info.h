#pragma once
// The machine a report was measured on: cores, CPU model, memory, load averages, source revision.
#include <string>

namespace cslam::experiment {

struct MachineInfo {
  int cores = 0;
  std::string cpu_model, kernel;
  double memory_gb = 0;
};
MachineInfo machine_info();

// "/proc/loadavg" as "1.02 0.88 0.61" and the 1-minute value (NaN if unreadable).
std::string load_average_text();
double load_average_1min();

// CPU accounting around a run, to tell the run's own CPU use from other work on the machine:
// the machine's busy CPU time since boot (/proc/stat, all cores) and this process's plus its
// reaped children's CPU time (getrusage), with the wall clock.
struct CpuSample {
  double machine_busy_s = 0, own_s = 0, wall_s = 0;
  bool valid = false;
};
CpuSample cpu_sample();
// Between two samples (children reaped): CPU seconds used by this process and its children,
// and the average number of cores used by everything else.
double own_cpu_seconds(const CpuSample& before, const CpuSample& after);
double other_cpu_cores(const CpuSample& before, const CpuSample& after);

// "abc1234" or "abc1234 + uncommitted changes" of the source tree; "unknown" without git.
// Runs git with its output in log_path.
std::string source_revision(const std::string& source_dir, const std::string& log_path);

// Current UTC time, "2026-11-21 14:03 UTC".
std::string utc_now();

}  // namespace cslam::experiment
