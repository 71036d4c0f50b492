#pragma once
// The byte stream of one accepted HTTP connection, plain TCP or TLS, over a non-blocking socket.
//
// Threads: a Channel is used by one thread at a time. The guard's event loop owns it while the
// TLS handshake runs and a request arrives (SSL_do_handshake / SSL_read); the whole connection is
// then moved to one worker under the guard's mutex, which writes the response (SSL_write) and moves
// it back under the same mutex. The mutex hand-over orders every access to the SSL object, which
// OpenSSL does not allow two threads to use at once.
//
// The socket BIO is cslam's own: OpenSSL's writes with write(2), which raises SIGPIPE when the peer
// has gone; this one sends with MSG_NOSIGNAL.
#include <chrono>
#include <cstddef>
#include <string>

typedef struct ssl_st SSL;
typedef struct ssl_ctx_st SSL_CTX;

namespace cslam::http {

enum class Io { kDone, kWantRead, kWantWrite, kClosed, kError };

class Channel {
 public:
  Channel(int fd, SSL_CTX* tls);  // owns fd; tls null: plain TCP
  ~Channel();                     // TLS: one non-blocking close_notify; closes fd
  Channel(const Channel&) = delete;
  Channel& operator=(const Channel&) = delete;

  int fd() const { return fd_; }
  bool tls() const { return ssl_ != nullptr; }
  bool ready() const { return ready_; }  // plain, or the TLS handshake finished
  // Advances the TLS handshake: kDone once finished; kWantRead / kWantWrite: call again when the
  // socket is readable / writable; kError: the handshake failed (plain_http(): because the peer
  // sent a plain HTTP request to the TLS port).
  Io handshake();
  bool plain_http() const { return plain_http_; }
  // Application bytes, non-blocking; *n is set when the result is kDone.
  Io read(char* buf, std::size_t size, std::size_t* n);
  Io write(const char* p, std::size_t size, std::size_t* n);
  // TLS: decrypted bytes held inside OpenSSL, which poll() on the socket cannot see.
  bool pending() const;
  // One non-blocking attempt to send `bytes` through the channel (error replies); nothing if the
  // handshake has not finished.
  void send_once(const std::string& bytes);
  // One non-blocking attempt to send `bytes` on the raw socket, past TLS (the answer to plain HTTP).
  void send_raw_once(const std::string& bytes);

 private:
  Io tls_result(int ret);

  int fd_;
  SSL* ssl_ = nullptr;
  bool ready_ = false;
  bool broken_ = false;  // a fatal TLS error: no SSL_shutdown afterwards
  bool plain_http_ = false;
};

// Writes all of [p, p + n) before the deadline, polling the socket as the channel asks; false on
// an error or at the deadline.
bool write_all(Channel& channel, const char* p, std::size_t n, std::chrono::steady_clock::time_point deadline);

}  // namespace cslam::http
