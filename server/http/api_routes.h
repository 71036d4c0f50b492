#pragma once
// The JSON API of the HTTP server (see README "HTTP API"), one named handler per route: the
// state routes (api_routes.cpp: status, clients, events, trajectories, map points, metrics,
// health) and the reconstruction routes (recon_routes.cpp). Every handler reads one immutable
// StatusCache snapshot or the reconstruction job table; none calls into the SLAM system.
#include <vector>

#include "server/http/http_server.h"

namespace cslam::http {

// What the handlers read: the HttpServer's members (they outlive the routes).
struct ApiContext {
  const StatusCache& cache;
  ReconJobs& jobs;
  const HttpConfig& config;
  const HttpServer::HeldFramesSource& held_frames;  // read per request: set after the routes
};

using ApiHandler = void (*)(const ApiContext&, const httplib::Request&, httplib::Response&);

struct ApiRoute {
  enum class Method { kGet, kPost };
  Method method;
  const char* pattern;  // httplib's regex, matched whole
  ApiHandler handler;
  bool guarded;  // input checks and exceptions as JSON 400 / 500 (api_params.h)
};

std::vector<ApiRoute> state_routes();  // api_routes.cpp
std::vector<ApiRoute> recon_routes();  // recon_routes.cpp

// Registers `routes` in order (the first match wins within a method).
void add_api_routes(httplib::Server& server, const ApiContext& context, const std::vector<ApiRoute>& routes);

}  // namespace cslam::http
