#pragma once
// TLS for the HTTP guard: the server's certificate (chain) and private key, PEM files, loaded once
// at startup into an OpenSSL SSL_CTX (OpenSSL is the library cpp-httplib itself uses on Debian).
// A file that is missing, unreadable or not PEM, an encrypted key, or a key that does not belong
// to the certificate is a ConfigError of one line naming the file. TLS 1.2 or newer, no
// renegotiation. The context is read-only once loaded and shared by every connection.
#include <string>

typedef struct ssl_ctx_st SSL_CTX;

namespace cslam::http {

class TlsContext {
 public:
  TlsContext(const std::string& cert_file, const std::string& key_file);
  ~TlsContext();
  TlsContext(const TlsContext&) = delete;
  TlsContext& operator=(const TlsContext&) = delete;

  SSL_CTX* get() const { return ctx_; }

 private:
  SSL_CTX* ctx_ = nullptr;
};

// The reason of the oldest error in this thread's OpenSSL error queue ("" if none); clears the queue.
std::string openssl_error();

}  // namespace cslam::http
