#include "server/http/http_server.h"

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/log.h"
#include "server/http/tls_context.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include "server/http/json_reply.h"
#include "server/http/request_router.h"

#ifndef CSLAM_WEB_DIR
#define CSLAM_WEB_DIR "web"
#endif

namespace cslam::http {

namespace {

constexpr std::size_t kMinExposedTokenLength = 16;

// The first line of a token file, without surrounding blanks.
std::string read_token_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("cslam-server: --http-token-file " + path + " cannot be read");
  std::string line;
  std::getline(in, line);
  const auto b = line.find_first_not_of(" \t\r"), e = line.find_last_not_of(" \t\r");
  if (b == std::string::npos)
    throw ConfigError("cslam-server: --http-token-file " + path + " has no token on its first line");
  return line.substr(b, e - b + 1);
}

}  // namespace

bool HttpConfig::loopback() const { return bind.rfind("127.", 0) == 0 || bind == "localhost" || bind == "::1"; }

void HttpConfig::validate() const {
  if (tls_cert.empty() != tls_key.empty()) throw ConfigError("cslam-server: --http-cert and --http-key go together");
  if (!enabled || loopback()) return;
  const std::string where = "cslam-server: --http-bind " + (bind.empty() ? std::string("(all addresses)") : bind);
  if (token.empty())
    throw ConfigError(where +
                      " reaches beyond this machine: give --http-token or --http-token-file (every /api/* and "
                      "/metrics request must then carry it), or bind 127.0.0.1");
  if (token.size() < kMinExposedTokenLength)
    throw ConfigError(where + " reaches beyond this machine: the token must have at least " +
                      std::to_string(kMinExposedTokenLength) + " characters (e.g. head -c 24 /dev/urandom | base64)");
  if (tls_cert.empty() && !insecure)
    throw ConfigError(where +
                      " would send the token and the maps in clear text: give --http-cert and --http-key "
                      "(TLS), or --http-insecure (e.g. behind a TLS-terminating proxy)");
}

void declare_options(CliArgs& cli) {
  cli.option("http", "HTTP status API and web viewer port (0: any free port, off: disabled)", "8080")
      .option("http-bind", "address the HTTP server binds (beyond loopback: --http-token and TLS, or --http-insecure)",
              "127.0.0.1")
      .option("http-token", "require 'Authorization: Bearer TOKEN' on every /api/* and /metrics request", "")
      .option("http-token-file",
              "read --http-token from the first line of this file (keeps it out of the process list)", "")
      .option("http-cert", "serve HTTPS with this PEM certificate (chain); needs --http-key", "")
      .option("http-key", "the PEM private key (unencrypted) of --http-cert", "")
      .flag("http-insecure",
            "allow plain HTTP with a --http-bind beyond loopback (e.g. behind a TLS-terminating proxy)")
      .option("web-root", "folder of the web viewer (index.html, viewer.js, node_modules/three)", CSLAM_WEB_DIR)
      .option("http-port-file", "write the bound HTTP port to this file once listening", "")
      .option("datasets-dir",
              "reconstruction over HTTP: per-client TUM folders DIR/<name>, DIR/robot_K or DIR/client_K", "")
      .option("recon-max-mb",
              "memory budget of one reconstruction request (MB): refused (413) if its estimate is over, stopped if the "
              "server grows more while it runs",
              "768")
      .option("recon-keep-jobs", "finished reconstruction jobs kept for download (the oldest go first)", "8")
      .option("recon-keep-s", "seconds a finished reconstruction job is kept for download", "900")
      .option("health-snapshot-failing-s",
              "GET /api/health answers 503 once map snapshots have failed for this many seconds", "120")
      .option("recon-camera",
              "camera preset or file for the reconstruction datasets (default: each DIR/camera.yaml, else its "
              "calibration.txt (fx fy cx cy), else the TUM camera its folder name says, else tum1)",
              "");
}

namespace {

// --http: a port, or "off".
void read_port(const CliArgs& cli, HttpConfig& c) {
  const std::string port = cli.get("http");
  if (port == "off") {
    c.enabled = false;
    return;
  }
  try {
    std::size_t used = 0;
    c.port = std::stoi(port, &used);
    if (used != port.size() || c.port < 0 || c.port > 65535) throw std::invalid_argument(port);
  } catch (const std::exception&) {
    throw ConfigError("cslam-server: --http must be a port 0..65535 or 'off', got '" + port + "'");
  }
}

// --recon-max-mb, --recon-keep-jobs, --recon-keep-s, --health-snapshot-failing-s.
void read_limits(const CliArgs& cli, HttpConfig& c) {
  c.recon.max_mb = cli.get_double("recon-max-mb");
  if (!(c.recon.max_mb >= 1)) throw ConfigError("cslam-server: --recon-max-mb must be at least 1");
  const int keep = cli.get_int("recon-keep-jobs");
  if (keep < 0) throw ConfigError("cslam-server: --recon-keep-jobs must be >= 0");
  c.recon.max_finished = std::size_t(keep);
  c.recon.max_age_s = cli.get_double("recon-keep-s");
  if (!(c.recon.max_age_s >= 0)) throw ConfigError("cslam-server: --recon-keep-s must be >= 0");
  c.health_snapshot_failing_s = cli.get_double("health-snapshot-failing-s");
  if (!(c.health_snapshot_failing_s > 0))
    throw ConfigError("cslam-server: --health-snapshot-failing-s must be positive");
}

}  // namespace

HttpConfig config_from(const CliArgs& cli) {
  HttpConfig c;
  read_port(cli, c);
  c.bind = cli.get("http-bind");
  c.token = cli.get("http-token");
  if (const std::string file = cli.get("http-token-file"); !file.empty()) {
    if (!c.token.empty()) throw ConfigError("cslam-server: give --http-token or --http-token-file, not both");
    c.token = read_token_file(file);
  }
  c.tls_cert = cli.get("http-cert");
  c.tls_key = cli.get("http-key");
  c.insecure = cli.flag_set("http-insecure");
  c.web_root = cli.get("web-root");
  c.port_file = cli.get("http-port-file");
  c.datasets_dir = cli.get("datasets-dir");
  c.recon_camera = cli.get("recon-camera");
  read_limits(cli, c);
  c.validate();
  // Loaded now, so that a bad file stops the program before anything else starts.
  if (c.enabled && !c.tls_cert.empty()) c.tls = std::make_shared<const TlsContext>(c.tls_cert, c.tls_key);
  return c;
}

HttpServer::HttpServer(const CollaborativeSystem& system, HttpConfig config)
    : config_(std::move(config)),
      system_(system),
      cache_(system, config_.cache),
      auth_(config_.token, config_.auth),
      jobs_(config_.recon),
      server_(std::make_unique<RequestRouter>()) {
  config_.validate();
  if (config_.enabled && !config_.tls_cert.empty() && !config_.tls)
    config_.tls = std::make_shared<const TlsContext>(config_.tls_cert, config_.tls_key);
  cache_.set_recon_jobs(&jobs_);
  cache_.set_auth_gate(&auth_);
  routes();
}

HttpServer::~HttpServer() { stop(); }

httplib::Server& HttpServer::routes_server() { return *server_; }

bool HttpServer::start() {
  auto log = logger("http");
  if (!config_.enabled) return false;
  if (!std::filesystem::exists(std::filesystem::path(config_.web_root) / "node_modules/three/build/three.module.js"))
    log->warn(
        "three.js not found under {}/node_modules (run scripts/install-web.sh): the viewer shows the client "
        "table only",
        config_.web_root);
  guard_ = std::make_unique<HttpGuard>(*server_, config_.guard, config_.tls.get());
  port_ = guard_->bind(config_.bind, config_.port);
  if (port_ < 0) {  // the caller says so (cslam-server refuses to start)
    guard_.reset();
    return false;
  }
  cache_.set_guard_stats(&guard_->stats());
  cache_.start();
  guard_->start();
  if (!config_.port_file.empty()) {
    const std::string tmp = config_.port_file + ".tmp";
    std::ofstream(tmp) << port_ << "\n";
    std::filesystem::rename(tmp, config_.port_file);
  }
  log->info("HTTP API and viewer on {}://{}:{}/{}", config_.tls ? "https" : "http", config_.bind, port_,
            config_.token.empty() ? "" : " (token required)");
  return true;
}

void HttpServer::stop() {
  if (guard_) guard_->stop();  // joins the event loop and the workers
  cache_.stop();
}

void HttpServer::routes() {
  server_limits();
  request_handlers();
  api_routes();
  static_routes();
}

void HttpServer::server_limits() {
  httplib::Server& s = *server_;
  // Limits are enforced by HttpGuard before a request reaches httplib (see http_guard.h).
  s.set_read_timeout(5, 0);
  s.set_write_timeout(5, 0);
  s.set_keep_alive_timeout(2);
  s.set_keep_alive_max_count(config_.guard.keep_alive_max_requests);
  // Headers and body go out in separate writes: without TCP_NODELAY, Nagle + delayed ACK add
  // ~40 ms to every keep-alive response.
  s.set_tcp_nodelay(true);
  s.set_payload_max_length(config_.guard.max_body_bytes);
}

void HttpServer::request_handlers() {
  httplib::Server& s = *server_;
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (refuse_unauthorised(req, res)) return httplib::Server::HandlerResponse::Handled;
    // Every route: a path or parameter that is not clean UTF-8 text is a 400 before any handler.
    if (const auto bad = unclean_request_part(req)) {
      json_error(res, 400, *bad);
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  s.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (res.body.empty())
      json_error(res, res.status, res.status == 404 ? "no such resource: " + req.path : "request failed");
  });
  s.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    json_error(res, 500, what);
  });
}

// Every /api/* and /metrics request needs the token; the viewer's files (no data) do not. An
// address that sent too many wrong tokens is refused before its token is looked at.
bool HttpServer::refuse_unauthorised(const httplib::Request& req, httplib::Response& res) {
  const bool api = req.path.rfind("/api/", 0) == 0 || req.path == "/metrics";
  if (!api || !auth_.enabled()) return false;
  const AuthGate::Result r = auth_.check(req.remote_addr, req.get_header_value("Authorization"));
  switch (r.verdict) {
    case AuthGate::Verdict::kOk:
      return false;
    case AuthGate::Verdict::kThrottled:
      res.set_header("Retry-After", std::to_string(r.retry_after_s));
      json_error(res, 429,
                 "too many wrong tokens from this address: retry after " + std::to_string(r.retry_after_s) + " s");
      return true;
    default:
      res.set_header("WWW-Authenticate", "Bearer");
      json_error(res, 401, "missing or wrong bearer token");
      return true;
  }
}

void HttpServer::static_routes() {
  auto file = [this](const std::string& name, const std::string& type) {
    return [this, name, type](const httplib::Request&, httplib::Response& res) {
      std::ifstream in(std::filesystem::path(config_.web_root) / name, std::ios::binary);
      if (!in) return json_error(res, 404, "viewer file missing: " + name + " (web root " + config_.web_root + ")");
      std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      res.set_header("Cache-Control", "no-cache");
      res.set_content(body, type.c_str());
    };
  };
  server_->Get("/", file("index.html", "text/html; charset=utf-8"));
  server_->Get("/index.html", file("index.html", "text/html; charset=utf-8"));
  server_->Get("/viewer.js", file("viewer.js", "text/javascript; charset=utf-8"));
  // The viewer's modules (web/*.js): flat lower-case names only, so no path can leave the web root.
  server_->Get(R"(/([a-z0-9_]+\.js))", [file](const httplib::Request& req, httplib::Response& res) {
    file(std::string(req.matches[1]), "text/javascript; charset=utf-8")(req, res);
  });
  // three.js (r160 is one ES module file) from the npm install, never from the internet.
  server_->Get("/vendor/three.module.js",
               file("node_modules/three/build/three.module.js", "text/javascript; charset=utf-8"));
}

}  // namespace cslam::http
