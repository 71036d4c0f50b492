#include "machine_info.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <sys/resource.h>
#include <sys/utsname.h>
#include <unistd.h>

#include "process.h"

namespace cslam::experiment {

MachineInfo machine_info() {
  MachineInfo m;
  m.cores = int(std::thread::hardware_concurrency());
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) m.cpu_model = line.substr(line.find_first_not_of(" \t", colon + 1));
      break;
    }
  }
  std::ifstream mem("/proc/meminfo");
  std::string key;
  double kb = 0;
  if (mem >> key >> kb && key == "MemTotal:") m.memory_gb = kb / 1024.0 / 1024.0;
  utsname u{};
  if (::uname(&u) == 0) m.kernel = std::string(u.sysname) + " " + u.release;
  return m;
}

std::string load_average_text() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "unknown";
  return a + " " + b + " " + c;
}

double load_average_1min() {
  std::ifstream in("/proc/loadavg");
  double v = NAN;
  if (!(in >> v)) return NAN;
  return v;
}

CpuSample cpu_sample() {
  CpuSample c;
  c.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  auto seconds = [](const timeval& t) { return double(t.tv_sec) + double(t.tv_usec) * 1e-6; };
  rusage self{}, children{};
  getrusage(RUSAGE_SELF, &self);
  getrusage(RUSAGE_CHILDREN, &children);
  c.own_s = seconds(self.ru_utime) + seconds(self.ru_stime) + seconds(children.ru_utime) + seconds(children.ru_stime);
  std::ifstream stat("/proc/stat");
  std::string cpu;
  double user = 0, nice = 0, system = 0, idle = 0, iowait = 0, irq = 0, softirq = 0, steal = 0;
  if (stat >> cpu >> user >> nice >> system >> idle >> iowait >> irq >> softirq >> steal && cpu == "cpu") {
    const double hz = double(::sysconf(_SC_CLK_TCK));
    c.machine_busy_s = (user + nice + system + irq + softirq + steal) / hz;  // guest time is inside user
    c.valid = hz > 0;
  }
  return c;
}

double own_cpu_seconds(const CpuSample& before, const CpuSample& after) { return after.own_s - before.own_s; }

double other_cpu_cores(const CpuSample& before, const CpuSample& after) {
  const double wall = after.wall_s - before.wall_s;
  if (!before.valid || !after.valid || wall <= 0) return NAN;
  const double other = (after.machine_busy_s - before.machine_busy_s) - own_cpu_seconds(before, after);
  return std::max(0.0, other / wall);  // clock-tick rounding can make it slightly negative
}

std::string source_revision(const std::string& source_dir, const std::string& log_path) {
  auto git = [&](const std::vector<std::string>& args) -> std::string {
    std::filesystem::remove(log_path);
    std::vector<std::string> argv{"/usr/bin/git", "-C", source_dir};
    argv.insert(argv.end(), args.begin(), args.end());
    try {
      ChildProcess p(argv, log_path);
      if (wait_any({&p}, Clock::now() + std::chrono::seconds(10)) != 0 || !p.succeeded()) return "?";
    } catch (const std::runtime_error&) {
      return "?";
    }
    std::ifstream in(log_path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  std::string rev = git({"rev-parse", "--short", "HEAD"});
  if (rev == "?" || rev.empty()) return "unknown";
  while (!rev.empty() && (rev.back() == '\n' || rev.back() == ' ')) rev.pop_back();
  const std::string dirty = git({"status", "--porcelain", "--untracked-files=no"});
  std::filesystem::remove(log_path);
  if (dirty == "?") return rev;
  return dirty.empty() ? rev : rev + " + uncommitted changes";
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M UTC", &tm);
  return buf;
}

}  // namespace cslam::experiment
