#include "server/decode_pool.h"

#include <stdexcept>

#include "core/stopwatch.h"
#include "core/thread_priority.h"

namespace cslam::server {

DecodePool::DecodePool(std::size_t threads, std::size_t capacity, Submit submit)
    : capacity_(std::max<std::size_t>(1, capacity)), submit_(std::move(submit)) {
  if (threads == 0) throw std::invalid_argument("DecodePool needs at least one thread");
  for (std::size_t i = 0; i < threads; ++i) threads_.emplace_back([this] { run(); });
}

DecodePool::~DecodePool() { finish(); }

bool DecodePool::post(DecodeJob job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stop_ || queue_.size() >= capacity_) return false;
    queue_.push_back(std::move(job));
  }
  wake_.notify_one();
  return true;
}

std::vector<DecodeResult> DecodePool::drain() {
  results_pipe_.clear();
  std::lock_guard<std::mutex> lock(results_mutex_);
  std::vector<DecodeResult> out;
  out.swap(results_);
  return out;
}

std::size_t DecodePool::queued() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.size();
}

void DecodePool::finish() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_)
    if (t.joinable()) t.join();
}

void DecodePool::run() {
  name_current_thread("decode");
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    // The oldest job of a client that no other thread is decoding (keeps each client's order).
    auto next = queue_.end();
    wake_.wait(lock, [&] {
      next = queue_.begin();
      while (next != queue_.end() && busy_.count(next->client)) ++next;
      return next != queue_.end() || (stop_ && queue_.empty());
    });
    if (next == queue_.end()) return;  // stopping and nothing left
    DecodeJob job = std::move(*next);
    queue_.erase(next);
    busy_.insert(job.client);
    // A map node stays where it is while other clients' nodes come and go.
    std::unique_ptr<video::H264Decoder>* colour_stream =
        job.frame->rgb().encoding() == wire::RGB_H264 ? &colour_streams_[job.client] : nullptr;
    lock.unlock();
    DecodeResult result = process(job, colour_stream);
    job.frame.reset();
    {
      std::lock_guard<std::mutex> results_lock(results_mutex_);
      results_.push_back(std::move(result));
    }
    results_pipe_.notify();
    lock.lock();
    busy_.erase(job.client);
    wake_.notify_all();  // that client's next job may go now
  }
}

DecodeResult DecodePool::process(DecodeJob& job, std::unique_ptr<video::H264Decoder>* colour_stream) {
  const Stopwatch timer;
  DecodeResult r;
  r.client = job.client;
  r.seq = job.seq;
  try {
    if (colour_stream && !*colour_stream)
      *colour_stream = std::make_unique<video::H264Decoder>(job.camera.width, job.camera.height);
    RgbdFrame decoded =
        wire::from_wire_frame(*job.frame, job.camera, job.source, colour_stream ? colour_stream->get() : nullptr);
    decoded.client = job.client;
    decoded.arrived = job.arrived;
    // Only frames that may become keyframes are kept for the dense map.
    if (wire::keyframe_eligible(*job.frame))
      decoded.encoded = std::make_shared<const EncodedRgbd>(wire::take_encoded(*job.frame));
    if (!submit_(std::move(decoded))) {
      r.outcome = DecodeResult::Outcome::kShuttingDown;
      r.code = wire::ERROR_SHUTTING_DOWN;
      r.message = job.source + ": system is finishing";
    }
  } catch (const wire::WireError& e) {
    r.outcome = DecodeResult::Outcome::kRejected;
    r.code = e.code();
    r.message = e.what();
  } catch (const std::invalid_argument& e) {
    r.outcome = DecodeResult::Outcome::kRejected;
    r.code = wire::ERROR_SIZE_MISMATCH;
    r.message = job.source + ": " + e.what();
  } catch (const std::exception& e) {  // e.g. std::bad_alloc: drop the frame, keep serving
    r.outcome = DecodeResult::Outcome::kRejected;
    r.code = wire::ERROR_CORRUPT_IMAGE;
    r.message = job.source + ": " + e.what();
  }
  r.decode_ms = timer.ms();
  return r;
}

}  // namespace cslam::server
