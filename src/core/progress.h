#pragma once
// Progress of long work (frames sent, frames fused, runs done), shared by every cslam program.
// On a terminal the line is redrawn in place ("\r", at most 5 times a second) with done/total,
// percent, rate and ETA; otherwise (a log file, a pipe) a plain line is printed every
// `interval_s` seconds and once at the end, so logs stay readable.
//   Progress progress("client 1: sent", pairs.size(), "frames");
//   for (...) { ...; progress.update(i + 1, "94.3 KB/frame"); }
//   progress.finish();
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

namespace cslam {

struct ProgressOptions {
  double interval_s = 2.0;  // between plain lines (not a terminal)
  double redraw_s = 0.2;    // between redraws on a terminal
  int terminal = -1;        // 1: redraw in place, 0: plain lines, -1: isatty(out)
};

class Progress {
 public:
  // total 0: unknown (no percent, no ETA). Writes to `out` (default stderr).
  Progress(std::string label, std::uint64_t total, std::string unit, ProgressOptions options = {},
           std::FILE* out = stderr);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // Reports `done` units so far; prints if a line is due. `extra` is appended to the line.
  void update(std::uint64_t done, const std::string& extra = "");
  // Prints the final line (with the mean rate over the whole run) and ends a terminal line.
  void finish(const std::string& extra = "");
  // On a terminal, erases the drawn line so other output can be printed; the next update redraws.
  void clear();
  bool terminal() const { return terminal_; }

  // One line: "LABEL 120/600 frames (20.0 %), 29.8 frames/s, ETA 16 s, EXTRA"; a rate below one
  // unit per second is shown as time per unit ("2 min 05 s each").
  static std::string format(const std::string& label, std::uint64_t done, std::uint64_t total, const std::string& unit,
                            double rate, const std::string& extra);

 private:
  using Clock = std::chrono::steady_clock;
  void print(std::uint64_t done, double rate, const std::string& extra, bool final_line);

  std::string label_, unit_;
  std::uint64_t total_;
  ProgressOptions options_;
  std::FILE* out_;
  bool terminal_, finished_ = false, drawn_ = false;
  Clock::time_point start_, last_print_;
  std::uint64_t done_at_last_print_ = 0, last_done_ = 0;
  double rate_ = 0;  // smoothed units/s
};

// "42 s", "3 min 05 s", "1 h 02 min".
std::string format_duration(double seconds);

}  // namespace cslam
