#include "slam_runner.h"

#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "process.h"

namespace cslam::experiment {

namespace fs = std::filesystem;

namespace {

// A value as the shortest text that reads back to the same double (std::to_string keeps six
// decimals: a budget below 1e-6 MB/s would reach the client as 0, none).
std::string round_trip_text(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

Clock::time_point deadline_after(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::string fraction_text(double percent) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", percent / 100.0);
  return buf;
}

std::string describe_failure(const ChildProcess& c, const std::string& role) {
  std::string s = role + " (" + c.name() + ") " + c.status_text();
  const std::string tail = log_tail(c.log_path(), 2);
  if (!tail.empty()) s += ": " + tail;
  return s;
}

// Waits for every child; a failing child or the deadline stops the others. Returns "" on success.
std::string wait_for_all(const std::vector<ChildProcess*>& children, const std::vector<std::string>& roles,
                         Clock::time_point deadline, double timeout_s) {
  try {
    for (;;) {
      bool any_running = false;
      for (auto* c : children) any_running = any_running || c->running();
      if (!any_running) return "";
      const int i = wait_any(children, deadline);
      if (i < 0) {
        std::string who;
        for (std::size_t k = 0; k < children.size(); ++k)
          if (children[k]->running()) who += (who.empty() ? "" : ", ") + roles[k];
        stop_all(children, 5.0);
        return "timeout after " + std::to_string(int(timeout_s)) + " s (still running: " + who + ")";
      }
      const auto& done = *children[std::size_t(i)];
      if (!done.succeeded()) {
        const std::string what = describe_failure(done, roles[std::size_t(i)]);
        stop_all(children, 5.0);
        return what;
      }
      // The server exits (--exit-when-done) only after every client said goodbye; a client may
      // still be closing its socket then (slow on a busy machine): it gets a grace period to
      // exit on its own, and only a client still running after it is a failure.
      if (roles[std::size_t(i)] == "server") {
        const auto grace = Clock::now() + std::chrono::seconds(20);
        for (std::size_t k = 0; k < children.size(); ++k) {
          auto* c = children[k];
          if (!c->running()) continue;
          if (wait_any({c}, std::min(deadline, grace)) < 0 && c->running()) {
            stop_all(children, 5.0);
            return "the server exited (" + done.status_text() + ") while " + c->name() +
                   " was still running 20 s later";
          }
          if (!c->succeeded()) {
            const std::string what = describe_failure(*c, roles[k]);
            stop_all(children, 5.0);
            return what;
          }
        }
      }
    }
  } catch (const Interrupted&) {
    stop_all(children, 2.0);
    throw;
  }
}

RunOutcome run_offline(const RunConfig& cfg, const ExperimentOptions& opt, const std::string& dir) {
  const std::string out = run_output_dir(dir);
  std::vector<std::string> argv{opt.bin_dir + "/cslam-slam"};
  if (cfg.clients == 1) {
    const ClientSpec& s = cfg.specs.at(0);
    argv.insert(argv.end(),
                {"--dataset", s.dataset, "--range", std::to_string(s.first) + ":" + std::to_string(s.last), "--out",
                 out + "/traj.txt", "--keyframes", out + "/keyframes.txt", "--stats", out + "/stats.json", "--quiet"});
  } else if (cfg.split) {
    argv.insert(argv.end(), {"--dataset", cfg.specs.at(0).dataset, "--clients", std::to_string(cfg.clients),
                             "--overlap", fraction_text(cfg.overlap_percent), "--out-dir", out});
  } else {
    argv.push_back("--datasets");
    for (const auto& s : cfg.specs) argv.push_back(s.dataset);
    argv.insert(argv.end(), {"--out-dir", out});
  }
  if (!opt.camera.empty()) argv.insert(argv.end(), {"--camera", opt.camera});
  argv.insert(argv.end(), {"--log-level", "warn"});
  RunOutcome r;
  const auto start = Clock::now();
  try {
    ChildProcess slam(argv, dir + "/slam.log");
    r.error = wait_for_all({&slam}, {"cslam-slam"}, deadline_after(opt.timeout_s), opt.timeout_s);
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  r.process_wall_s = seconds_since(start);
  r.ok = r.error.empty();
  return r;
}

RunOutcome run_network(const RunConfig& cfg, const ExperimentOptions& opt, const std::string& dir) {
  const std::string out = run_output_dir(dir);
  const std::string endpoint_file = dir + "/endpoint";
  fs::remove(endpoint_file);
  RunOutcome r;
  const auto start = Clock::now();
  const auto deadline = deadline_after(opt.timeout_s);
  std::vector<std::unique_ptr<ChildProcess>> owned;
  std::vector<ChildProcess*> children;
  std::vector<std::string> roles;
  try {
    owned.push_back(std::make_unique<ChildProcess>(
        std::vector<std::string>{opt.bin_dir + "/cslam-server", "--bind", "tcp://127.0.0.1:*", "--endpoint-file",
                                 endpoint_file, "--clients", std::to_string(cfg.clients), "--exit-when-done", "--http",
                                 "off", "--out-dir", out, "--log-interval", "10"},
        dir + "/server.log"));
    children.push_back(owned.back().get());
    roles.push_back("server");
    // The server writes the endpoint file (temp + rename) once it listens. Checked between 20 ms
    // waits on the server process itself, so a server that dies at start-up is noticed at once.
    std::string endpoint;
    while (endpoint.empty()) {
      if (wait_any(children, std::min(deadline, deadline_after(0.02))) == 0) {
        r.error = describe_failure(*children[0], "server") + " before listening";
        break;
      }
      std::ifstream(endpoint_file) >> endpoint;
      if (endpoint.empty() && Clock::now() >= deadline) {
        stop_all(children, 5.0);
        r.error = "timeout: the server did not write " + endpoint_file;
        break;
      }
    }
    if (r.error.empty()) {
      for (const auto& s : cfg.specs) {
        std::vector<std::string> argv{opt.bin_dir + "/cslam-client",
                                      "--server",
                                      endpoint,
                                      "--id",
                                      std::to_string(s.id),
                                      "--name",
                                      "client" + std::to_string(s.id),
                                      "--dataset",
                                      s.dataset,
                                      "--range",
                                      std::to_string(s.first) + ":" + std::to_string(s.last),
                                      "--progress-interval",
                                      "10"};
        if (opt.mode == RunMode::kLive) argv.push_back("--live");
        // A lean stream encodes each frame when it leaves, so it cannot be preloaded.
        if (opt.mode == RunMode::kLive && opt.depth_every == 1) argv.push_back("--preload");
        if (opt.mode != RunMode::kLive) argv.insert(argv.end(), {"--rate", opt.rate});
        if (opt.depth_every > 1) argv.insert(argv.end(), {"--depth-every", std::to_string(opt.depth_every)});
        if (opt.byte_budget_mb > 0) argv.insert(argv.end(), {"--byte-budget", round_trip_text(opt.byte_budget_mb)});
        argv.insert(argv.end(), {"--summary-out", dir + "/client_" + std::to_string(s.id) + "_summary.json"});
        if (!opt.camera.empty()) argv.insert(argv.end(), {"--camera", opt.camera});
        owned.push_back(std::make_unique<ChildProcess>(argv, dir + "/client_" + std::to_string(s.id) + ".log"));
        children.push_back(owned.back().get());
        roles.push_back("client " + std::to_string(s.id));
      }
      r.error = wait_for_all(children, roles, deadline, opt.timeout_s);
    }
  } catch (const Interrupted&) {
    stop_all(children, 2.0);
    throw;
  } catch (const std::exception& e) {  // a program that cannot be started
    stop_all(children, 5.0);
    r.error = e.what();
  }
  r.process_wall_s = seconds_since(start);
  r.ok = r.error.empty();
  return r;
}

}  // namespace

std::string run_output_dir(const std::string& run_dir) { return run_dir + "/out"; }

RunOutcome run_slam(const RunConfig& config, const ExperimentOptions& options, const std::string& run_dir) {
  fs::create_directories(run_output_dir(run_dir));
  return options.mode == RunMode::kOffline ? run_offline(config, options, run_dir)
                                           : run_network(config, options, run_dir);
}

}  // namespace cslam::experiment
