// cslam-server: receives RGB-D frames from client robots over ZeroMQ (protobuf messages, see
// proto/cslam.proto and docs/network.md) and runs one SLAM pipeline per client.
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <cstdlib>
#include <memory>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <zmq.hpp>

#include "server/dense/dense_products.h"
#include "server/dense/dense_service.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/thread_priority.h"
#include "slam/features/opencv_threads.h"
#include "proto/keys/curve_keys.h"
#include "server/http/http_server.h"
#include "server/receiver.h"
#include "server/state_store.h"
#include "server/http/map_routes.h"
#include "server/http/dense_routes.h"
#include "slam/mapping/local_mapper.h"
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

// Fails at start, not after the session, when results could not be written there.
void require_writable_dir(const std::string& option, const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  std::string reason = ec ? ec.message() : "";
  if (reason.empty()) {
    const fs::path probe = fs::path(dir) / ".cslam-write-probe";
    errno = 0;
    std::ofstream f(probe);  // a folder without write permission fails here (errno says why)
    f << "ok\n";
    f.close();  // a full disk fails here, not at the first write into the buffer
    const int err = errno;
    fs::remove(probe, ec);
    if (f.fail()) reason = "cannot write a file in it" + (err ? std::string(": ") + std::strerror(err) : std::string());
  }
  if (!reason.empty())
    throw cslam::ConfigError("cslam-server: " + option + " '" + dir + "' is not writable: " + reason);
}

// A private folder for the keyframe store under TMPDIR (/tmp); refused with what to do where none
// can be made (a read-only container root without a tmpfs at /tmp, TMPDIR naming no folder).
std::string make_private_store_dir() {
  const auto refuse = [](const std::string& where, const std::string& why) {
    return cslam::ConfigError("cslam-server: cannot create the keyframe store's temporary folder in '" + where +
                              "': " + why +
                              "; give --state-dir (the store then lives in STATE_DIR/dense), set TMPDIR to a "
                              "writable folder, or --no-dense");
  };
  std::error_code ec;
  const std::filesystem::path tmp = std::filesystem::temp_directory_path(ec);
  if (ec) {
    const char* env = std::getenv("TMPDIR");
    throw refuse(env ? env : "/tmp", ec.message());
  }
  std::string tmpl = (tmp / "cslam-dense-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw refuse(tmp.string(), std::strerror(errno));
  return tmpl;
}

// Removes the keyframe store's private folder (if it has one) where no DenseService, which removes
// it at exit, will own it: a refused start, or a dense map that could not start.
void discard_private_store(const cslam::server::DenseServiceConfig& c) {
  std::error_code ignored;
  if (c.store_is_temporary) std::filesystem::remove_all(c.store.dir, ignored);
}

cslam::server::DenseServiceConfig dense_config_from(const cslam::CliArgs& cli, const std::string& state_dir) {
  cslam::server::DenseServiceConfig c;
  c.enabled = !cli.flag_set("no-dense");
  const double max_mb = cli.get_double("dense-store-max-mb");
  if (!(max_mb >= 1)) throw cslam::ConfigError("cslam-server: --dense-store-max-mb must be at least 1");
  c.store.max_bytes = std::uint64_t(max_mb * 1024 * 1024);
  const double voxel = cli.get_double("dense-voxel");
  if (!(voxel >= 0.005 && voxel <= 0.2))
    throw cslam::ConfigError("cslam-server: --dense-voxel must be within [0.005, 0.2] m");
  c.map.tsdf.voxel_size = float(voxel);
  c.map.tsdf.truncation = float(4 * voxel);
  c.map.keyframes_per_submap = cli.get_int("dense-submap-keyframes");
  if (!state_dir.empty()) {
    c.store.dir = state_dir + "/dense";
  } else if (c.enabled) {  // a private folder for this run, removed at exit
    c.store.dir = make_private_store_dir();
    c.store_is_temporary = true;
  }
  try {
    c.validate();
  } catch (const cslam::ConfigError&) {
    discard_private_store(c);
    throw;
  }
  return c;
}

// The dense map, or none (logged) when it is off or its store cannot be used: SLAM runs either way.
std::unique_ptr<cslam::server::DenseService> start_dense(const cslam::server::DenseServiceConfig& config,
                                                         const cslam::CollaborativeSystem& system) {
  if (!config.enabled) return nullptr;
  try {
    auto dense = std::make_unique<cslam::server::DenseService>(config, system);
    dense->start();
    cslam::logger("server")->info("live dense map on (voxel {} m, keyframe store {})", config.map.tsdf.voxel_size,
                                  config.store.dir);
    return dense;
  } catch (const std::exception& e) {
    cslam::logger("server")->error("live dense map off: {}", e.what());
    discard_private_store(config);
    return nullptr;
  }
}

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-server",
                     "Receives RGB-D frames from cslam clients over ZeroMQ and runs collaborative SLAM.");
  cli.option("bind",
             "ZeroMQ endpoint to bind (tcp://127.0.0.1:* picks a free port; beyond loopback needs "
             "--curve-secret or --insecure-bind)",
             "tcp://127.0.0.1:5555")
      .option("clients", "number of clients to wait for before --exit-when-done can end the run", "1")
      .flag("exit-when-done", "exit once --clients clients said goodbye and no other client is still active")
      .option("out-dir", "folder for client_K.txt trajectories, stats.json and network_stats.json", "cslam-out")
      .flag("no-slam", "do not run SLAM (count frames only; for throughput benchmarks)")
      .flag("deterministic",
            "each client's local mapping, loop closing and fusion checks run inline on its worker "
            "(no mapping threads): a lossless client's result depends only on its frames and on how the clients' "
            "frames interleave (tests, experiments)")
      .option("window", "flow-control window: frames in flight per client", "4")
      .option("queue-capacity", "frames queued per client before the SLAM worker (>= window)", "8")
      .option("max-msg-bytes", "largest accepted message (ZMQ_MAXMSGSIZE); larger ones drop the connection", "16777216")
      .option("heartbeat-timeout", "seconds of silence before a client is marked disconnected", "5")
      .option(
          "max-timestamp-jump",
          "a frame stamped more than max(this, 100 x the session's median frame interval) "
          "+ 2 x the wall-clock time since its last frame past that frame is refused (ERROR_TIMESTAMP_JUMP); 0: off",
          "10")
      .option("log-interval", "seconds between progress lines", "5")
      .option("endpoint-file", "write the bound endpoint to this file once listening", "")
      .option("log-level", "trace, debug, info, warn, error, off", "info")
      .option("curve-secret", "server CURVE key file (cslam-keygen): encrypt and authenticate every robot", "")
      .option("clients-allowed", "folder of robots' CURVE public keys (*.pub, optionally bound to client ids)", "")
      .flag("insecure-bind", "allow a non-loopback --bind without CURVE keys (anyone reaching the port can send)")
      .option("max-clients", "sessions at a time (any state); more hellos are refused", "64")
      .option("max-pixels", "largest camera (width*height) a hello may announce", "2073600")
      .option("session-ttl", "seconds after which a disconnected or finished session is reclaimed (0: never)", "300")
      .option("decode-threads", "threads decoding frames for all clients", "2")
      .option("tracking-wait",
              "after a new keyframe, a client's tracking waits until local mapping has created and fused its points "
              "(new-points), fully processed it (keyframe: repeatable runs, more latency) or not at all (none)",
              "new-points")
      .option("tracking-slots",
              "client workers tracking at a time, served in arrival order: auto (as many as the cores this "
              "process may use) or a number (0: no limit). More robots than slots: each frame is tracked at "
              "full speed instead of all at once at a fraction of it, and pose latency drops "
              "(docs/performance.md)",
              "auto")
      .option("flow",
              "flow frames (optical-flow tracking between full frames, a fraction of their CPU): off, under-load "
              "(while a client's worker falls behind its live frames, instead of skipping more), always",
              "under-load")
      .option("state-dir", "folder of map snapshots: loaded at start, written periodically and at exit (empty: off)",
              "")
      .option("snapshot-interval", "seconds between background map snapshots (0: only on demand and at exit)", "10")
      .flag("state-reset",
            "start with empty maps even if --state-dir holds a snapshot (it is replaced by the next one)")
      .flag("no-dense", "do not keep keyframe images nor build the live dense map")
      .option("dense-store-max-mb",
              "keyframe image store budget (MB); beyond it new keyframes' images are refused (counted)", "4096")
      .option("dense-voxel", "voxel size of the live dense map (m)", "0.02")
      .option("dense-submap-keyframes", "keyframes per dense submap", "8");
  cslam::http::declare_options(cli);
  if (!cli.parse(argc, argv)) return 0;
  cslam::set_log_level(cli.get("log-level"));
  require_writable_dir("--out-dir", cli.get("out-dir"));

  cslam::server::ReceiverConfig rc;
  rc.bind = cli.get("bind");
  rc.window = std::uint32_t(cli.get_int("window"));
  rc.max_message_bytes = std::stoll(cli.get("max-msg-bytes"));
  rc.heartbeat_timeout_s = cli.get_double("heartbeat-timeout");
  rc.timestamp_bound.min_jump_s = cli.get_double("max-timestamp-jump");
  if (!(rc.timestamp_bound.min_jump_s >= 0))
    throw cslam::ConfigError("cslam-server: --max-timestamp-jump must be >= 0 (0 turns the bound off)");
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
  rc.max_clients = std::size_t(cli.get_int("max-clients"));
  rc.max_pixels = std::uint64_t(std::stoll(cli.get("max-pixels")));
  rc.session_ttl_s = cli.get_double("session-ttl");
  rc.decode_threads = std::size_t(cli.get_int("decode-threads"));
  rc.reclaim_dir = out_dir + "/reclaimed";
  if (cli.get_int("max-clients") < 1 || cli.get_int("decode-threads") < 1 || rc.max_pixels < 1 || rc.session_ttl_s < 0)
    throw cslam::ConfigError(
        "cslam-server: --max-clients, --decode-threads and --max-pixels must be positive, "
        "--session-ttl not negative");
  if (rc.expected_clients > rc.max_clients)
    throw cslam::ConfigError("cslam-server: --clients is larger than --max-clients");
  const std::string curve_secret = cli.get("curve-secret"), allowed = cli.get("clients-allowed");
  if (curve_secret.empty() != allowed.empty())
    throw cslam::ConfigError("cslam-server: --curve-secret and --clients-allowed go together");
  if (!curve_secret.empty()) {
    cslam::server::CurveConfig curve;
    curve.server = cslam::auth::read_secret_file(curve_secret);
    curve.clients = std::make_shared<const cslam::auth::KeyRegistry>(cslam::auth::read_allowed_dir(allowed));
    rc.curve = std::move(curve);
  } else if (!cslam::server::loopback_endpoint(rc.bind) && !cli.flag_set("insecure-bind")) {
    throw cslam::ConfigError("cslam-server: --bind " + rc.bind +
                             " reaches beyond this machine without keys: give "
                             "--curve-secret and --clients-allowed (see docs/security.md), or --insecure-bind");
  }
  // Read (and refused, if wrong) before anything starts: a bad HTTP setting is the only line.
  const cslam::http::HttpConfig http_config = cslam::http::config_from(cli);
  cslam::server::StateStoreConfig state_config;
  state_config.dir = cli.get("state-dir");
  if (!state_config.dir.empty()) require_writable_dir("--state-dir", state_config.dir);  // else no snapshot, ever
  state_config.interval_s = cli.get_double("snapshot-interval");
  state_config.reset = cli.flag_set("state-reset");
  if (state_config.interval_s < 0) throw cslam::ConfigError("cslam-server: --snapshot-interval must be >= 0");

  cslam::server::DenseServiceConfig dense_config = dense_config_from(cli, state_config.dir);

  // Declaration order is destruction order in reverse: the system (and its workers) stops before
  // the done channel they report to, the sockets close before their context.
  cslam::server::WakePipe stop;
  cslam::server::DoneChannel done;
  cslam::SystemConfig sc;
  sc.client_queue_capacity = std::size_t(capacity);
  sc.run_slam = !cli.flag_set("no-slam");
  sc.slam.mapper.tracking_wait = cslam::parse_tracking_wait(cli.get("tracking-wait"));
  const bool auto_slots = cli.get("tracking-slots") == "auto";
  sc.tracking_slots = auto_slots ? cslam::usable_cores() : cli.get_int("tracking-slots");
  if (sc.tracking_slots < 0)
    throw cslam::ConfigError("cslam-server: --tracking-slots must be auto or >= 0 (0: no limit)");
  cslam::logger("server")->info("tracking slots: {}{}",
                                sc.tracking_slots == 0 ? "no limit" : std::to_string(sc.tracking_slots),
                                auto_slots ? " (auto: the cores this process may use)" : "");
  sc.slam.tracker.flow.mode = cslam::parse_flow_mode(cli.get("flow"));
  if (cli.flag_set("deterministic")) {
    sc.slam.threaded = false;
    sc.fusion.threaded = false;
  }
  sc.on_frame_done = [&done](const cslam::FrameDone& d) { done.push(d); };
  // Keyframes reach the dense map once it exists (after the snapshot is loaded).
  std::atomic<cslam::server::DenseService*> dense_sink{nullptr};
  sc.on_keyframe = [&dense_sink](const cslam::ClientInfo& c, const cslam::KeyFrameId& id, const cslam::RgbdFrame& f,
                                 const cslam::SE3& T_cam_depthcam) {
    if (auto* d = dense_sink.load()) d->on_keyframe(c, id, f, T_cam_depthcam);
  };
  cslam::CollaborativeSystem system(sc);
  // Loads the newest snapshot (refuses to start on a bad one unless --state-reset).
  cslam::server::StateStore state(state_config, system);
  for (const auto& r : state.load()) rc.restored_sessions.emplace_back(r.info, r.last_seq);
  std::unique_ptr<cslam::server::DenseService> dense = start_dense(dense_config, system);
  dense_sink = dense.get();
  struct SinkReset {  // destroyed before the dense map: no SLAM worker reaches it afterwards
    std::atomic<cslam::server::DenseService*>& sink;
    ~SinkReset() { sink = nullptr; }
  } sink_reset{dense_sink};
  zmq::context_t context(1);
  cslam::server::Receiver receiver(context, rc, system, done, stop);
  cslam::http::NetStatusBoard net_status;
  receiver.set_status_board(&net_status);
  cslam::http::HttpServer http(system, http_config);  // reads snapshots only
  http.set_network_status(&net_status);
  cslam::http::add_map_routes(http.routes_server(), state, http_config.token);
  http.set_map_store(&state);  // snapshot health in /metrics and /api/health
  cslam::http::add_dense_routes(http.routes_server(), dense.get());
  if (dense && http_config.datasets_dir.empty()) http.set_held_frames(cslam::http::held_frames_source(dense.get()));
  http.set_status_extra([d = dense.get()](nlohmann::json& status, std::string& metrics) {
    cslam::http::add_dense_status(d, status, metrics);
  });
  if (http_config.enabled && !http.start())  // asked for, so not silently without the API and viewer
    throw cslam::ConfigError("cslam-server: cannot serve HTTP on " + http_config.bind + ":" +
                             std::to_string(http_config.port) +
                             " (in use?): --http PORT (0: any free port), or --http off");
  // A snapshot holds only keyframes whose images the store has (unless the dense worker is more
  // than 5 s behind: then the restarted server counts the missing ones).
  if (dense) state.set_before_export([d = dense.get()] { d->wait_stored(5.0); });
  state.start();
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
  state.stop();
  system.finish();
  if (dense) {
    log->info("finishing the dense map");
    dense->finish();
    for (const std::string& f : cslam::server::write_dense_outputs(*dense->view(), out_dir)) log->info("wrote {}", f);
  }
  if (!state_config.dir.empty() && state.write()) log->info("final map snapshot written to {}", state_config.dir);
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

int main(int argc, char** argv) {
  cslam::run_opencv_on_calling_threads();
  return cslam::run_main("cslam-server", argc, argv, run);
}
