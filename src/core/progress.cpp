#include "core/progress.h"

#include <cmath>

#include <unistd.h>

namespace cslam {

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  char buf[48];
  const long s = std::lround(seconds);
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%ld s", s);
  else if (s < 3600)
    std::snprintf(buf, sizeof buf, "%ld min %02ld s", s / 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld h %02ld min", s / 3600, (s % 3600) / 60);
  return buf;
}

Progress::Progress(std::string label, std::uint64_t total, std::string unit, ProgressOptions options, std::FILE* out)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      options_(options),
      out_(out),
      terminal_(options.terminal < 0 ? ::isatty(::fileno(out)) != 0 : options.terminal != 0),
      start_(Clock::now()),
      last_print_(start_) {}

Progress::~Progress() {
  if (terminal_ && drawn_ && !finished_) std::fputc('\n', out_);  // leave the cursor on a fresh line
}

std::string Progress::format(const std::string& label, std::uint64_t done, std::uint64_t total, const std::string& unit,
                             double rate, const std::string& extra) {
  char buf[160];
  std::string line = label + " " + std::to_string(done);
  if (total > 0) {
    std::snprintf(buf, sizeof buf, "/%llu %s (%.1f %%)", static_cast<unsigned long long>(total), unit.c_str(),
                  100.0 * double(done) / double(total));
  } else {
    std::snprintf(buf, sizeof buf, " %s", unit.c_str());
  }
  line += buf;
  if (rate > 0 && rate < 1) {
    line += ", " + format_duration(1.0 / rate) + " each";  // slow work (experiment runs): time per unit
  } else {
    std::snprintf(buf, sizeof buf, ", %.1f %s/s", rate, unit.c_str());
    line += buf;
  }
  if (total > 0 && done < total) line += ", ETA " + (rate > 0 ? format_duration(double(total - done) / rate) : "?");
  if (!extra.empty()) line += ", " + extra;
  return line;
}

void Progress::update(std::uint64_t done, const std::string& extra) {
  last_done_ = done;
  const auto now = Clock::now();
  const double since = std::chrono::duration<double>(now - last_print_).count();
  if (since < (terminal_ ? options_.redraw_s : options_.interval_s)) return;
  // Rate over the last interval, smoothed so a terminal line does not flicker.
  const double recent = since > 0 ? double(done - done_at_last_print_) / since : rate_;
  rate_ = drawn_ ? 0.7 * rate_ + 0.3 * recent : recent;
  print(done, rate_, extra, false);
  last_print_ = now;
  done_at_last_print_ = done;
}

void Progress::finish(const std::string& extra) {
  if (finished_) return;
  const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
  const double rate = elapsed > 0 ? double(last_done_) / elapsed : 0.0;
  print(last_done_, rate, extra.empty() ? "done in " + format_duration(elapsed) : extra, true);
  finished_ = true;
}

void Progress::clear() {
  if (terminal_ && drawn_ && !finished_) {
    std::fputs("\r\033[K", out_);
    std::fflush(out_);
  }
}

void Progress::print(std::uint64_t done, double rate, const std::string& extra, bool final_line) {
  const std::string line = format(label_, done, total_, unit_, rate, extra);
  if (terminal_) {
    std::fprintf(out_, "\r\033[K%s%s", line.c_str(), final_line ? "\n" : "");
  } else {
    std::fprintf(out_, "%s\n", line.c_str());
  }
  std::fflush(out_);
  drawn_ = true;
}

}  // namespace cslam
