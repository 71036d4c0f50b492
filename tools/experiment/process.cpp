#include "process.h"

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace cslam::experiment {

namespace {

// Self-pipe written by the signal handler, polled by wait_any().
int g_interrupt_pipe[2] = {-1, -1};
volatile std::sig_atomic_t g_interrupted = 0;

extern "C" void on_interrupt(int sig) {
  g_interrupted = 1;
  if (g_interrupt_pipe[1] >= 0) {
    const char c = 1;
    [[maybe_unused]] const ssize_t n = ::write(g_interrupt_pipe[1], &c, 1);
  }
  std::signal(sig, SIG_DFL);  // a second Ctrl-C ends the harness at once
}

int open_pidfd(pid_t pid) {
#ifdef SYS_pidfd_open
  const long fd = ::syscall(SYS_pidfd_open, pid, 0);
  if (fd >= 0) {
    ::fcntl(int(fd), F_SETFD, FD_CLOEXEC);
    return int(fd);
  }
#endif
  return -1;
}

}  // namespace

ChildProcess::ChildProcess(const std::vector<std::string>& argv, const std::string& log_path)
    : name_(argv.empty() ? std::string() : std::filesystem::path(argv[0]).filename().string()), log_path_(log_path) {
  if (argv.empty()) throw std::invalid_argument("ChildProcess: empty argv");
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  const int rc = posix_spawn(&pid_, argv[0].c_str(), &actions, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (rc != 0)
    throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc) + " (log " + log_path + ")");
  running_ = true;
  pidfd_ = open_pidfd(pid_);
}

ChildProcess::~ChildProcess() {
  kill_and_reap();
  if (pidfd_ >= 0) ::close(pidfd_);
}

void ChildProcess::kill_and_reap() {
  if (!running_) return;
  ::kill(pid_, SIGKILL);
  int status = 0;
  pid_t r;
  do r = ::waitpid(pid_, &status, 0);
  while (r < 0 && errno == EINTR);
  record(r, status);
}

void ChildProcess::record(pid_t waited, int status) {
  running_ = false;
  if (waited < 0) return;  // not our child any more (should not happen): reported as lost
  if (WIFEXITED(status)) {
    exited_ = true;
    exit_code_ = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    signal_ = WTERMSIG(status);
  }
}

bool ChildProcess::poll_exit() {
  if (!running_) return true;
  int status = 0;
  pid_t r;
  do r = ::waitpid(pid_, &status, WNOHANG);
  while (r < 0 && errno == EINTR);
  if (r == 0) return false;
  record(r, status);
  return true;
}

void ChildProcess::send_signal(int sig) const {
  if (running_) ::kill(pid_, sig);
}

std::string ChildProcess::status_text() const {
  if (running_) return "running";
  if (exited_) return "exit code " + std::to_string(exit_code_);
  if (signal_) return "killed by signal " + std::to_string(signal_) + " (" + strsignal(signal_) + ")";
  return "lost (not reapable)";
}

int wait_any(const std::vector<ChildProcess*>& children, Clock::time_point deadline) {
  for (;;) {
    if (g_interrupted) throw Interrupted();
    bool any_running = false, all_have_fd = true;
    for (std::size_t i = 0; i < children.size(); ++i) {
      if (!children[i]->running()) continue;
      if (children[i]->poll_exit()) return int(i);
      any_running = true;
      all_have_fd = all_have_fd && children[i]->exit_fd() >= 0;
    }
    if (!any_running) return -1;
    const auto now = Clock::now();
    if (now >= deadline) return -1;
    const auto left_ms = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count() + 1;
    if (all_have_fd) {
      // pidfds: sleep in poll() until a child exits, the deadline, or the interrupt pipe.
      std::vector<pollfd> fds;
      for (auto* c : children)
        if (c->running()) fds.push_back({c->exit_fd(), POLLIN, 0});
      if (g_interrupt_pipe[0] >= 0) fds.push_back({g_interrupt_pipe[0], POLLIN, 0});
      ::poll(fds.data(), nfds_t(fds.size()), int(std::min<long long>(left_ms, 60000)));
    } else {
      // No pidfd on this kernel: there is no portable "wait for any of these children with a
      // timeout" primitive, so re-check with waitpid(WNOHANG) every 10 ms until the deadline.
      std::this_thread::sleep_for(std::chrono::milliseconds(std::min<long long>(left_ms, 10)));
    }
  }
}

void stop_all(const std::vector<ChildProcess*>& children, double grace_s) {
  for (auto* c : children) c->send_signal(SIGTERM);
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(grace_s));
  for (;;) {
    bool any = false;
    for (auto* c : children) any = any || !c->poll_exit();
    if (!any) return;
    int r;
    try {
      r = wait_any(children, deadline);
    } catch (const Interrupted&) {
      r = -1;  // interrupted while stopping: go straight to SIGKILL
    }
    if (r < 0) break;
  }
  for (auto* c : children)
    if (!c->poll_exit()) c->kill_and_reap();
}

void install_interrupt_handler() {
  if (g_interrupt_pipe[0] < 0 && ::pipe2(g_interrupt_pipe, O_CLOEXEC | O_NONBLOCK) != 0) {
    g_interrupt_pipe[0] = g_interrupt_pipe[1] = -1;
  }
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool interrupt_requested() { return g_interrupted != 0; }

std::string log_tail(const std::string& path, int max_lines) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    lines.push_back(line);
    if (int(lines.size()) > max_lines) lines.erase(lines.begin());
  }
  std::string out;
  for (const auto& l : lines) out += (out.empty() ? "" : " | ") + l;
  return out;
}

}  // namespace cslam::experiment
