#pragma once
// The server's keyframe RGB-D store: every keyframe's colour and depth exactly as a robot sent
// them (the compressed payload, never re-encoded), with its capture times, and each client's
// camera, so the dense map can be built and rebuilt from what was received.
//
// One SQLite file, <dir>/keyframes.sqlite, in WAL mode: each put is one transaction that either
// happens completely or not at all, also under kill -9. SQLite rather than files of our own: WAL
// gives atomic, crash-safe commits in a single file per store, and a widely used, well-tested
// library is far less likely to lose data than hand-written file formats and fsync sequences.
//
// Bounded: the sum of the payloads (colour + depth bytes) never exceeds max_bytes. When a new
// keyframe would not fit it is refused (kFull, counted); keyframes already stored are never
// dropped to make room (reopened with a smaller budget than it holds, it keeps everything and
// refuses new ones). A failed write (disk full, folder turned read-only, I/O error) is
// reported (kError, counted, last_error) and leaves the previous state intact and readable.
//
// Threads: one SQLite connection guarded by a member mutex, so every operation is serialised.
// A put of ~90 KB holds it for ~0.1 ms, but the put that fills the WAL to 4 MB (about every 45th
// of that size) also checkpoints: it copies the WAL into the file and fsyncs both, 15-20 ms
// typically and up to ~0.4 s on a slow disk. Call put from a thread that may wait (a dense or
// store thread, not SLAM's). stats() takes only a second small mutex and never waits for I/O.
// The file is locked exclusively while a store object has it open: a second process (another
// server on the same --state-dir) gets a clear error instead of a shared, diverging file.
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "codec/encoded_rgbd.h"
#include "core/ids.h"
#include "geometry/camera.h"

struct sqlite3;
struct sqlite3_stmt;

namespace cslam::server {

struct KeyframeRecord {
  KeyFrameId id;                 // carries the client
  double timestamp = 0;          // colour image capture time (s)
  double depth_time_offset = 0;  // depth capture time relative to colour (s)
  EncodedRgbd images;
};

struct KeyframeStoreConfig {
  std::string dir;                          // the file is dir/keyframes.sqlite (created with its folder)
  std::uint64_t max_bytes = 4096ull << 20;  // payload budget (--dense-store-max-mb)
  // Throws ConfigError: empty dir, max_bytes of 0 or above kMaxStoreBytes.
  void validate() const;
};

// Largest accepted budget (1 TiB) and largest accepted image blob (256 MiB: a raw BGR8 image of
// 8192 x 8192 is 192 MiB; the network's messages are far smaller). A record whose blobs are larger
// is refused on put (kError) and reported as corrupt on read; SQLite itself is told to never build
// a value larger than a record may be (SQLITE_LIMIT_LENGTH), so a damaged file cannot make a read
// allocate more than that.
constexpr std::uint64_t kMaxStoreBytes = 1ull << 40;
constexpr std::uint64_t kMaxImageBlobBytes = 256ull << 20;

enum class PutStatus { kStored, kAlreadyStored, kFull, kError };
const char* to_string(PutStatus status);

struct KeyframeStoreStats {
  // What the file holds (refreshed on open, kept up to date by put and erase).
  std::uint64_t keyframes = 0, payload_bytes = 0;
  std::uint64_t file_bytes = 0;  // keyframes.sqlite + its -wal file, as on disk now
  std::uint64_t max_bytes = 0;
  // Operations of this store object since it was opened (like every counter of the server, they
  // start at 0 with the process).
  std::uint64_t stored = 0, refused_full = 0, errors = 0, erased = 0;
  std::string last_error;  // empty when the last write succeeded
};

class KeyframeStore {
 public:
  // Opens dir/keyframes.sqlite, or creates it (and dir). Throws ConfigError on a bad config, and
  // InputError (one line: the path and the reason) if the folder cannot be created or written,
  // the file is not an SQLite database, is not a keyframe store, has another schema version, is
  // damaged, or is in use by another process.
  explicit KeyframeStore(KeyframeStoreConfig config);
  ~KeyframeStore();
  KeyframeStore(const KeyframeStore&) = delete;
  KeyframeStore& operator=(const KeyframeStore&) = delete;

  // Stores a keyframe's images, one transaction. kAlreadyStored if the id is already there (a
  // keyframe's images never change; the stored ones are kept). kFull if payload_bytes plus this
  // record's bytes would exceed max_bytes. kError on any failure to write (disk full, read-only,
  // I/O error) or on a record that cannot be stored (an image blob over kMaxImageBlobBytes):
  // counted, last_error set, previous state intact. Never throws on those.
  PutStatus put(const KeyframeRecord& record);

  // Stores (or replaces) a client's camera: every field, exactly (doubles round-trip bit for bit,
  // -0.0 included; a NaN comes back as a NaN). false on a failed write (counted, last_error).
  bool put_camera(ClientId client, const PinholeCamera& camera);
  // Throws InputError naming the file if the stored camera is unreadable.
  std::optional<PinholeCamera> camera(ClientId client) const;

  // Removes a keyframe (culled by local mapping). false if absent, or on a failed write (counted,
  // last_error). Its space is reused by later puts; the file does not shrink.
  bool erase(KeyFrameId id);

  // nullopt if absent. Throws InputError naming the file and the keyframe if its row is
  // damaged (bad codec value, blob over the limits, wrong types) or cannot be read.
  std::optional<KeyframeRecord> get(KeyFrameId id) const;
  // Every stored keyframe, sorted. Throws InputError naming the file if it cannot be read.
  std::vector<KeyFrameId> ids() const;

  KeyframeStoreStats stats() const;
  const std::string& path() const { return path_; }

 private:
  struct Statements;
  void open_or_create();
  void refresh_counters();  // from the file; caller holds mutex_
  std::string db_error(int rc) const;
  std::string folder_not_writable() const;  // "" if it is writable
  void record_error(const std::string& what) const;
  void record_success();

  const KeyframeStoreConfig config_;
  const std::string path_;
  mutable std::mutex mutex_;  // the connection and its statements
  sqlite3* db_ = nullptr;
  std::unique_ptr<Statements> st_;
  mutable std::mutex stats_mutex_;  // taken after mutex_ when both are held
  mutable KeyframeStoreStats stats_;
};

}  // namespace cslam::server
