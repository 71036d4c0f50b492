#pragma once
// Child processes of the experiment harness: started with posix_spawn (stdin from /dev/null,
// stdout and stderr into one log file), waited for with a deadline, stopped with SIGTERM then
// SIGKILL. Never detached: a child still running when its object goes away is killed and reaped.
#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <sys/types.h>

namespace cslam::experiment {

using Clock = std::chrono::steady_clock;

class ChildProcess {
 public:
  // argv[0] is the program's path. Throws std::runtime_error naming the program and the log if
  // it cannot be started.
  ChildProcess(const std::vector<std::string>& argv, const std::string& log_path);
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  const std::string& name() const { return name_; }  // program file name
  const std::string& log_path() const { return log_path_; }
  pid_t pid() const { return pid_; }
  bool running() const { return running_; }
  // Reaps the child if it has exited (non-blocking); returns true once it is no longer running.
  bool poll_exit();
  // A descriptor that becomes readable when the child exits (Linux pidfd), or -1 if unavailable.
  int exit_fd() const { return pidfd_; }
  void send_signal(int sig) const;
  // SIGKILL and a blocking reap (no-op if it already exited).
  void kill_and_reap();

  bool succeeded() const { return !running_ && exited_ && exit_code_ == 0; }
  // "exit code 1", "killed by signal 9 (Killed)", "running".
  std::string status_text() const;

 private:
  void record(pid_t waited, int status);

  std::string name_, log_path_;
  pid_t pid_ = -1;
  int pidfd_ = -1;
  bool running_ = false, exited_ = false;
  int exit_code_ = -1, signal_ = 0;
};

// Blocks until one of the running children exits (it is reaped and its index returned), the
// deadline passes (returns -1) or the harness is interrupted (throws Interrupted).
int wait_any(const std::vector<ChildProcess*>& children, Clock::time_point deadline);

// SIGTERM to every running child, up to grace_s for them to exit, then SIGKILL; all reaped.
void stop_all(const std::vector<ChildProcess*>& children, double grace_s);

// SIGINT/SIGTERM to the harness: wait_any() throws Interrupted, so the caller stops its
// children and exits; the signal's default action is restored for a second Ctrl-C.
struct Interrupted : std::runtime_error {
  Interrupted() : std::runtime_error("interrupted") {}
};
void install_interrupt_handler();
bool interrupt_requested();

// Last lines of a log file (for one-line error messages).
std::string log_tail(const std::string& path, int max_lines = 3);

}  // namespace cslam::experiment
