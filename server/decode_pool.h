#pragma once
// Frame decoding off the receiving thread: a small fixed pool of threads decodes frames (bounded
// decoders, see codec/image_codec.h) and submits them to the SLAM system; results go back to the
// receiving thread through a wake pipe. Frames of one client are decoded one at a time and
// submitted in the order they were posted; other clients' frames are decoded meanwhile by the
// other threads, so one client's heavy frame never delays another client's acks.
// The queue is bounded (post() returns false when full); with credits it never fills.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "codec/video_codec.h"
#include "proto/adapter.h"
#include "server/wake_pipe.h"

namespace cslam::server {

struct DecodeJob {
  ClientId client = 0;
  std::uint64_t seq = 0;
  PinholeCamera camera;
  std::string source;  // "client K frame S" for error messages
  std::unique_ptr<wire::RgbdFrame> frame;
  std::chrono::steady_clock::time_point arrived;  // when the receiver read the packet
};

struct DecodeResult {
  ClientId client = 0;
  std::uint64_t seq = 0;
  enum class Outcome { kSubmitted, kRejected, kShuttingDown } outcome = Outcome::kSubmitted;
  wire::ErrorCode code = wire::ERROR_UNSPECIFIED;  // kRejected: why
  std::string message;
  double decode_ms = 0;  // decode + submit on the pool thread
};

class DecodePool {
 public:
  // submit: hands a decoded frame to the system (false: finishing / unknown client; may throw
  // std::invalid_argument for a frame that contradicts the client's camera).
  using Submit = std::function<bool(RgbdFrame)>;
  DecodePool(std::size_t threads, std::size_t capacity, Submit submit);
  ~DecodePool();  // finish()
  DecodePool(const DecodePool&) = delete;
  DecodePool& operator=(const DecodePool&) = delete;

  // Queues a job; false if the queue is full or the pool is finishing.
  bool post(DecodeJob job);
  // Results since the last call (receiving thread).
  std::vector<DecodeResult> drain();
  int read_fd() const { return results_pipe_.read_fd(); }
  // Decodes and submits what is queued, then joins the threads. Idempotent.
  void finish();
  std::size_t threads() const { return threads_.size(); }
  std::size_t queued() const;

 private:
  void run();
  DecodeResult process(DecodeJob& job, std::unique_ptr<video::H264Decoder>* colour_stream);

  const std::size_t capacity_;
  Submit submit_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<DecodeJob> queue_;
  std::set<ClientId> busy_;  // clients with a job being decoded right now
  // Each client's colour-stream decoder (light frames' RGB_H264 colour), made at its first such packet. Only
  // the thread that holds the client in busy_ touches it; the map itself is guarded by mutex_.
  // At most one per session (the server bounds sessions with --max-clients).
  std::map<ClientId, std::unique_ptr<video::H264Decoder>> colour_streams_;
  bool stop_ = false;
  std::vector<std::thread> threads_;

  std::mutex results_mutex_;
  std::vector<DecodeResult> results_;
  WakePipe results_pipe_;
};

}  // namespace cslam::server
