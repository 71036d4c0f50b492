#include "server/http/tls_channel.h"

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdint>
#include <memory>

namespace cslam::http {
namespace {

int bio_fd(BIO* b) { return int(reinterpret_cast<std::intptr_t>(BIO_get_data(b))); }

int bio_write(BIO* b, const char* in, int n) {
  BIO_clear_retry_flags(b);
  for (;;) {
    const ssize_t w = ::send(bio_fd(b), in, std::size_t(n), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (w >= 0) return int(w);
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) BIO_set_retry_write(b);
    return -1;
  }
}

int bio_read(BIO* b, char* out, int n) {
  BIO_clear_retry_flags(b);
  for (;;) {
    const ssize_t r = ::recv(bio_fd(b), out, std::size_t(n), MSG_DONTWAIT);
    if (r >= 0) return int(r);
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) BIO_set_retry_read(b);
    return -1;
  }
}

long bio_ctrl(BIO*, int cmd, long, void*) { return cmd == BIO_CTRL_FLUSH ? 1 : 0; }

int bio_create(BIO* b) {
  BIO_set_init(b, 0);
  return 1;
}

int bio_destroy(BIO*) { return 1; }  // the Channel owns the socket

// A socket BIO that never raises SIGPIPE (one method table for the process).
const BIO_METHOD* socket_method() {
  static const std::unique_ptr<BIO_METHOD, void (*)(BIO_METHOD*)> method = [] {
    BIO_METHOD* m = BIO_meth_new(BIO_get_new_index() | BIO_TYPE_SOURCE_SINK | BIO_TYPE_DESCRIPTOR, "cslam socket");
    BIO_meth_set_write(m, bio_write);
    BIO_meth_set_read(m, bio_read);
    BIO_meth_set_ctrl(m, bio_ctrl);
    BIO_meth_set_create(m, bio_create);
    BIO_meth_set_destroy(m, bio_destroy);
    return std::unique_ptr<BIO_METHOD, void (*)(BIO_METHOD*)>(m, BIO_meth_free);
  }();
  return method.get();
}

Io plain_result(ssize_t r, bool writing) {
  if (r > 0) return Io::kDone;
  if (r == 0) return writing ? Io::kError : Io::kClosed;
  if (errno == EAGAIN || errno == EWOULDBLOCK) return writing ? Io::kWantWrite : Io::kWantRead;
  return Io::kError;
}

int clamp_int(std::size_t n) { return n > std::size_t(INT_MAX) ? INT_MAX : int(n); }

}  // namespace

Channel::Channel(int fd, SSL_CTX* tls) : fd_(fd), ready_(tls == nullptr) {
  if (!tls) return;
  ssl_ = SSL_new(tls);
  BIO* bio = ssl_ ? BIO_new(socket_method()) : nullptr;
  if (!bio) {  // out of memory: the handshake fails at once
    broken_ = true;
    return;
  }
  BIO_set_data(bio, reinterpret_cast<void*>(std::intptr_t(fd)));
  BIO_set_init(bio, 1);
  SSL_set_bio(ssl_, bio, bio);  // one reference, owned by the SSL object
  SSL_set_accept_state(ssl_);
}

Channel::~Channel() {
  if (ssl_) {
    if (ready_ && !broken_) {
      ERR_clear_error();
      SSL_shutdown(ssl_);  // close_notify, one try: the socket is non-blocking
    }
    SSL_free(ssl_);
    ERR_clear_error();
  }
  ::close(fd_);
}

Io Channel::tls_result(int ret) {
  const int e = SSL_get_error(ssl_, ret);
  if (e == SSL_ERROR_WANT_READ) return Io::kWantRead;
  if (e == SSL_ERROR_WANT_WRITE) return Io::kWantWrite;
  if (e == SSL_ERROR_ZERO_RETURN) return Io::kClosed;  // the peer's close_notify
  broken_ = true;
  const unsigned long reason = ERR_peek_error();
  if (!ready_ && ERR_GET_LIB(reason) == ERR_LIB_SSL && ERR_GET_REASON(reason) == SSL_R_HTTP_REQUEST) plain_http_ = true;
  ERR_clear_error();
  return e == SSL_ERROR_SYSCALL && ret == 0 ? Io::kClosed : Io::kError;
}

Io Channel::handshake() {
  if (ready_) return Io::kDone;
  if (!ssl_ || broken_) return Io::kError;
  ERR_clear_error();
  const int r = SSL_do_handshake(ssl_);
  if (r == 1) {
    ready_ = true;
    return Io::kDone;
  }
  const Io io = tls_result(r);
  return io == Io::kClosed ? Io::kError : io;  // a peer gone mid-handshake failed it
}

Io Channel::read(char* buf, std::size_t size, std::size_t* n) {
  if (!ssl_) {
    ssize_t r;
    do r = ::recv(fd_, buf, size, MSG_DONTWAIT);
    while (r < 0 && errno == EINTR);
    if (r > 0) *n = std::size_t(r);
    return plain_result(r, false);
  }
  if (!ready_ || broken_) return Io::kError;
  ERR_clear_error();
  const int r = SSL_read(ssl_, buf, clamp_int(size));
  if (r > 0) {
    *n = std::size_t(r);
    return Io::kDone;
  }
  return tls_result(r);
}

Io Channel::write(const char* p, std::size_t size, std::size_t* n) {
  if (!ssl_) {
    ssize_t w;
    do w = ::send(fd_, p, size, MSG_NOSIGNAL | MSG_DONTWAIT);
    while (w < 0 && errno == EINTR);
    if (w > 0) *n = std::size_t(w);
    return plain_result(w, true);
  }
  if (!ready_ || broken_) return Io::kError;
  ERR_clear_error();
  const int w = SSL_write(ssl_, p, clamp_int(size));
  if (w > 0) {
    *n = std::size_t(w);
    return Io::kDone;
  }
  return tls_result(w);
}

bool Channel::pending() const { return ssl_ && ready_ && !broken_ && SSL_pending(ssl_) > 0; }

void Channel::send_once(const std::string& bytes) {
  std::size_t n = 0;
  if (ready_) write(bytes.data(), bytes.size(), &n);
}

void Channel::send_raw_once(const std::string& bytes) {
  // Read what the peer already sent first: closing a socket with unread input resets the
  // connection, and the peer may then lose this answer.
  char sink[4096];
  for (int i = 0; i < 16 && ::recv(fd_, sink, sizeof sink, MSG_DONTWAIT) > 0; ++i) {
  }
  [[maybe_unused]] const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ::shutdown(fd_, SHUT_WR);
}

bool write_all(Channel& channel, const char* p, std::size_t n, std::chrono::steady_clock::time_point deadline) {
  while (n > 0) {
    std::size_t written = 0;
    const Io io = channel.write(p, n, &written);
    if (io == Io::kDone) {
      p += written;
      n -= written;
      continue;
    }
    if (io != Io::kWantRead && io != Io::kWantWrite) return false;
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) return false;
    pollfd pfd{channel.fd(), short(io == Io::kWantRead ? POLLIN : POLLOUT), 0};
    if (::poll(&pfd, 1, int(left)) < 0 && errno != EINTR) return false;
  }
  return true;
}

}  // namespace cslam::http
