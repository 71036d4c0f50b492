// cslam-server: receives RGB-D frames from client robots over ZeroMQ (protobuf messages, see
// proto/cslam.proto and docs/network.md) and runs one SLAM pipeline per client.
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <zmq.hpp>

#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "server/http/http_server.h"
#include "server/receiver.h"
#include "system/collaborative_system.h"

namespace {

// The one piece of global state: where the signal handler writes (async-signal-safe).
cslam::server::WakePipe* g_stop_pipe = nullptr;

extern "C" void on_signal(int) {
  if (g_stop_pipe) g_stop_pipe->notify();
}

void install_signal_handlers(cslam::server::WakePipe* pipe) {
  g_stop_pipe = pipe;
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-server", "Receives RGB-D frames from cslam clients over ZeroMQ and runs collaborative SLAM.");
  cli.option("bind", "ZeroMQ endpoint to bind (tcp://127.0.0.1:* picks a free port)", "tcp://*:5555")
      .option("clients", "number of clients to wait for before --exit-when-done can end the run", "1")
      .flag("exit-when-done", "exit once --clients clients said goodbye and no other client is still active")
      .option("out-dir", "folder for client_K.txt trajectories, stats.json and network_stats.json", "cslam-out")
      .flag("no-slam", "do not run SLAM (count frames only; for throughput benchmarks)")
      .option("window", "flow-control window: frames in flight per client", "4")
      .option("queue-capacity", "frames queued per client before the SLAM worker (>= window)", "8")
      .option("max-msg-bytes", "largest accepted message (ZMQ_MAXMSGSIZE); larger ones drop the connection", "16777216")
      .option("heartbeat-timeout", "seconds of silence before a client is marked disconnected", "5")
      .option("log-interval", "seconds between progress lines", "5")
      .option("endpoint-file", "write the bound endpoint to this file once listening", "")
      .option("log-level", "trace, debug, info, warn, error, off", "info");
  cslam::http::declare_options(cli);
  if (!cli.parse(argc, argv)) return 0;
  cslam::set_log_level(cli.get("log-level"));

  cslam::server::ReceiverConfig rc;
  rc.bind = cli.get("bind");
  rc.window = std::uint32_t(cli.get_int("window"));
  rc.max_message_bytes = std::stoll(cli.get("max-msg-bytes"));
  rc.heartbeat_timeout_s = cli.get_double("heartbeat-timeout");
  rc.log_interval_s = cli.get_double("log-interval");
  rc.expected_clients = std::size_t(std::max(1, cli.get_int("clients")));
  rc.exit_when_done = cli.flag_set("exit-when-done");
  const int capacity = cli.get_int("queue-capacity");
  if (rc.window < 1 || capacity < int(rc.window))
    throw cslam::ConfigError("cslam-server: need 1 <= --window <= --queue-capacity (submit must never block)");
  if (rc.max_message_bytes < 1024) throw cslam::ConfigError("cslam-server: --max-msg-bytes must be at least 1024");
  if (rc.heartbeat_timeout_s <= 0 || rc.log_interval_s <= 0)
    throw cslam::ConfigError("cslam-server: --heartbeat-timeout and --log-interval must be positive");
  const std::string out_dir = cli.get("out-dir");

  // Declaration order is destruction order in reverse: the system (and its workers) stops before
  // the done channel they report to, the sockets close before their context.
  cslam::server::WakePipe stop;
  cslam::server::DoneChannel done;
  cslam::SystemConfig sc;
  sc.client_queue_capacity = std::size_t(capacity);
  sc.run_slam = !cli.flag_set("no-slam");
  sc.on_frame_done = [&done](const cslam::FrameDone& d) { done.push(d); };
  cslam::CollaborativeSystem system(sc);
  zmq::context_t context(1);
  cslam::server::Receiver receiver(context, rc, system, done, stop);
  cslam::http::HttpServer http(system, cslam::http::config_from(cli));  // reads snapshots only
  http.start();
  install_signal_handlers(&stop);
  if (cli.has("endpoint-file")) {
    const std::string path = cli.get("endpoint-file"), tmp = path + ".tmp";
    std::ofstream(tmp) << receiver.endpoint() << "\n";
    std::filesystem::rename(tmp, path);
  }

  const auto start = std::chrono::steady_clock::now();
  receiver.run();
  auto log = cslam::logger("server");
  log->info("finishing queued frames");
  system.finish();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  system.write_outputs(out_dir);
  const cslam::server::ServerStats& stats = receiver.stats();
  const cslam::SystemSnapshot snapshot = system.snapshot();
  std::ofstream(out_dir + "/network_stats.json") << stats.to_json(snapshot, wall_s) << "\n";
  for (const std::string& line : stats.summary_lines(snapshot, wall_s)) log->info("total {}", line);
  log->info("wrote trajectories and statistics to {}", out_dir);
  install_signal_handlers(nullptr);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cslam::run_main("cslam-server", argc, argv, run); }
