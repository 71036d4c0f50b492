#pragma once
// HTTP routes of the live dense map (docs/http.md, "Dense map"): status, the submap index with
// versions (ETag / If-None-Match), each submap's mesh (CSM1, levels of detail), a group's fused
// cloud and mesh (PLY), and the navigation maps. Handlers read the dense worker's immutable view;
// products derived from it are cached per (group, view version), a bounded number of them.

#include <string>

#include <nlohmann/json.hpp>

#include "server/http/http_server.h"

namespace httplib {
class Server;
}

namespace cslam::server {
class DenseService;
}

namespace cslam::http {

// The dense map's part of /api/status ("dense") and /metrics (cslam_dense_*), for
// HttpServer::set_status_extra.
void add_dense_status(const server::DenseService* dense, nlohmann::json& status, std::string& metrics);

// POST /api/reconstruction without --datasets-dir: every stored keyframe of the group at its
// current pose (HttpServer::set_held_frames).
HttpServer::HeldFramesSource held_frames_source(const server::DenseService* dense);

// dense may be null (dense map off): the routes answer {"enabled": false} / 503.
void add_dense_routes(httplib::Server& server, const server::DenseService* dense);

}  // namespace cslam::http
