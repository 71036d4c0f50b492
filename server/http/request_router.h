#pragma once
// The routes of the HTTP server: an httplib::Server that never listens. HttpGuard (which owns the
// socket, reads and checks every request) hands it one complete request at a time, on an
// in-memory stream, to route and answer.
//
// Why a subclass, and the one protected call in it. cpp-httplib 0.11 (Debian 12) offers no public
// way to route a request that someone else has read: its only public entry to the router is its
// own accept loop (listen / listen_after_bind), which reads each connection with blocking reads on
// a pool thread (one thread held per open connection, no header-count limit, a chunked body past
// payload_max_length: the reasons HttpGuard exists, docs/security.md "HTTP limits"). It cannot
// adopt a socket nor a request read elsewhere, and set_socket_options / set_pre_routing_handler /
// the timeouts act only after a worker thread is already tied to the connection. The supported
// way to reach Server::process_request is what httplib's own SSLServer does: a derived class
// calling it on itself. So the seam is this one class: the router *is* the object created
// (no cast of a plain httplib::Server, no member-pointer access), routes are registered through
// the public Get/Post API, and the single protected member used is named here. A change of that
// signature in a future cpp-httplib fails to compile in this file only.
//
// The alternative that uses public API only, a loopback proxy (httplib listening on a private
// port, each worker forwarding the request to it), was rejected: the peer address the auth gate
// rate-limits by would be lost, httplib's keep-alive headers would describe the internal
// connection, and every response would be copied twice.
#include <functional>

#include <httplib.h>  // after every Eigen include: <resolv.h> defines a macro _res

namespace cslam::http {

class RequestRouter : public httplib::Server {
 public:
  // Reads one request from `stream` (complete and normalised by the guard), runs the pre-routing
  // handler and the matching route, and writes the response to `stream`. `close`: the response
  // says "Connection: close"; `closed` is set if httplib decided to close the connection.
  // `setup` runs on the parsed request before routing (the peer's address goes in there).
  bool route(httplib::Stream& stream, bool close, bool& closed, const std::function<void(httplib::Request&)>& setup) {
    return process_request(stream, close, closed, setup);
  }
};

}  // namespace cslam::http
