#include "server/http/tls_context.h"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509err.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "core/log.h"

namespace cslam::http {
namespace {

// Refuses to ask for a passphrase: an encrypted key must fail, never prompt on the terminal.
int no_passphrase(char*, int, int, void*) { return 0; }

void require_readable(const std::string& option, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError("cslam-server: " + option + " " + path + " cannot be read: " + std::strerror(errno));
}

void warn_if_expired(SSL_CTX* ctx, const std::string& cert_file) {
  X509* cert = SSL_CTX_get0_certificate(ctx);
  if (cert && X509_cmp_current_time(X509_get0_notAfter(cert)) < 0)
    logger("http")->warn("HTTP: the certificate in {} has expired: clients will refuse it", cert_file);
}

}  // namespace

std::string openssl_error() {
  const unsigned long e = ERR_get_error();
  ERR_clear_error();
  if (e == 0) return "";
  char buf[256];
  ERR_error_string_n(e, buf, sizeof buf);
  return buf;
}

TlsContext::TlsContext(const std::string& cert_file, const std::string& key_file) {
  require_readable("--http-cert", cert_file);
  require_readable("--http-key", key_file);
  ERR_clear_error();
  ctx_ = SSL_CTX_new(TLS_server_method());
  if (!ctx_) throw ConfigError("cslam-server: cannot create a TLS context: " + openssl_error());
  SSL_CTX_set_min_proto_version(ctx_, TLS1_2_VERSION);
  SSL_CTX_set_options(ctx_, SSL_OP_NO_RENEGOTIATION | SSL_OP_CIPHER_SERVER_PREFERENCE | SSL_OP_NO_COMPRESSION);
  // Non-blocking writes: a retried SSL_write may pass the rest of a buffer, and may write part of it.
  SSL_CTX_set_mode(ctx_, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  SSL_CTX_set_default_passwd_cb(ctx_, no_passphrase);
  try {
    if (SSL_CTX_use_certificate_chain_file(ctx_, cert_file.c_str()) != 1)
      throw ConfigError("cslam-server: --http-cert " + cert_file + " is not a PEM certificate (" + openssl_error() +
                        ")");
    if (SSL_CTX_use_PrivateKey_file(ctx_, key_file.c_str(), SSL_FILETYPE_PEM) != 1 ||
        SSL_CTX_check_private_key(ctx_) != 1) {
      const unsigned long e = ERR_peek_error();
      if (ERR_GET_LIB(e) == ERR_LIB_X509 && ERR_GET_REASON(e) == X509_R_KEY_VALUES_MISMATCH) {
        ERR_clear_error();
        throw ConfigError("cslam-server: --http-key " + key_file + " does not belong to the certificate in " +
                          cert_file);
      }
      throw ConfigError("cslam-server: --http-key " + key_file + " is not an unencrypted PEM private key (" +
                        openssl_error() + ")");
    }
  } catch (...) {
    SSL_CTX_free(ctx_);
    ctx_ = nullptr;
    throw;
  }
  warn_if_expired(ctx_, cert_file);
}

TlsContext::~TlsContext() {
  if (ctx_) SSL_CTX_free(ctx_);
}

}  // namespace cslam::http
