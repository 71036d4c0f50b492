#pragma once
// TLS helpers for the HTTP tests: a self-signed certificate made at test time with the OpenSSL C
// API (nothing checked in, nothing downloaded), and a raw TLS client over a real socket whose
// source address, timing and bytes the test controls (httplib::SSLClient cannot stall mid-request
// or choose its source address).
#include <string>

typedef struct ssl_st SSL;
typedef struct ssl_ctx_st SSL_CTX;

namespace cslam::test {

struct CertFiles {
  std::string cert, key;
};

// Writes DIR/NAME.crt and DIR/NAME.key: a P-256 key and a self-signed certificate for CN=localhost
// with subjectAltName DNS:localhost, IP:127.0.0.1, valid from an hour ago for a day.
CertFiles make_self_signed(const std::string& dir, const std::string& name = "server");

// A TCP connection to 127.0.0.1:port from `source_ip` (any 127.x address is this machine), TLS on
// request. Certificates are not verified here (the tests that verify use httplib::SSLClient).
class TlsConn {
 public:
  explicit TlsConn(int port, const std::string& source_ip = "127.0.0.1");
  ~TlsConn();
  TlsConn(const TlsConn&) = delete;
  TlsConn& operator=(const TlsConn&) = delete;

  bool connected() const { return fd_ >= 0; }
  int fd() const { return fd_; }
  bool send_raw(const std::string& bytes);  // on the socket, past TLS
  bool handshake(double timeout_s = 10);
  bool send(const std::string& bytes);  // through TLS
  // One response (headers and a Content-Length body), or what came before close/timeout.
  std::string read_response(double timeout_s = 10);
  // Everything until the server closes (*closed = true) or the timeout (*closed = false). Works on
  // the raw socket before a handshake.
  std::string read_until_close(double timeout_s, bool* closed);

 private:
  int read_some(char* buf, int n, double timeout_s);  // > 0 bytes, 0 closed, -1 timeout/error

  int fd_ = -1;
  SSL_CTX* ctx_ = nullptr;
  SSL* ssl_ = nullptr;
};

// The status code of "HTTP/1.1 NNN ...", or 0.
int status_of(const std::string& response);
// A full request with an optional bearer token.
std::string get_request(const std::string& path, const std::string& token = "", bool close = true);

}  // namespace cslam::test
