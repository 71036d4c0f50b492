#pragma once
// Helpers for the network tests: a tiny TUM-layout dataset, a raw ZeroMQ DEALER peer speaking
// the wire protocol by hand, an in-process server, and child processes with a deadline.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <zmq.hpp>

#include "proto/adapter.h"
#include "server/receiver.h"

namespace cslam::test {

// The 64x48 pinhole camera (fx = fy = 50, centred) the network tests' frames use.
PinholeCamera small_camera();

// Writes `frames` random-texture w x h RGB PNGs + 16-bit depth PNGs, rgb.txt, depth.txt and
// camera.yaml (synthetic camera of that size) into dir. Returns the camera.
PinholeCamera write_tiny_dataset(const std::string& dir, int frames, int width = 64, int height = 48,
                                 unsigned seed = 1);

// Renders the small synthetic scene that the network tests running SLAM stream (cslam-synth
// --preset test-small --seed 7, one robot) into `out` and returns its robot's TUM folder. Throws
// std::runtime_error with cslam-synth's output if it fails.
std::string render_small_scene(const std::string& out);

// A unique scratch folder under the system temp dir (removed by the caller if wanted).
std::string scratch_dir(const std::string& name);

// A unique scratch folder that is removed when the object goes away, unless the running test has
// failed: then it is kept (and its path printed) so the logs inside can be read.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name) : path_(scratch_dir(name)) {}
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::vector<std::string> read_lines(const std::string& path);
// Data lines of a TUM trajectory file (comments dropped).
std::vector<std::string> trajectory_lines(const std::string& path);

// A hand-driven DEALER: sends whatever bytes a test wants, reads the server's replies.
class RawPeer {
 public:
  RawPeer(zmq::context_t& context, const std::string& endpoint);
  void send_bytes(const std::string& bytes);
  void send(const wire::ClientMessage& message) { send_bytes(message.SerializeAsString()); }
  std::optional<wire::ServerMessage> receive(int timeout_ms = 3000);
  void close() { socket_.close(); }

 private:
  zmq::socket_t socket_;
};

// Hello / frame builders for hand-made messages.
wire::ClientMessage make_hello(ClientId id, const PinholeCamera& camera);
wire::ClientMessage make_frame(ClientId id, std::uint64_t seq, double timestamp, const PinholeCamera& camera,
                               const CodecOptions& codecs = CodecOptions());

// CollaborativeSystem + Receiver on a thread, bound to a free loopback port.
class InProcessServer {
 public:
  explicit InProcessServer(server::ReceiverConfig config, SystemConfig system_config = SystemConfig());
  ~InProcessServer();
  std::string endpoint() const { return receiver_->endpoint(); }
  // Stops the loop (if still running) and joins; the stats/system stay readable.
  void stop();
  // Waits for the loop to end by itself (exit_when_done); false on timeout.
  bool wait_done(double timeout_s);
  CollaborativeSystem& system() { return *system_; }
  const server::ServerStats& stats() const { return receiver_->stats(); }
  const server::SessionTable& sessions() const { return receiver_->sessions(); }
  // Live counters published by the receiving thread (safe to read while it runs).
  std::shared_ptr<const http::NetStatus> net_status() const { return board_.get(); }

 private:
  http::NetStatusBoard board_;
  server::WakePipe stop_pipe_;
  server::DoneChannel done_;
  std::unique_ptr<CollaborativeSystem> system_;
  zmq::context_t context_{1};
  std::unique_ptr<server::Receiver> receiver_;
  std::thread thread_;
  std::atomic<bool> finished_{false};
};

// A child process (fork + exec) with stdout/stderr to a log file.
class ChildProcess {
 public:
  ChildProcess(const std::vector<std::string>& argv, const std::string& log_path);
  ~ChildProcess();  // kills the child if still running
  // Exit code, or nullopt if it did not exit within timeout_s (it is then killed).
  std::optional<int> wait(double timeout_s);
  void terminate();  // SIGTERM

 private:
  int pid_ = -1;
  bool reaped_ = false;
};

// Waits until `path` exists (a server's --endpoint-file) and returns its first line.
std::optional<std::string> wait_for_file_line(const std::string& path, double timeout_s);

}  // namespace cslam::test
