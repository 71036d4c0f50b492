#include "raw_socket.h"
#include "network/tls_test_util.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>

namespace cslam::test {
namespace {

using Clock = std::chrono::steady_clock;

void write_pem(const std::string& path, X509* cert, EVP_PKEY* key) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw std::runtime_error("cannot write " + path);
  const bool ok =
      cert ? PEM_write_X509(f, cert) == 1 : PEM_write_PrivateKey(f, key, nullptr, nullptr, 0, nullptr, nullptr) == 1;
  std::fclose(f);
  if (!ok) throw std::runtime_error("cannot write PEM to " + path);
}

void add_san(X509* cert) {
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, cert, cert, nullptr, nullptr, 0);
  X509_EXTENSION* ext = X509V3_EXT_conf_nid(nullptr, &ctx, NID_subject_alt_name, "DNS:localhost,IP:127.0.0.1");
  if (!ext) throw std::runtime_error("subjectAltName");
  X509_add_ext(cert, ext, -1);
  X509_EXTENSION_free(ext);
}

}  // namespace

CertFiles make_self_signed(const std::string& dir, const std::string& name) {
  EVP_PKEY* key = EVP_EC_gen("P-256");
  X509* cert = X509_new();
  if (!key || !cert) throw std::runtime_error("OpenSSL: cannot make a key or certificate");
  X509_set_version(cert, 2);
  ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
  X509_gmtime_adj(X509_getm_notBefore(cert), -3600);
  X509_gmtime_adj(X509_getm_notAfter(cert), 24 * 3600);
  X509_set_pubkey(cert, key);
  X509_NAME* subject = X509_get_subject_name(cert);
  X509_NAME_add_entry_by_txt(subject, "CN", MBSTRING_ASC, reinterpret_cast<const unsigned char*>("localhost"), -1, -1,
                             0);
  X509_set_issuer_name(cert, subject);
  add_san(cert);
  if (X509_sign(cert, key, EVP_sha256()) == 0) throw std::runtime_error("OpenSSL: cannot sign");
  CertFiles files{dir + "/" + name + ".crt", dir + "/" + name + ".key"};
  write_pem(files.cert, cert, nullptr);
  write_pem(files.key, nullptr, key);
  X509_free(cert);
  EVP_PKEY_free(key);
  return files;
}

TlsConn::TlsConn(int port, const std::string& source_ip) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in src{}, dst{};
  src.sin_family = dst.sin_family = AF_INET;
  inet_pton(AF_INET, source_ip.c_str(), &src.sin_addr);
  dst.sin_port = htons(std::uint16_t(port));
  dst.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&src), sizeof src) != 0 ||
      ::connect(fd, reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) {
    ::close(fd);
    return;
  }
  fd_ = fd;
}

TlsConn::~TlsConn() {
  if (ssl_) SSL_free(ssl_);
  if (ctx_) SSL_CTX_free(ctx_);
  if (fd_ >= 0) ::close(fd_);
}

bool TlsConn::send_raw(const std::string& bytes) { return send_all(fd_, bytes); }

bool TlsConn::handshake(double timeout_s) {
  if (fd_ < 0) return false;
  ctx_ = SSL_CTX_new(TLS_client_method());
  ssl_ = SSL_new(ctx_);
  SSL_set_fd(ssl_, fd_);
  timeval tv{long(timeout_s), 0};
  ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  const bool ok = SSL_connect(ssl_) == 1;
  ERR_clear_error();
  return ok;
}

bool TlsConn::send(const std::string& bytes) {
  if (!ssl_) return false;
  std::size_t off = 0;
  while (off < bytes.size()) {
    const int n = SSL_write(ssl_, bytes.data() + off, int(bytes.size() - off));
    if (n <= 0) {
      ERR_clear_error();
      return false;
    }
    off += std::size_t(n);
  }
  return true;
}

int TlsConn::read_some(char* buf, int n, double timeout_s) {
  if (ssl_ && SSL_pending(ssl_) > 0) return SSL_read(ssl_, buf, n);
  pollfd p{fd_, POLLIN, 0};
  if (::poll(&p, 1, int(timeout_s * 1000)) <= 0) return -1;
  if (!ssl_) {
    const ssize_t r = ::recv(fd_, buf, std::size_t(n), 0);
    return r < 0 ? 0 : int(r);  // a reset is a close too
  }
  const int r = SSL_read(ssl_, buf, n);
  if (r > 0) return r;
  const int e = SSL_get_error(ssl_, r);
  ERR_clear_error();
  return e == SSL_ERROR_WANT_READ ? read_some(buf, n, 0.2) : 0;  // a record without data (ticket)
}

std::string TlsConn::read_response(double timeout_s) {
  std::string out;
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  char buf[4096];
  while (Clock::now() < deadline) {
    const auto he = out.find("\r\n\r\n");
    if (he != std::string::npos) {
      const auto cl = out.find("Content-Length: ");
      if (cl != std::string::npos && cl < he && out.size() >= he + 4 + std::stoul(out.substr(cl + 16))) return out;
    }
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    const int n = read_some(buf, sizeof buf, std::max(0.01, left));
    if (n <= 0) break;
    out.append(buf, std::size_t(n));
  }
  return out;
}

std::string TlsConn::read_until_close(double timeout_s, bool* closed) {
  std::string out;
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  char buf[4096];
  *closed = false;
  while (Clock::now() < deadline) {
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    const int n = read_some(buf, sizeof buf, std::max(0.01, left));
    if (n == 0) {
      *closed = true;
      break;
    }
    if (n > 0) out.append(buf, std::size_t(n));
  }
  return out;
}

int status_of(const std::string& response) {
  int status = 0;
  return std::sscanf(response.c_str(), "HTTP/1.%*d %d", &status) == 1 ? status : 0;
}

std::string get_request(const std::string& path, const std::string& token, bool close) {
  std::string r = "GET " + path + " HTTP/1.1\r\nHost: localhost\r\n";
  if (!token.empty()) r += "Authorization: Bearer " + token + "\r\n";
  if (close) r += "Connection: close\r\n";
  return r + "\r\n";
}

}  // namespace cslam::test
