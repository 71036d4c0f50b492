#include "proto/snapshot_file.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <unistd.h>

#include "core/error.h"

namespace cslam::snapshot {

namespace fs = std::filesystem;

std::string current_path(const std::string& dir) { return (fs::path(dir) / kCurrentName).string(); }
std::string previous_path(const std::string& dir) { return current_path(dir) + ".prev"; }

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what, int err) {
  throw WriteError(path + ": " + what + ": " + std::strerror(err));
}

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }
  int release() {
    const int f = fd_;
    fd_ = -1;
    return f;
  }

 private:
  int fd_;
};

void fsync_dir(const std::string& dir) {
  Fd fd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (fd.get() < 0) fail(dir, "cannot open folder to sync", errno);
  if (::fsync(fd.get()) != 0) fail(dir, "fsync of folder failed", errno);
}

// Writes and fsyncs `tmp`; removes it and throws WriteError on any failure.
void write_synced(const std::string& tmp, const std::string& bytes) {
  {
    Fd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
    if (fd.get() < 0) fail(tmp, "cannot create", errno);
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const int err = n < 0 ? errno : ENOSPC;
        ::unlink(tmp.c_str());
        fail(tmp, "write failed after " + std::to_string(done) + " of " + std::to_string(bytes.size()) + " bytes", err);
      }
      done += std::size_t(n);
    }
    if (::fsync(fd.get()) != 0) {
      const int err = errno;
      ::unlink(tmp.c_str());
      fail(tmp, "fsync failed", err);
    }
    const int raw = fd.release();
    if (::close(raw) != 0) {
      const int err = errno;
      ::unlink(tmp.c_str());
      fail(tmp, "close failed", err);
    }
  }
}

}  // namespace

void write_file_atomic(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".tmp";
  write_synced(tmp, bytes);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    fail(path, "rename failed", err);
  }
  const fs::path parent = fs::path(path).parent_path();
  fsync_dir(parent.empty() ? "." : parent.string());
}

void write_atomic(const std::string& dir, const std::string& bytes) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw WriteError(dir + ": cannot create state folder: " + ec.message());
  const std::string current = current_path(dir), prev = previous_path(dir), tmp = current + ".tmp",
                    prev_tmp = prev + ".tmp";
  write_synced(tmp, bytes);
  // Keep the current snapshot as the previous one: a hard link, so the current name never
  // disappears (a crash at any point leaves a loadable map.snapshot).
  if (fs::exists(current)) {
    ::unlink(prev_tmp.c_str());
    if (::link(current.c_str(), prev_tmp.c_str()) == 0) {
      if (::rename(prev_tmp.c_str(), prev.c_str()) != 0) fail(prev, "rename failed", errno);
    }
  }
  if (::rename(tmp.c_str(), current.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    fail(current, "rename failed", err);
  }
  fsync_dir(dir);
}

std::optional<std::string> newest_snapshot(const std::string& dir) {
  if (fs::exists(current_path(dir))) return current_path(dir);
  if (fs::exists(previous_path(dir))) return previous_path(dir);
  return std::nullopt;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open snapshot file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path, "read error");
  return ss.str();
}

}  // namespace cslam::snapshot
