#include "server/dense/keyframe_store.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <utility>

#include <sqlite3.h>
#include <unistd.h>

#include "core/error.h"
#include "core/log.h"

namespace cslam::server {

namespace {

constexpr const char* kFileName = "keyframes.sqlite";
// PRAGMA application_id: "CSKF", so a store is told apart from any other SQLite file.
constexpr std::int32_t kApplicationId = 0x43534B46;
// PRAGMA user_version: the schema below. A file of another version is refused, never guessed at.
constexpr int kSchemaVersion = 1;
// A camera's name is free text from the client; no real one comes near this.
constexpr int kMaxCameraNameBytes = 4096;
// KeyFrameId::packed() is client (16 bits) << 32 | seq (32 bits).
constexpr std::int64_t kMaxPackedId = (std::int64_t(1) << 48) - 1;

// Numeric columns are declared without a type on purpose: SQLite stores a whole-number double of
// a REAL column as an integer on disk, which turns -0.0 into 0.0. Untyped columns keep the 8 bytes
// of every double as given (a NaN, which SQLite cannot store, is written as NULL and read back as
// a NaN). Codecs are stored by name ("jpeg", "zstd") so the file does not depend on enum order.
constexpr const char* kSchema = R"sql(
CREATE TABLE keyframes(
  id INTEGER PRIMARY KEY,        -- KeyFrameId::packed(): client << 32 | seq
  timestamp,                     -- colour capture time (s)
  depth_time_offset,             -- depth capture time - colour capture time (s)
  rgb_codec TEXT NOT NULL,
  depth_codec TEXT NOT NULL,
  rgb BLOB NOT NULL,             -- as received, never re-encoded
  depth BLOB NOT NULL
);
CREATE TABLE cameras(
  client INTEGER PRIMARY KEY,
  fx, fy, cx, cy, k1, k2, p1, p2, k3,
  width INTEGER NOT NULL, height INTEGER NOT NULL,
  depth_factor, depth_scale_correction, readout_time,
  name TEXT NOT NULL
);
)sql";

std::string hex32(std::int64_t v) {
  std::ostringstream os;
  os << "0x" << std::hex << (std::uint32_t(v) & 0xffffffffu);
  return os.str();
}

std::string kf_text(KeyFrameId id) {
  std::ostringstream os;
  os << id;
  return os.str();
}

KeyFrameId unpack(std::int64_t packed) {
  KeyFrameId id;
  id.client = ClientId(std::uint64_t(packed) >> 32);
  id.seq = std::uint32_t(std::uint64_t(packed) & 0xffffffffu);
  return id;
}

// Resets a statement (and its bindings) whatever way the caller leaves.
class Use {
 public:
  explicit Use(sqlite3_stmt* s) : s_(s) {}
  ~Use() {
    sqlite3_reset(s_);
    sqlite3_clear_bindings(s_);
  }
  Use(const Use&) = delete;
  Use& operator=(const Use&) = delete;
  sqlite3_stmt* get() const { return s_; }

 private:
  sqlite3_stmt* s_;
};

// A column read as a double: a REAL (or an INTEGER, if someone edited the file by hand) as is, a
// NULL as the NaN it was written from. Anything else is damage.
bool column_double(sqlite3_stmt* s, int col, double& out) {
  switch (sqlite3_column_type(s, col)) {
    case SQLITE_FLOAT:
      out = sqlite3_column_double(s, col);
      return true;
    case SQLITE_INTEGER:
      out = double(sqlite3_column_int64(s, col));
      return true;
    case SQLITE_NULL:
      out = std::numeric_limits<double>::quiet_NaN();
      return true;
    default:
      return false;
  }
}

// A blob column copied into `out` after checking its type and size (never above kMaxImageBlobBytes).
bool column_blob(sqlite3_stmt* s, int col, std::string& out, std::string& why) {
  if (sqlite3_column_type(s, col) != SQLITE_BLOB) {
    why = "column " + std::string(sqlite3_column_name(s, col)) + " is not a blob";
    return false;
  }
  const void* data = sqlite3_column_blob(s, col);
  const int n = sqlite3_column_bytes(s, col);
  if (n < 0 || std::uint64_t(n) > kMaxImageBlobBytes) {
    why = "column " + std::string(sqlite3_column_name(s, col)) + " has " + std::to_string(n) +
          " bytes, over the limit of " + std::to_string(kMaxImageBlobBytes);
    return false;
  }
  if (n > 0 && !data) {
    why = "column " + std::string(sqlite3_column_name(s, col)) + " could not be read";
    return false;
  }
  out.assign(static_cast<const char*>(data), std::size_t(n));
  return true;
}

}  // namespace

const char* to_string(PutStatus status) {
  switch (status) {
    case PutStatus::kStored:
      return "stored";
    case PutStatus::kAlreadyStored:
      return "already stored";
    case PutStatus::kFull:
      return "full";
    case PutStatus::kError:
      return "error";
  }
  return "unknown";
}

void KeyframeStoreConfig::validate() const {
  if (dir.empty()) throw ConfigError("keyframe store: the folder is empty");
  if (max_bytes == 0) throw ConfigError("keyframe store: the budget (--dense-store-max-mb) must be positive");
  if (max_bytes > kMaxStoreBytes)
    throw ConfigError("keyframe store: the budget (--dense-store-max-mb) must be at most " +
                      std::to_string(kMaxStoreBytes >> 20) + " MiB");
}

struct KeyframeStore::Statements {
  sqlite3_stmt* exists = nullptr;
  sqlite3_stmt* insert = nullptr;
  sqlite3_stmt* select = nullptr;
  sqlite3_stmt* erase = nullptr;
  sqlite3_stmt* ids = nullptr;
  sqlite3_stmt* counters = nullptr;
  sqlite3_stmt* put_camera = nullptr;
  sqlite3_stmt* camera = nullptr;
  ~Statements() {
    for (sqlite3_stmt* s : {exists, insert, select, erase, ids, counters, put_camera, camera}) sqlite3_finalize(s);
  }
};

KeyframeStore::KeyframeStore(KeyframeStoreConfig config)
    : config_((config.validate(), std::move(config))),
      path_((std::filesystem::path(config_.dir) / kFileName).string()) {
  stats_.max_bytes = config_.max_bytes;
  try {
    open_or_create();
  } catch (...) {
    st_.reset();
    if (db_) sqlite3_close_v2(db_);
    db_ = nullptr;
    throw;
  }
  const auto s = stats();
  logger("dense")->info("keyframe store {}: {} keyframes, {:.1f} MB of images (budget {:.1f} MB), file {:.1f} MB",
                        path_, s.keyframes, s.payload_bytes / 1e6, s.max_bytes / 1e6, s.file_bytes / 1e6);
}

KeyframeStore::~KeyframeStore() {
  std::lock_guard<std::mutex> lock(mutex_);
  st_.reset();
  // Closing checkpoints the WAL into the file and removes it; if that fails (disk full), the WAL
  // stays and the next open replays it.
  if (db_) sqlite3_close_v2(db_);
}

std::string KeyframeStore::db_error(int rc) const {
  std::string text = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
  const int sys = db_ ? sqlite3_system_errno(db_) : 0;
  if (sys != 0) {
    text += std::string(" (") + std::strerror(sys) + ")";
  } else {
    // The extended code tells I/O errors apart (e.g. 778 = SQLITE_IOERR_WRITE, a write refused).
    const int code = db_ ? sqlite3_extended_errcode(db_) : rc;
    if (code != (code & 0xff)) text += " (SQLite code " + std::to_string(code) + ")";
  }
  return text;
}

std::string KeyframeStore::folder_not_writable() const {
  if (access(config_.dir.c_str(), W_OK) == 0) return "";
  return std::string("the folder is not writable (") + std::strerror(errno) + ")";
}

void KeyframeStore::open_or_create() {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(config_.dir, ec);
  if (ec) throw InputError(config_.dir, "cannot create the keyframe store's folder: " + ec.message());
  if (!fs::is_directory(config_.dir, ec)) throw InputError(config_.dir, "not a folder");
  if (fs::exists(path_, ec) && !fs::is_regular_file(path_, ec)) throw InputError(path_, "not a regular file");

  // NOMUTEX: the connection is only ever used under mutex_.
  int rc =
      sqlite3_open_v2(path_.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string folder = folder_not_writable();
    throw InputError(path_, "cannot open the keyframe store: " + (folder.empty() ? db_error(rc) : folder));
  }
  sqlite3_extended_result_codes(db_, 1);
  // No value SQLite builds, on read or write, may be larger than a record: a damaged length in the
  // file then gives SQLITE_TOOBIG instead of a huge allocation.
  sqlite3_limit(db_, SQLITE_LIMIT_LENGTH, int(2 * kMaxImageBlobBytes + (1 << 16)));

  auto fail = [&](const std::string& what, int code) -> InputError {
    const int primary = code & 0xff;
    if (primary == SQLITE_NOTADB) return InputError(path_, "not a keyframe store: " + db_error(code));
    if (primary == SQLITE_BUSY || primary == SQLITE_LOCKED)
      return InputError(path_, "the keyframe store is in use by another process (another server on the same folder?)");
    if (primary == SQLITE_READONLY || primary == SQLITE_CANTOPEN || primary == SQLITE_PERM) {
      const std::string folder = folder_not_writable();
      return InputError(path_, what + ": " + (folder.empty() ? db_error(code) : folder));
    }
    if (primary == SQLITE_CORRUPT) return InputError(path_, "damaged keyframe store: " + db_error(code));
    return InputError(path_, what + ": " + db_error(code));
  };
  auto exec = [&](const char* sql, const std::string& what) {
    const int r = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
    if (r != SQLITE_OK) {
      InputError e = fail(what, r);
      if (!sqlite3_get_autocommit(db_)) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
      throw e;
    }
  };
  auto pragma_int = [&](const char* sql, const std::string& what) -> std::int64_t {
    sqlite3_stmt* s = nullptr;
    int r = sqlite3_prepare_v2(db_, sql, -1, &s, nullptr);
    std::int64_t v = 0;
    if (r == SQLITE_OK) {
      r = sqlite3_step(s);
      if (r == SQLITE_ROW) {
        v = sqlite3_column_int64(s, 0);
        r = SQLITE_OK;
      }
    }
    sqlite3_finalize(s);
    if (r != SQLITE_OK) throw fail(what, r);
    return v;
  };

  if (sqlite3_db_readonly(db_, "main") == 1) {
    const std::string folder = folder_not_writable();
    throw InputError(path_, "the file is read-only" + (folder.empty() ? std::string() : ", " + folder));
  }
  // One process per store: the file stays locked while this object has it open (and the WAL index
  // lives in this process's memory, no -shm file). Must be set before WAL mode is first used.
  exec("PRAGMA locking_mode=EXCLUSIVE", "cannot open the keyframe store");

  // Checks what the file is before changing anything in it (the first read also replays a WAL
  // left by a process that was killed).
  const std::int64_t pages = pragma_int("PRAGMA page_count", "cannot read the keyframe store");
  const bool fresh = pages == 0;
  if (!fresh) {
    const std::int64_t app = pragma_int("PRAGMA application_id", "cannot read the keyframe store");
    const std::int64_t version = pragma_int("PRAGMA user_version", "cannot read the keyframe store");
    if (app != kApplicationId)
      throw InputError(path_, "not a keyframe store (an SQLite file with application_id " + hex32(app) + ", expected " +
                                  hex32(kApplicationId) + ")");
    if (version != kSchemaVersion)
      throw InputError(path_, "keyframe store of schema version " + std::to_string(version) +
                                  "; this server reads version " + std::to_string(kSchemaVersion) +
                                  " (move the file away to start a new store)");
  }

  // WAL: a commit appends the transaction's pages to the -wal file and marks it committed with a
  // checksummed commit frame; a reader (or the next open after a crash) ignores any frame after
  // the last complete commit. A kill -9 at any instant thus leaves the state of the last commit.
  // synchronous=NORMAL does not fsync on each commit, only at checkpoints: after a process crash
  // the committed frames are in the kernel's page cache and are replayed, so nothing committed is
  // lost. Only a power loss or kernel crash can lose the last commits (never consistency), and
  // keyframe images that are lost then are lost with the map snapshot's newest changes too.
  {
    sqlite3_stmt* s = nullptr;
    int r = sqlite3_prepare_v2(db_, "PRAGMA journal_mode=WAL", -1, &s, nullptr);
    std::string mode;
    if (r == SQLITE_OK && (r = sqlite3_step(s)) == SQLITE_ROW) {
      const unsigned char* t = sqlite3_column_text(s, 0);
      mode = t ? reinterpret_cast<const char*>(t) : "";
      r = SQLITE_OK;
    }
    sqlite3_finalize(s);
    if (r != SQLITE_OK) throw fail("cannot switch the keyframe store to WAL mode", r);
    if (mode != "wal")
      throw InputError(path_, "cannot switch the keyframe store to WAL mode (journal mode is '" + mode + "')");
  }
  exec("PRAGMA synchronous=NORMAL", "cannot configure the keyframe store");
  // After a checkpoint, a WAL that grew larger than this is truncated back.
  exec("PRAGMA journal_size_limit=67108864", "cannot configure the keyframe store");
  // Extra checks of each page as it is read (cheap): damage is reported, not followed.
  exec("PRAGMA cell_size_check=ON", "cannot configure the keyframe store");

  if (fresh) {
    const std::string sql = std::string("BEGIN IMMEDIATE;") + kSchema +
                            "PRAGMA application_id=" + std::to_string(kApplicationId) +
                            ";PRAGMA user_version=" + std::to_string(kSchemaVersion) + ";COMMIT;";
    exec(sql.c_str(), "cannot create the keyframe store");
  } else {
    // Takes the exclusive lock now rather than at the first put.
    exec("BEGIN IMMEDIATE; COMMIT;", "cannot lock the keyframe store");
  }

  st_ = std::make_unique<Statements>();
  auto prepare = [&](const char* sql, sqlite3_stmt** out) {
    const int r = sqlite3_prepare_v3(db_, sql, -1, SQLITE_PREPARE_PERSISTENT, out, nullptr);
    if (r != SQLITE_OK) throw InputError(path_, "damaged keyframe store: " + db_error(r));
  };
  prepare("SELECT 1 FROM keyframes WHERE id = ?1", &st_->exists);
  prepare(
      "INSERT INTO keyframes(id, timestamp, depth_time_offset, rgb_codec, depth_codec, rgb, depth) "
      "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7)",
      &st_->insert);
  prepare("SELECT timestamp, depth_time_offset, rgb_codec, depth_codec, rgb, depth FROM keyframes WHERE id = ?1",
          &st_->select);
  prepare("DELETE FROM keyframes WHERE id = ?1 RETURNING length(rgb) + length(depth)", &st_->erase);
  prepare("SELECT id FROM keyframes ORDER BY id", &st_->ids);
  // length() of a blob reads the row's header only, not its pages of image bytes.
  prepare("SELECT count(*), coalesce(sum(length(rgb) + length(depth)), 0) FROM keyframes", &st_->counters);
  prepare(
      "INSERT OR REPLACE INTO cameras(client, fx, fy, cx, cy, k1, k2, p1, p2, k3, width, height, depth_factor, "
      "depth_scale_correction, readout_time, name) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, "
      "?15, ?16)",
      &st_->put_camera);
  prepare(
      "SELECT fx, fy, cx, cy, k1, k2, p1, p2, k3, width, height, depth_factor, depth_scale_correction, readout_time, "
      "name "
      "FROM cameras WHERE client = ?1",
      &st_->camera);

  std::lock_guard<std::mutex> lock(mutex_);
  refresh_counters();
}

void KeyframeStore::refresh_counters() {
  Use use(st_->counters);
  const int rc = sqlite3_step(use.get());
  if (rc != SQLITE_ROW) throw InputError(path_, "cannot count the stored keyframes: " + db_error(rc));
  const std::int64_t n = sqlite3_column_int64(use.get(), 0), bytes = sqlite3_column_int64(use.get(), 1);
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.keyframes = std::uint64_t(std::max<std::int64_t>(n, 0));
  stats_.payload_bytes = std::uint64_t(std::max<std::int64_t>(bytes, 0));
}

void KeyframeStore::record_error(const std::string& what) const {
  bool first = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.errors;
    first = stats_.last_error.empty();
    stats_.last_error = what;
  }
  // Once per run of failures (a full disk fails every put until it is freed).
  if (first) logger("dense")->warn("{} (further failures are counted, not logged, until a write succeeds)", what);
}

void KeyframeStore::record_success() {
  bool recovered = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    recovered = !stats_.last_error.empty();
    stats_.last_error.clear();
  }
  if (recovered) logger("dense")->info("keyframe store {}: writes succeed again", path_);
}

PutStatus KeyframeStore::put(const KeyframeRecord& record) {
  const EncodedRgbd& im = record.images;
  const std::string id_text = kf_text(record.id);
  const std::string rgb_codec = to_string(im.rgb_codec), depth_codec = to_string(im.depth_codec);
  if (rgb_codec == "unknown" || depth_codec == "unknown") {
    record_error(path_ + ": keyframe " + id_text + " not stored: unknown codec value");
    return PutStatus::kError;
  }
  if (im.rgb.size() > kMaxImageBlobBytes || im.depth.size() > kMaxImageBlobBytes) {
    record_error(path_ + ": keyframe " + id_text + " not stored: an image of " +
                 std::to_string(std::max(im.rgb.size(), im.depth.size())) + " bytes is over the limit of " +
                 std::to_string(kMaxImageBlobBytes));
    return PutStatus::kError;
  }
  const std::uint64_t bytes = im.bytes();

  std::lock_guard<std::mutex> lock(mutex_);
  // Called with the failed statement reset (its Use gone), the error text taken before.
  auto fail = [&](const std::string& why) {
    // SQLite rolls a failed statement back itself, and after some errors (disk full, I/O) the whole
    // transaction; a single INSERT is its own transaction, so this is only a safeguard.
    if (!sqlite3_get_autocommit(db_)) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    try {
      refresh_counters();  // what the file holds now, whatever the failure left
    } catch (const std::exception&) {
    }
    record_error(path_ + ": keyframe " + id_text + " not stored: " + why);
    return PutStatus::kError;
  };
  std::string why;
  {
    Use use(st_->exists);
    sqlite3_bind_int64(use.get(), 1, std::int64_t(record.id.packed()));
    const int rc = sqlite3_step(use.get());
    if (rc == SQLITE_ROW) return PutStatus::kAlreadyStored;
    if (rc != SQLITE_DONE) why = db_error(rc);
  }
  if (!why.empty()) return fail(why);
  {
    std::unique_lock<std::mutex> s(stats_mutex_);
    if (stats_.payload_bytes + bytes > config_.max_bytes) {
      const bool first = stats_.refused_full++ == 0;
      const std::uint64_t held = stats_.payload_bytes;
      s.unlock();
      if (first)
        logger("dense")->warn(
            "keyframe store {} is full ({} of {} bytes of images): new keyframes' images are refused, "
            "stored ones are kept (--dense-store-max-mb)",
            path_, held, config_.max_bytes);
      return PutStatus::kFull;
    }
  }
  {
    Use use(st_->insert);
    sqlite3_stmt* s = use.get();
    sqlite3_bind_int64(s, 1, std::int64_t(record.id.packed()));
    sqlite3_bind_double(s, 2, record.timestamp);
    sqlite3_bind_double(s, 3, record.depth_time_offset);
    sqlite3_bind_text(s, 4, rgb_codec.c_str(), int(rgb_codec.size()), SQLITE_STATIC);
    sqlite3_bind_text(s, 5, depth_codec.c_str(), int(depth_codec.size()), SQLITE_STATIC);
    // data() of an empty string is not null: an empty image is stored as an empty blob, not NULL.
    sqlite3_bind_blob64(s, 6, im.rgb.data(), im.rgb.size(), SQLITE_STATIC);
    sqlite3_bind_blob64(s, 7, im.depth.data(), im.depth.size(), SQLITE_STATIC);
    const int rc = sqlite3_step(s);
    if (rc != SQLITE_DONE) why = db_error(rc);
  }
  if (!why.empty()) return fail(why);
  {
    std::lock_guard<std::mutex> s(stats_mutex_);
    ++stats_.keyframes;
    stats_.payload_bytes += bytes;
    ++stats_.stored;
  }
  record_success();
  return PutStatus::kStored;
}

bool KeyframeStore::put_camera(ClientId client, const PinholeCamera& c) {
  if (c.name.size() > std::size_t(kMaxCameraNameBytes)) {
    record_error(path_ + ": camera of client " + std::to_string(client) + " not stored: name over " +
                 std::to_string(kMaxCameraNameBytes) + " bytes");
    return false;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  Use use(st_->put_camera);
  sqlite3_stmt* s = use.get();
  sqlite3_bind_int64(s, 1, client);
  const double values[] = {c.fx, c.fy, c.cx, c.cy, c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]};
  for (int i = 0; i < 9; ++i) sqlite3_bind_double(s, 2 + i, values[i]);
  sqlite3_bind_int64(s, 11, c.width);
  sqlite3_bind_int64(s, 12, c.height);
  sqlite3_bind_double(s, 13, c.depth_factor);
  sqlite3_bind_double(s, 14, c.depth_scale_correction);
  sqlite3_bind_double(s, 15, c.readout_time);
  sqlite3_bind_text(s, 16, c.name.c_str(), int(c.name.size()), SQLITE_STATIC);
  const int rc = sqlite3_step(s);
  if (rc != SQLITE_DONE) {
    const std::string why = db_error(rc);
    sqlite3_reset(s);
    if (!sqlite3_get_autocommit(db_)) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    record_error(path_ + ": camera of client " + std::to_string(client) + " not stored: " + why);
    return false;
  }
  record_success();
  return true;
}

std::optional<PinholeCamera> KeyframeStore::camera(ClientId client) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Use use(st_->camera);
  sqlite3_stmt* s = use.get();
  sqlite3_bind_int64(s, 1, client);
  const int rc = sqlite3_step(s);
  if (rc == SQLITE_DONE) return std::nullopt;
  const std::string what = "camera of client " + std::to_string(client);
  if (rc != SQLITE_ROW) {
    const std::string msg = what + " unreadable: " + db_error(rc);
    record_error(path_ + ": " + msg);
    throw InputError(path_, msg);
  }
  PinholeCamera c;
  double* fields[] = {&c.fx, &c.fy, &c.cx, &c.cy, &c.dist[0], &c.dist[1], &c.dist[2], &c.dist[3], &c.dist[4]};
  bool ok = true;
  for (int i = 0; i < 9; ++i) ok = ok && column_double(s, i, *fields[i]);
  ok = ok && sqlite3_column_type(s, 9) == SQLITE_INTEGER && sqlite3_column_type(s, 10) == SQLITE_INTEGER;
  const std::int64_t w = sqlite3_column_int64(s, 9), h = sqlite3_column_int64(s, 10);
  ok = ok && w >= std::numeric_limits<int>::min() && w <= std::numeric_limits<int>::max() &&
       h >= std::numeric_limits<int>::min() && h <= std::numeric_limits<int>::max();
  ok = ok && column_double(s, 11, c.depth_factor) && column_double(s, 12, c.depth_scale_correction) &&
       column_double(s, 13, c.readout_time);
  ok = ok && sqlite3_column_type(s, 14) == SQLITE_TEXT && sqlite3_column_bytes(s, 14) <= kMaxCameraNameBytes;
  if (!ok) {
    const std::string msg = what + " is damaged (wrong column types or sizes)";
    record_error(path_ + ": " + msg);
    throw InputError(path_, msg);
  }
  c.width = int(w);
  c.height = int(h);
  const unsigned char* name = sqlite3_column_text(s, 14);
  c.name.assign(name ? reinterpret_cast<const char*>(name) : "", std::size_t(sqlite3_column_bytes(s, 14)));
  return c;
}

bool KeyframeStore::erase(KeyFrameId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::int64_t bytes = -1;
  std::string why;
  {
    Use use(st_->erase);
    sqlite3_stmt* s = use.get();
    sqlite3_bind_int64(s, 1, std::int64_t(id.packed()));
    int rc;
    while ((rc = sqlite3_step(s)) == SQLITE_ROW) bytes = sqlite3_column_int64(s, 0);
    if (rc != SQLITE_DONE) why = db_error(rc);
  }
  if (!why.empty()) {
    if (!sqlite3_get_autocommit(db_)) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    try {
      refresh_counters();
    } catch (const std::exception&) {
    }
    record_error(path_ + ": keyframe " + kf_text(id) + " not erased: " + why);
    return false;
  }
  if (bytes < 0) return false;  // absent
  {
    std::lock_guard<std::mutex> st(stats_mutex_);
    if (stats_.keyframes > 0) --stats_.keyframes;
    stats_.payload_bytes -= std::min<std::uint64_t>(stats_.payload_bytes, std::uint64_t(bytes));
    ++stats_.erased;
  }
  record_success();
  return true;
}

std::optional<KeyframeRecord> KeyframeStore::get(KeyFrameId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Use use(st_->select);
  sqlite3_stmt* s = use.get();
  sqlite3_bind_int64(s, 1, std::int64_t(id.packed()));
  const int rc = sqlite3_step(s);
  if (rc == SQLITE_DONE) return std::nullopt;
  const std::string what = "keyframe " + kf_text(id);
  auto damaged = [&](const std::string& why) {
    record_error(path_ + ": " + what + " unreadable: " + why);
    return InputError(path_, what + " unreadable: " + why);
  };
  if (rc != SQLITE_ROW) throw damaged(db_error(rc));
  KeyframeRecord r;
  r.id = id;
  if (!column_double(s, 0, r.timestamp) || !column_double(s, 1, r.depth_time_offset))
    throw damaged("capture times are not numbers");
  if (sqlite3_column_type(s, 2) != SQLITE_TEXT || sqlite3_column_type(s, 3) != SQLITE_TEXT)
    throw damaged("codec names are not text");
  try {
    r.images.rgb_codec = parse_rgb_codec(reinterpret_cast<const char*>(sqlite3_column_text(s, 2)));
    r.images.depth_codec = parse_depth_codec(reinterpret_cast<const char*>(sqlite3_column_text(s, 3)));
  } catch (const ConfigError& e) {
    throw damaged(e.what());
  }
  std::string why;
  if (!column_blob(s, 4, r.images.rgb, why) || !column_blob(s, 5, r.images.depth, why)) throw damaged(why);
  return r;
}

std::vector<KeyFrameId> KeyframeStore::ids() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Use use(st_->ids);
  sqlite3_stmt* s = use.get();
  std::vector<KeyFrameId> out;
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    const std::int64_t packed = sqlite3_column_int64(s, 0);
    if (packed < 0 || packed > kMaxPackedId) {
      const std::string msg = "damaged keyframe store: keyframe id " + std::to_string(packed) + " out of range";
      record_error(path_ + ": " + msg);
      throw InputError(path_, msg);
    }
    out.push_back(unpack(packed));
  }
  if (rc != SQLITE_DONE) {
    const std::string msg = "cannot list the stored keyframes: " + db_error(rc);
    record_error(path_ + ": " + msg);
    throw InputError(path_, msg);
  }
  return out;  // ORDER BY packed id == (client, seq) order
}

KeyframeStoreStats KeyframeStore::stats() const {
  KeyframeStoreStats out;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    out = stats_;
  }
  std::error_code ec;
  const auto db = std::filesystem::file_size(path_, ec);
  if (!ec) out.file_bytes += db;
  const auto wal = std::filesystem::file_size(path_ + "-wal", ec);
  if (!ec) out.file_bytes += wal;
  return out;
}

}  // namespace cslam::server
