#include "server/dense/dense_service.h"
#include "server/heap.h"

#include <algorithm>
#include <ctime>
#include <filesystem>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "core/thread_priority.h"
#include "geometry/camera.h"

namespace cslam::server {

namespace {

auto log() { return logger("dense"); }

constexpr std::size_t kTimingWindow = 512;

}  // namespace

void DenseServiceConfig::validate() const {
  map.validate();
  if (enabled) store.validate();  // off: there is no store
  if (!(step_interval_s > 0) || queue_capacity < 1 || queue_decoded > queue_capacity || max_integrations_per_step < 1 ||
      max_reintegrations_per_step < 0)
    throw ConfigError("dense map: step interval, queue capacity and integrations per step must be positive");
}

DenseService::DenseService(DenseServiceConfig config, const CollaborativeSystem& system)
    : config_((config.validate(), std::move(config))), system_(system), store_(config_.store), map_(config_.map) {}

DenseService::~DenseService() {
  finish();
  if (config_.store_is_temporary) {
    std::error_code ec;
    std::filesystem::remove_all(config_.store.dir, ec);
  }
}

double DenseService::uptime_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void DenseService::start() {
  // The snapshot is the truth: stored keyframes its maps do not hold (written after it, or by an
  // earlier run) are dropped; the others are integrated again with the restored poses.
  std::set<KeyFrameId> held;
  for (const KeyframePose& p : system_.keyframe_poses()) held.insert(p.id);
  std::size_t restored = 0, dropped = 0;
  const std::vector<KeyFrameId> stored = store_.ids();
  for (const KeyFrameId id : stored) {
    if (!held.count(id)) {
      store_.erase(id);
      ++dropped;
      continue;
    }
    if (!cameras_.count(id.client))
      if (const auto camera = store_.camera(id.client)) {
        cameras_[id.client] = *camera;
        map_.set_camera(id.client, *camera);
        std::lock_guard<std::mutex> lock(camera_mutex_);
        store_cameras_[id.client] = *camera;  // already in the store: put_job need not write it again
      }
    map_.add_keyframe(id, std::nullopt, -1e9);
    ++restored;
  }
  if (restored + dropped > 0)
    log()->info("keyframe store {}: {} keyframes to integrate again, {} not in the snapshot dropped", store_.path(),
                restored, dropped);
  // Keyframes of the snapshot whose images never reached the store (the server stopped between
  // the two, or ran without a dense map): the dense map lacks them; say so and count them.
  const std::size_t lost = held.size() - restored;
  if (lost > 0) {
    log()->warn(
        "keyframe store {}: {} keyframe(s) of the snapshot have no stored images; the dense map lacks them "
        "(counted in missing_images)",
        store_.path(), lost);
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.missing_images += lost;
  }
  thread_ = std::thread([this] { run(); });
}

void DenseService::on_keyframe(const ClientInfo& client, const KeyFrameId& id, const RgbdFrame& frame,
                               const SE3& T_cam_depthcam) {
  auto job = std::make_shared<Job>();
  job->T_cam_depthcam = T_cam_depthcam;
  job->client = client;
  job->record.id = id;
  job->record.timestamp = frame.timestamp;
  job->record.depth_time_offset = frame.depth_time_offset;
  if (frame.encoded) job->record.images = *frame.encoded;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.keyframes_received;
    if (stop_ || queue_.size() >= config_.queue_capacity) {
      ++stats_.queue_dropped;
      return;
    }
    // Decoded images (shared, not copied) save a decode when the worker keeps up; behind a long
    // queue only the received bytes wait, and the images are decoded from the store later.
    if (!frame.encoded || queue_.size() < config_.queue_decoded) job->images = DenseImages{frame.bgr, frame.depth};
    queue_.push_back(std::move(job));
  }
  wake_.notify_one();
}

void DenseService::finish() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (finished_) return;
    finished_ = true;
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool DenseService::put_job(Job& job) {
  int unclaimed = kUnclaimed;
  if (!job.store_state.compare_exchange_strong(unclaimed, kStoring)) return false;
  {
    const ClientId c = job.client.id;
    std::lock_guard<std::mutex> lock(camera_mutex_);
    const auto known = store_cameras_.find(c);
    if (known == store_cameras_.end() || !same_projection(known->second, job.client.camera)) {
      store_.put_camera(c, job.client.camera);
      store_cameras_[c] = job.client.camera;
    }
  }
  if (job.record.images.rgb.empty() && job.images) {  // frames that did not come over the network: lossless copy
    CodecOptions lossless;
    lossless.rgb = RgbCodec::kPng;
    const Bytes rgb = encode_rgb(job.images->bgr, lossless), depth = encode_depth(job.images->depth, lossless);
    job.record.images = {RgbCodec::kPng, std::string(rgb.begin(), rgb.end()), lossless.depth,
                         std::string(depth.begin(), depth.end())};
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.encoded_here;
  }
  const PutStatus status = store_.put(job.record);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (status == PutStatus::kStored || status == PutStatus::kAlreadyStored)
      ++stats_.stored;
    else if (status == PutStatus::kFull)
      ++stats_.store_refused_full;
    else
      ++stats_.store_errors;
    job.store_state = kStored;
  }
  stored_cv_.notify_all();
  return true;
}

bool DenseService::wait_stored(double timeout_s) {
  std::vector<std::shared_ptr<Job>> queued;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queued.assign(queue_.begin(), queue_.end());
  }
  // Store what the worker has not reached on this thread (the worker runs at low priority and
  // may lag by seconds on a busy machine); the worker then finds them stored and only integrates.
  for (const auto& job : queued) put_job(*job);
  // A job the worker was storing meanwhile: wait for that one.
  std::unique_lock<std::mutex> lock(mutex_);
  const bool done = stored_cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] {
    return std::all_of(queued.begin(), queued.end(), [](const auto& j) { return j->store_state == kStored; });
  });
  if (!done) log()->warn("keyframe store: a keyframe being stored by the dense worker took over {} s", timeout_s);
  return done;
}

void DenseService::run() {
  // Well below SLAM's compute threads (nice +5): on a saturated machine the robots' poses come
  // first and the dense map catches up (its queue and pending list are bounded and counted).
  name_current_thread("dense");
  lower_current_thread_priority(kDenseNice);
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait_for(lock, std::chrono::duration<double>(config_.step_interval_s),
                   [&] { return stop_ || !queue_.empty(); });
    const bool stopping = stop_;
    // Store the queued keyframes one at a time, each left in the queue until it is stored, so
    // that wait_stored sees every keyframe not stored yet.
    std::vector<std::shared_ptr<Job>> jobs;
    for (std::size_t n = queue_.size(); n > 0; --n) {
      std::shared_ptr<Job> job = queue_.front();
      lock.unlock();
      if (!put_job(*job)) {  // wait_stored took it: wait until it is in the store
        std::unique_lock<std::mutex> wait(mutex_);
        stored_cv_.wait(wait, [&] { return job->store_state == kStored; });
      }
      lock.lock();
      queue_.pop_front();
      jobs.push_back(std::move(job));
    }
    lock.unlock();
    integrate_jobs(jobs);
    step(stopping);
    lock.lock();
    if (stopping && queue_.empty()) break;
  }
}

void DenseService::integrate_jobs(std::vector<std::shared_ptr<Job>>& jobs) {
  const double now = uptime_s();
  for (const auto& job : jobs) {
    const ClientId c = job->client.id;
    const auto known = cameras_.find(c);
    if (known == cameras_.end() || !same_projection(known->second, job->client.camera)) {
      cameras_[c] = job->client.camera;
      map_.set_camera(c, job->client.camera);
    }
    // Integrated from the decoded images at hand even when the store refused them (they are
    // then missing only for a later re-integration, counted there).
    map_.add_keyframe(job->record.id, std::move(job->images), now, job->T_cam_depthcam);
  }
}

std::vector<KeyframePose> DenseService::group_keyframes(int group) const {
  std::vector<KeyframePose> out;
  for (const KeyframePose& p : system_.keyframe_poses())
    if (p.group == group) out.push_back(p);
  return out;
}

std::optional<DenseService::StoredKeyframe> DenseService::stored_keyframe(KeyFrameId id) const {
  try {
    const auto camera = store_.camera(id.client);
    return camera ? decode_stored(id, *camera) : std::nullopt;
  } catch (const InputError& e) {
    log()->warn("{}", e.what());
    return std::nullopt;
  }
}

std::optional<DenseService::StoredKeyframe> DenseService::decode_stored(KeyFrameId id,
                                                                        const PinholeCamera& camera) const {
  try {
    const auto record = store_.get(id);
    if (!record) return std::nullopt;
    std::ostringstream source;
    source << "stored keyframe " << id;
    auto [bgr, depth] = decode_rgbd(record->images, camera.width, camera.height, source.str());
    return StoredKeyframe{{std::move(bgr), std::move(depth)}, camera, record->depth_time_offset};
  } catch (const InputError& e) {
    log()->warn("{}", e.what());
    return std::nullopt;
  }
}

std::optional<DenseImages> DenseService::load(KeyFrameId id) {
  const auto camera = cameras_.find(id.client);  // the worker's own copy: no store read for it
  if (camera == cameras_.end()) return std::nullopt;
  auto stored = decode_stored(id, camera->second);
  return stored ? std::optional<DenseImages>(std::move(stored->images)) : std::nullopt;
}

void DenseService::step(bool final) {
  const Stopwatch timer;
  const double cpu0 = thread_cpu_ms();
  const std::vector<KeyframePose> poses = system_.keyframe_poses();
  const DenseImageLoader loader = [this](KeyFrameId id) { return load(id); };
  const DenseStepResult r = final ? map_.flush(poses, loader)
                                  : map_.step(poses, uptime_s(), loader,
                                              {config_.max_integrations_per_step, config_.max_reintegrations_per_step});
  for (const KeyFrameId id : r.culled) store_.erase(id);
  const auto view = map_.view();
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.steps;
  stats_.integrated += std::uint64_t(r.integrated);
  stats_.reintegrated += std::uint64_t(r.reintegrated);
  stats_.moved += std::uint64_t(r.moved);
  stats_.missing_images += std::uint64_t(r.missing_images);
  stats_.culled += r.culled.size();
  for (double ms : r.integrate_ms) {
    if (stats_.integrate_ms.size() >= kTimingWindow) stats_.integrate_ms.erase(stats_.integrate_ms.begin());
    stats_.integrate_ms.push_back(ms);
  }
  if (r.moved > 0 || r.reintegrated > 0) stats_.last_correction_s = uptime_s();
  stats_.pending = map_.pending();
  stats_.submaps = view->submaps.size();
  stats_.last_step_ms = timer.ms();
  stats_.integrate_cpu_ms += thread_cpu_ms() - cpu0;
  if (std::chrono::duration<double>(std::chrono::steady_clock::now() - last_log_).count() >= config_.log_interval_s) {
    last_log_ = std::chrono::steady_clock::now();
    const HeapStats heap = heap_stats();
    log()->info(
        "dense: {} submaps ({:.1f} MB meshes, {:.1f} MB volumes), {} keyframes integrated ({} pending, {} "
        "queued), {} re-integrations, heap {:.0f} MB held {:.0f} MB free, store {} keyframes {:.1f} MB{}",
        stats_.submaps, double(view->mesh_bytes) / 1e6, double(view->volume_bytes) / 1e6, stats_.integrated,
        stats_.pending, queue_.size(), stats_.reintegrated, double(heap.allocated) / 1e6,
        double(heap.free_mapped) / 1e6, store_.stats().keyframes, double(store_.stats().payload_bytes) / 1e6,
        store_.stats().last_error.empty() ? "" : " (store error: " + store_.stats().last_error + ")");
  }
}

DenseServiceStats DenseService::stats() const {
  DenseServiceStats s;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    s = stats_;
    s.queue = queue_.size();
  }
  s.store = store_.stats();
  return s;
}

}  // namespace cslam::server
