#pragma once
// The embedded HTTP server of cslam-server (cpp-httplib behind HttpGuard, which owns the socket
// and enforces the request limits): JSON status API, Prometheus metrics,
// asynchronous dense reconstruction jobs and the web viewer's static files (web/). Handlers only
// read the StatusCache snapshot; they never call into the SLAM system themselves.
#include <atomic>
#include <functional>
#include <optional>
#include <memory>
#include <string>
#include <thread>

#include "core/cli.h"
#include "server/http/auth_gate.h"
#include "server/http/http_guard.h"
#include "server/http/recon_jobs.h"
#include "server/http/status_cache.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace cslam::http {

class TlsContext;     // server/http/tls_context.h
class RequestRouter;  // server/http/request_router.h

struct HttpConfig {
  bool enabled = true;
  int port = 8080;  // 0: any free port (see HttpServer::port())
  std::string bind = "127.0.0.1";
  std::string token;              // non-empty: every /api/* and /metrics request needs "Authorization: Bearer TOKEN"
  std::string tls_cert, tls_key;  // PEM files: the server speaks HTTPS only
  bool insecure = false;          // --http-insecure: plain HTTP beyond loopback (e.g. behind a TLS proxy)
  std::shared_ptr<const TlsContext> tls;  // loaded from tls_cert/tls_key by config_from (else by HttpServer)
  AuthConfig auth;                        // failed-token rate limit per source address
  std::string web_root;                   // folder with index.html, viewer.js, node_modules/three
  std::string port_file;                  // written with the bound port once listening
  std::string datasets_dir;               // reconstruction: DIR/<name>, DIR/robot_K or DIR/client_K per client
  std::string recon_camera;               // camera preset or file for the datasets; empty: io/dataset_camera.h's rule
  CacheConfig cache;
  GuardConfig guard;                       // request deadline, header/body caps, keep-alive, worker pool
  ReconJobsConfig recon;                   // reconstruction budget (--recon-max-mb), finished jobs kept
  double health_snapshot_failing_s = 120;  // GET /api/health: 503 once snapshots fail this long
  bool loopback() const;                   // bind is 127.*, localhost or ::1
  // Throws ConfigError (one line) unless the exposure is deliberate: beyond loopback a token of at
  // least 16 characters is required, and TLS (tls_cert + tls_key) unless `insecure`.
  void validate() const;
};

// Declares --http, --http-bind, --http-token, --http-token-file, --http-cert, --http-key,
// --http-insecure, --web-root, --http-port-file, --datasets-dir, --recon-camera, --recon-max-mb,
// --health-snapshot-failing-s on a program's CliArgs, and reads them back (throws ConfigError on
// bad values, on an exposure validate() refuses, and on certificate or key files that cannot be
// loaded).
void declare_options(CliArgs& cli);
HttpConfig config_from(const CliArgs& cli);

class HttpServer {
 public:
  // Throws ConfigError if config.validate() does, or if its certificate or key cannot be loaded.
  HttpServer(const CollaborativeSystem& system, HttpConfig config);
  ~HttpServer();  // stop()
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // Binds and starts the listener and the cache threads. Returns false if HTTP is off or the port
  // cannot be bound (cslam-server then refuses to start).
  bool start();
  // Live network counters for /api/status and /metrics (set before start()).
  void set_network_status(const NetStatusBoard* board) { cache_.set_network(board); }
  // Snapshot writes for /api/status, /metrics and /api/health (set before start()).
  void set_map_store(const MapStore* store) { cache_.set_map_store(store); }
  // Another component's part of /api/status and /metrics (StatusCache::set_extra; before start()).
  void set_status_extra(StatusCache::StatusExtra extra) { cache_.set_extra(std::move(extra)); }
  // Frames the server holds itself (the keyframe store), for POST /api/reconstruction without
  // --datasets-dir (before start()).
  struct HeldFrames {
    std::vector<DatasetPoses> estimate_inputs;  // poses and cameras (no folder) for the memory estimate
    ReconFunction reconstruct;
  };
  using HeldFramesSource = std::function<std::optional<HeldFrames>(int group)>;
  void set_held_frames(HeldFramesSource source) { held_frames_ = std::move(source); }
  void stop();  // idempotent; joins every thread (reconstruction jobs are cancelled)
  int port() const { return port_; }
  const GuardStats* guard_stats() const { return guard_ ? &guard_->stats() : nullptr; }
  const AuthGate& auth() const { return auth_; }
  // Registers more routes (e.g. add_map_routes) before start().
  httplib::Server& routes_server();

 private:
  void routes();
  void server_limits();
  void request_handlers();  // pre-routing (token, clean input), errors, exceptions
  void api_routes();        // api_routes.cpp
  void static_routes();
  bool refuse_unauthorised(const httplib::Request& req, httplib::Response& res);

  HttpConfig config_;
  const CollaborativeSystem& system_;
  StatusCache cache_;
  AuthGate auth_;
  ReconJobs jobs_;
  HeldFramesSource held_frames_;
  std::unique_ptr<RequestRouter> server_;  // routes only: never listens itself
  std::unique_ptr<HttpGuard> guard_;       // owns the socket, hands complete requests to httplib
  int port_ = -1;
};

}  // namespace cslam::http
