#pragma once
// The socket calls of the HTTP guard (server/http/http_guard.*): the non-blocking listening
// socket and accepting connections with the peer's address.
#include <string>

namespace cslam::http {

void set_nonblocking(int fd, bool on);

// Binds and listens on host:port (port 0: any free port; host empty: every address), the first
// address that works. Returns the bound port and sets *fd (non-blocking, close-on-exec), or
// returns -1 (errno kept).
int listen_socket(const std::string& host, int port, int* fd);

// Accepts one pending connection (non-blocking, close-on-exec) and gives the peer's address as
// text and its port ("" and 0 for another family). Returns the socket, or -1 if none is pending.
int accept_connection(int listen_fd, std::string* ip, int* port);

}  // namespace cslam::http
