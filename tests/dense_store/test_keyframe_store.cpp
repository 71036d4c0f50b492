// The server's keyframe RGB-D store (server/dense/keyframe_store.h): exact round trips, the
// payload budget, kill -9 at random points, a full disk (a file size limit, as tests/persistence
// does, and a real small tmpfs where mount namespaces are allowed), read-only folders, foreign and
// damaged files, concurrent readers and a writer. All fixtures are synthetic.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <mutex>
#include <random>
#include <thread>

#include <gtest/gtest.h>
#include <sched.h>
#include <sqlite3.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/run_program.h"
#include "core/error.h"
#include "server/dense/keyframe_store.h"

namespace cslam::server {
namespace {

namespace fs = std::filesystem;

std::string random_bytes(std::mt19937_64& rng, std::size_t n) {
  std::string s(n, '\0');
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const std::uint64_t v = rng();
    std::memcpy(&s[i], &v, 8);
  }
  for (; i < n; ++i) s[i] = char(rng());
  return s;
}

// A keyframe's record, the same every time for the same id: image sizes up to max_bytes in all
// (at least 1 byte each), every codec pair, capture times that are not round numbers.
KeyframeRecord make_record(KeyFrameId id, std::size_t max_bytes = 40000) {
  std::mt19937_64 rng(id.packed() * 0x9E3779B97F4A7C15ull + 12345);
  KeyframeRecord r;
  r.id = id;
  r.timestamp = 1305031102.175304 + id.seq / 30.0 + id.client * 1e-3;
  r.depth_time_offset = (int(id.seq % 7) - 3) * 3.3e-3;
  r.images.rgb_codec = RgbCodec(id.seq % 3);
  r.images.depth_codec = DepthCodec((id.seq / 3) % 4);
  const std::size_t total = 2 + rng() % max_bytes;
  const std::size_t rgb = 1 + rng() % (total - 1);
  r.images.rgb = random_bytes(rng, rgb);
  r.images.depth = random_bytes(rng, total - rgb);
  return r;
}

bool same_double(double a, double b) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::memcmp(&a, &b, sizeof a) == 0;  // bit for bit: -0.0 != 0.0
}

void expect_same(const KeyframeRecord& a, const KeyframeRecord& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_TRUE(same_double(a.timestamp, b.timestamp)) << a.timestamp << " vs " << b.timestamp;
  EXPECT_TRUE(same_double(a.depth_time_offset, b.depth_time_offset))
      << a.depth_time_offset << " vs " << b.depth_time_offset;
  EXPECT_EQ(a.images.rgb_codec, b.images.rgb_codec);
  EXPECT_EQ(a.images.depth_codec, b.images.depth_codec);
  EXPECT_TRUE(a.images.rgb == b.images.rgb)
      << a.id << ": rgb differs (" << a.images.rgb.size() << " vs " << b.images.rgb.size() << " bytes)";
  EXPECT_TRUE(a.images.depth == b.images.depth)
      << a.id << ": depth differs (" << a.images.depth.size() << " vs " << b.images.depth.size() << " bytes)";
}

void expect_same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  EXPECT_TRUE(same_double(a.fx, b.fx));
  EXPECT_TRUE(same_double(a.fy, b.fy));
  EXPECT_TRUE(same_double(a.cx, b.cx));
  EXPECT_TRUE(same_double(a.cy, b.cy));
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(same_double(a.dist[i], b.dist[i])) << "dist[" << i << "]";
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_TRUE(same_double(a.depth_factor, b.depth_factor));
  EXPECT_TRUE(same_double(a.depth_scale_correction, b.depth_scale_correction));
  EXPECT_TRUE(same_double(a.readout_time, b.readout_time));
  EXPECT_EQ(a.name, b.name);
}

KeyframeStoreConfig config_for(const std::string& dir, std::uint64_t max_bytes = 4096ull << 20) {
  KeyframeStoreConfig c;
  c.dir = dir;
  c.max_bytes = max_bytes;
  return c;
}

// The InputError a constructor throws (empty if none).
std::string open_error(const KeyframeStoreConfig& config) {
  try {
    KeyframeStore store(config);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Runs fn in a forked child; its gtest failures are reported by the child. Returns the child's
// exit code: 0 passed, 1 failed, 77 skipped.
int run_in_child(const std::function<void()>& fn) {
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid == 0) {
    try {
      fn();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "exception: " << e.what();
    }
    const int code = ::testing::Test::HasFailure() ? 1 : ::testing::Test::IsSkipped() ? 77 : 0;
    std::fflush(stdout);
    std::fflush(stderr);
    _exit(code);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// In a forked child: a private mount namespace (as root, or as a user through a user namespace),
// so tmpfs and read-only bind mounts can be made without touching the machine's mounts.
bool enter_private_mount_namespace(std::string& why) {
  const uid_t uid = geteuid();
  const gid_t gid = getegid();
  if (uid == 0) {
    if (unshare(CLONE_NEWNS) != 0) return why = std::string("unshare(CLONE_NEWNS): ") + std::strerror(errno), false;
  } else {
    if (unshare(CLONE_NEWUSER | CLONE_NEWNS) != 0)
      return why = std::string("unshare(CLONE_NEWUSER | CLONE_NEWNS): ") + std::strerror(errno), false;
    std::ofstream("/proc/self/setgroups") << "deny";
    std::ofstream("/proc/self/uid_map") << "0 " << uid << " 1";
    std::ofstream("/proc/self/gid_map") << "0 " << gid << " 1";
  }
  if (mount("none", "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0)
    return why = std::string("making / private: ") + std::strerror(errno), false;
  return true;
}

bool mount_tmpfs(const std::string& dir, const std::string& size, std::string& why) {
  if (mount("tmpfs", dir.c_str(), "tmpfs", 0, ("size=" + size).c_str()) != 0)
    return why = std::string("mount tmpfs: ") + std::strerror(errno), false;
  return true;
}

bool mount_read_only(const std::string& dir, std::string& why) {
  if (mount(dir.c_str(), dir.c_str(), nullptr, MS_BIND, nullptr) != 0 ||
      mount(nullptr, dir.c_str(), nullptr, MS_BIND | MS_REMOUNT | MS_RDONLY, nullptr) != 0)
    return why = std::string("read-only bind mount: ") + std::strerror(errno), false;
  return true;
}

// ---------------------------------------------------------------------------------------------

TEST(KeyframeStore, ConfigIsValidated) {
  EXPECT_THROW(KeyframeStore(config_for("")), ConfigError);
  test::TempDir dir("cslam_kfstore_config");
  EXPECT_THROW(KeyframeStore(config_for(dir.str(), 0)), ConfigError);
  EXPECT_THROW(KeyframeStore(config_for(dir.str(), kMaxStoreBytes + 1)), ConfigError);
  EXPECT_NO_THROW(KeyframeStore(config_for(dir.str(), 1)));
}

TEST(KeyframeStore, RecordsAndCamerasRoundTripExactlyAndSurviveReopening) {
  test::TempDir dir("cslam_kfstore_roundtrip");
  const std::string folder = dir / "nested/state";  // created with its parents
  std::vector<KeyFrameId> ids;
  for (ClientId c : {ClientId(65535), ClientId(0), ClientId(3)})
    for (std::uint32_t seq :
         {std::uint32_t(7), std::uint32_t(0), std::uint32_t(0xffffffffu), std::uint32_t(1), std::uint32_t(2),
          std::uint32_t(3), std::uint32_t(4), std::uint32_t(5), std::uint32_t(11), std::uint32_t(6)})
      ids.push_back({c, seq});
  std::vector<KeyframeRecord> records;
  for (KeyFrameId id : ids) records.push_back(make_record(id));
  // Edge values: empty images (decode is not the store's business), exact doubles.
  records[1].images.depth.clear();
  records[2].images.rgb.clear();
  records[3].timestamp = -0.0;
  records[3].depth_time_offset = std::numeric_limits<double>::denorm_min();
  records[4].timestamp = 1e300;
  records[4].depth_time_offset = -0.1;
  records[5].timestamp = 0.1 + 0.2;
  records[5].depth_time_offset = std::numeric_limits<double>::quiet_NaN();
  records[6].images.rgb.assign(1, '\0');
  records[6].images.depth = std::string("\0\0\xff", 3);

  PinholeCamera cam_a = camera_tum_fr1();
  cam_a.readout_time = 0.03;
  cam_a.name = "tum1 \xc3\xa9 'quoted'";
  PinholeCamera cam_b;
  cam_b.fx = 1.0 / 3.0;
  cam_b.fy = 600.0;  // whole number: must come back as a double, exactly
  cam_b.cx = -0.0;
  cam_b.cy = std::nextafter(240.0, 241.0);
  cam_b.dist = {-0.0, 1e-310, -2.5e-7, 0.0, 123456789.123456789};
  cam_b.width = 320;
  cam_b.height = 240;
  cam_b.depth_factor = 1000;
  cam_b.depth_scale_correction = 1.031;
  cam_b.name = "";

  std::uint64_t payload = 0;
  {
    KeyframeStore store(config_for(folder));
    EXPECT_EQ(store.path(), (fs::path(folder) / "keyframes.sqlite").string());
    EXPECT_TRUE(fs::exists(store.path()));
    EXPECT_TRUE(store.ids().empty());
    EXPECT_FALSE(store.get({0, 0}).has_value());
    EXPECT_FALSE(store.camera(0).has_value());
    for (const auto& r : records) {
      EXPECT_EQ(store.put(r), PutStatus::kStored) << r.id;
      payload += r.images.bytes();
    }
    // A keyframe's images never change: a second put keeps the first.
    KeyframeRecord other = make_record(records[0].id, 500);
    EXPECT_EQ(store.put(other), PutStatus::kAlreadyStored);
    EXPECT_TRUE(store.put_camera(1, cam_b));  // replaced below
    EXPECT_TRUE(store.put_camera(1, cam_a));
    EXPECT_TRUE(store.put_camera(65535, cam_b));

    auto sorted = ids;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(store.ids(), sorted);
    for (const auto& r : records) {
      auto got = store.get(r.id);
      ASSERT_TRUE(got.has_value()) << r.id;
      expect_same(*got, r);
    }
    expect_same_camera(*store.camera(1), cam_a);
    expect_same_camera(*store.camera(65535), cam_b);
    EXPECT_FALSE(store.camera(2).has_value());

    const auto s = store.stats();
    EXPECT_EQ(s.keyframes, records.size());
    EXPECT_EQ(s.payload_bytes, payload);
    EXPECT_EQ(s.stored, records.size());
    EXPECT_EQ(s.errors, 0u);
    EXPECT_EQ(s.refused_full, 0u);
    EXPECT_TRUE(s.last_error.empty());
    EXPECT_GE(s.file_bytes, payload);

    // Erase: culled keyframes go, and only once.
    EXPECT_TRUE(store.erase(records[0].id));
    EXPECT_FALSE(store.erase(records[0].id));
    EXPECT_FALSE(store.erase({42, 42}));
    EXPECT_FALSE(store.get(records[0].id).has_value());
    payload -= records[0].images.bytes();
    EXPECT_EQ(store.stats().keyframes, records.size() - 1);
    EXPECT_EQ(store.stats().payload_bytes, payload);
    EXPECT_EQ(store.stats().erased, 1u);
    EXPECT_EQ(store.stats().errors, 0u);
  }
  // Reopened: everything is there, the counters of what the file holds are restored, the
  // operation counters start again.
  KeyframeStore store(config_for(folder));
  const auto s = store.stats();
  EXPECT_EQ(s.keyframes, records.size() - 1);
  EXPECT_EQ(s.payload_bytes, payload);
  EXPECT_EQ(s.stored, 0u);
  EXPECT_EQ(s.erased, 0u);
  EXPECT_EQ(store.ids().size(), records.size() - 1);
  EXPECT_FALSE(store.get(records[0].id).has_value());
  for (std::size_t i = 1; i < records.size(); ++i) {
    auto got = store.get(records[i].id);
    ASSERT_TRUE(got.has_value()) << records[i].id;
    expect_same(*got, records[i]);
  }
  expect_same_camera(*store.camera(1), cam_a);
  expect_same_camera(*store.camera(65535), cam_b);
  // The erased id can be stored again.
  EXPECT_EQ(store.put(records[0]), PutStatus::kStored);
  expect_same(*store.get(records[0].id), records[0]);
}

TEST(KeyframeStore, BudgetRefusesNewKeyframesAndKeepsTheOldOnes) {
  test::TempDir dir("cslam_kfstore_budget");
  std::vector<KeyframeRecord> records;
  for (std::uint32_t i = 0; i < 30; ++i) records.push_back(make_record({1, i}, 20000));
  std::uint64_t first10 = 0;
  for (int i = 0; i < 10; ++i) first10 += records[i].images.bytes();
  const std::uint64_t budget = first10 + 1000;

  KeyframeStore store(config_for(dir.str(), budget));
  std::size_t stored = 0, full = 0;
  std::uint64_t payload = 0;
  std::vector<KeyFrameId> kept;
  for (const auto& r : records) {
    const PutStatus st = store.put(r);
    if (st == PutStatus::kStored) {
      ++stored;
      payload += r.images.bytes();
      kept.push_back(r.id);
      EXPECT_LE(payload, budget);
    } else {
      EXPECT_EQ(st, PutStatus::kFull) << r.id;
      EXPECT_GT(payload + r.images.bytes(), budget) << r.id << " was refused though it fits";
      ++full;
    }
  }
  EXPECT_GE(stored, 10u);
  EXPECT_GT(full, 0u);
  const auto s = store.stats();
  EXPECT_EQ(s.keyframes, stored);
  EXPECT_EQ(s.payload_bytes, payload);
  EXPECT_EQ(s.refused_full, full);
  EXPECT_EQ(s.errors, 0u);
  EXPECT_EQ(s.max_bytes, budget);
  EXPECT_LE(s.payload_bytes, s.max_bytes);
  // The first ten, stored before the budget ran out, are all there and untouched.
  EXPECT_EQ(store.ids(), kept);
  for (int i = 0; i < 10; ++i) expect_same(*store.get(records[i].id), records[i]);
  // An id already stored is reported as such even when full.
  EXPECT_EQ(store.put(records[0]), PutStatus::kAlreadyStored);
  // Erasing makes room again.
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(store.erase(records[i].id));
  KeyframeRecord small = make_record({2, 0}, 100);
  EXPECT_EQ(store.put(small), PutStatus::kStored);
}

TEST(KeyframeStore, KillNineLeavesACompletePrefix) {
  test::TempDir dir("cslam_kfstore_kill");
  std::mt19937 rng(20261126);
  std::uint32_t committed_before = 0;
  for (int round = 0; round < 6; ++round) {
    // The child carries on where the last one was killed: the store accumulates over rounds.
    std::uint32_t start = 0;
    {
      KeyframeStore store(config_for(dir.str()));
      start = std::uint32_t(store.stats().keyframes);
    }
    int fds[2];
    ASSERT_EQ(pipe(fds), 0);
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      close(fds[0]);
      try {
        KeyframeStore store(config_for(dir.str()));
        for (std::uint32_t i = start; i < start + 5000; ++i) {
          if (store.put(make_record({7, i}, 120000)) != PutStatus::kStored) _exit(2);
          const char one = 1;
          if (write(fds[1], &one, 1) != 1) _exit(3);  // i is committed
        }
      } catch (...) {
        _exit(4);
      }
      _exit(0);
    }
    close(fds[1]);
    // Waits for a random number of commits, then kills at a random instant (mid-put, mid-
    // checkpoint: ~40 records of up to 120 KB fill the 4 MB after which the WAL is checkpointed).
    const int wait_commits = 1 + int(rng() % 80);
    int seen = 0;
    char buf;
    while (seen < wait_commits && read(fds[0], &buf, 1) == 1) ++seen;
    std::this_thread::sleep_for(std::chrono::microseconds(rng() % 3000));
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    while (read(fds[0], &buf, 1) == 1) ++seen;  // commits reported before the kill
    close(fds[0]);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child ended by itself, status " << status;
    ASSERT_GE(seen, wait_commits);

    KeyframeStore store(config_for(dir.str()));
    const auto ids = store.ids();
    // A prefix: every reported commit is there, at most the one in flight more, nothing else.
    ASSERT_GE(ids.size(), std::size_t(start) + seen) << "round " << round;
    ASSERT_LE(ids.size(), std::size_t(start) + seen + 1) << "round " << round;
    std::uint64_t payload = 0;
    for (std::uint32_t i = 0; i < ids.size(); ++i) {
      ASSERT_EQ(ids[i], (KeyFrameId{7, i})) << "round " << round;
      const auto got = store.get(ids[i]);
      ASSERT_TRUE(got.has_value());
      expect_same(*got, make_record(ids[i], 120000));
      payload += got->images.bytes();
    }
    EXPECT_EQ(store.stats().keyframes, ids.size());
    EXPECT_EQ(store.stats().payload_bytes, payload);
    EXPECT_GT(ids.size(), committed_before);
    committed_before = std::uint32_t(ids.size());
  }
}

// The method of tests/persistence (SnapshotFile.AFailedWriteNeverReplacesTheLastGoodSnapshot):
// a file size limit makes every write beyond it fail, as on a full disk.
TEST(KeyframeStore, FailedWritesKeepTheStoredStateFileSizeLimit) {
  test::TempDir dir("cslam_kfstore_fsize");
  std::vector<KeyframeRecord> before;
  for (std::uint32_t i = 0; i < 20; ++i) before.push_back(make_record({1, i}, 60000));
  KeyframeStore store(config_for(dir.str()));
  for (const auto& r : before) ASSERT_EQ(store.put(r), PutStatus::kStored);

  std::uint64_t largest = 0;
  for (const char* suffix : {"", "-wal"}) {
    std::error_code ec;
    largest = std::max<std::uint64_t>(largest, fs::file_size(store.path() + suffix, ec));
  }
  auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit old{};
  getrlimit(RLIMIT_FSIZE, &old);
  rlimit small = old;
  small.rlim_cur = largest + 100 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::size_t failed = 0, stored_meanwhile = 0;
  std::vector<KeyframeRecord> meanwhile;
  for (std::uint32_t i = 0; i < 200 && failed < 5; ++i) {
    KeyframeRecord r = make_record({2, i}, 60000);
    const PutStatus st = store.put(r);
    if (st == PutStatus::kError)
      ++failed;
    else if (st == PutStatus::kStored)
      ++stored_meanwhile, meanwhile.push_back(r);
  }
  const auto s = store.stats();
  setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);

  ASSERT_EQ(failed, 5u) << "no write failed under a " << small.rlim_cur << "-byte file size limit";
  EXPECT_EQ(s.errors, failed);
  EXPECT_NE(s.last_error.find(store.path()), std::string::npos) << s.last_error;
  EXPECT_NE(s.last_error.find("not stored"), std::string::npos) << s.last_error;
  EXPECT_EQ(s.keyframes, before.size() + stored_meanwhile);
  // Everything stored before the failures is there, byte for byte.
  for (const auto& r : before) expect_same(*store.get(r.id), r);
  for (const auto& r : meanwhile) expect_same(*store.get(r.id), r);
  EXPECT_EQ(store.ids().size(), before.size() + stored_meanwhile);
  // Space again: writes work, the error is cleared.
  KeyframeRecord after = make_record({3, 0}, 60000);
  EXPECT_EQ(store.put(after), PutStatus::kStored);
  EXPECT_TRUE(store.stats().last_error.empty());
  EXPECT_EQ(store.stats().errors, failed);
  expect_same(*store.get(after.id), after);
}

// A real full disk: a 6 MB tmpfs filled by another file, in a private mount namespace.
TEST(KeyframeStore, FailedWritesKeepTheStoredStateFullTmpfs) {
  test::TempDir dir("cslam_kfstore_tmpfs");
  const int code = run_in_child([&] {
    std::string why;
    if (!enter_private_mount_namespace(why) || !mount_tmpfs(dir.str(), "6m", why)) GTEST_SKIP() << why;
    const std::string folder = dir / "state";
    const std::string ballast = dir / "ballast";
    std::vector<KeyframeRecord> before;
    for (std::uint32_t i = 0; i < 15; ++i) before.push_back(make_record({1, i}, 60000));
    auto fill_disk = [&] {
      std::ofstream f(ballast, std::ios::binary | std::ios::app);
      const std::string chunk(4096, 'b');
      for (int i = 0; i < 10000 && f.write(chunk.data(), chunk.size()); ++i) {
      }
      f.close();  // its last write fails: ENOSPC
    };
    auto check_before = [&](KeyframeStore& store) {
      for (const auto& r : before) {
        auto got = store.get(r.id);
        ASSERT_TRUE(got.has_value()) << r.id;
        expect_same(*got, r);
      }
    };
    {
      KeyframeStore store(config_for(folder));
      for (const auto& r : before) ASSERT_EQ(store.put(r), PutStatus::kStored);
      ASSERT_TRUE(store.put_camera(1, camera_tum_fr1()));
      fill_disk();
      int failed = 0;
      for (std::uint32_t i = 0; i < 10; ++i) failed += store.put(make_record({2, i}, 60000)) == PutStatus::kError;
      EXPECT_EQ(failed, 10);
      const auto s = store.stats();
      EXPECT_EQ(s.errors, 10u);
      EXPECT_EQ(s.keyframes, before.size());
      EXPECT_NE(s.last_error.find("full"), std::string::npos) << s.last_error;
      EXPECT_NE(s.last_error.find(store.path()), std::string::npos) << s.last_error;
      check_before(store);
      EXPECT_EQ(store.ids().size(), before.size());
      (void)store.erase({1, 0});  // a delete may or may not fit; it must not crash or lose anything else
      before.erase(
          std::remove_if(before.begin(), before.end(), [&](const KeyframeRecord& r) { return !store.get(r.id); }),
          before.end());
    }  // closed on a full disk: its checkpoint may fail, the WAL stays
    {
      // Reopened while still full: everything is readable, writes fail cleanly.
      KeyframeStore store(config_for(folder));
      EXPECT_EQ(store.stats().keyframes, before.size());
      check_before(store);
      EXPECT_TRUE(store.camera(1).has_value());
      EXPECT_EQ(store.put(make_record({2, 100}, 60000)), PutStatus::kError);
      // Space freed: writes work again.
      fs::remove(ballast);
      KeyframeRecord after = make_record({3, 0}, 60000);
      EXPECT_EQ(store.put(after), PutStatus::kStored);
      EXPECT_TRUE(store.stats().last_error.empty());
      before.push_back(after);
      check_before(store);
    }
    KeyframeStore store(config_for(folder));
    EXPECT_EQ(store.ids().size(), before.size());
    check_before(store);
  });
  if (code == 77) GTEST_SKIP() << "no private mount namespace here (the file size limit test covers the failure path)";
  EXPECT_EQ(code, 0);
}

TEST(KeyframeStore, ReadOnlyFolderGivesAClearError) {
  test::TempDir dir("cslam_kfstore_readonly");
  const std::string existing = dir / "existing";
  const KeyframeRecord r = make_record({1, 1});
  {
    KeyframeStore store(config_for(existing));
    ASSERT_EQ(store.put(r), PutStatus::kStored);
  }
  const std::string empty = dir / "empty";
  fs::create_directories(empty);
  const int code = run_in_child([&] {
    std::string why;
    // As root, permissions do not stop writes: a read-only bind mount does. As a user, chmod.
    if (geteuid() == 0) {
      if (!enter_private_mount_namespace(why) || !mount_read_only(dir.str(), why)) GTEST_SKIP() << why;
    } else {
      fs::permissions(empty, fs::perms::owner_read | fs::perms::owner_exec);
      fs::permissions(existing, fs::perms::owner_read | fs::perms::owner_exec);
      fs::permissions(dir.str(), fs::perms::owner_read | fs::perms::owner_exec);
    }
    const std::string e1 = open_error(config_for(dir / "new/sub"));
    EXPECT_NE(e1.find(dir / "new/sub"), std::string::npos) << e1;
    EXPECT_EQ(e1.find('\n'), std::string::npos) << e1;
    const std::string e2 = open_error(config_for(empty));
    EXPECT_NE(e2.find(empty), std::string::npos) << e2;
    EXPECT_NE(e2.find("not writable"), std::string::npos) << e2;
    const std::string e3 = open_error(config_for(existing));
    EXPECT_NE(e3.find(existing), std::string::npos) << e3;
    EXPECT_NE(e3.find("not writable"), std::string::npos) << e3;
    std::cout << "read-only errors:\n  " << e1 << "\n  " << e2 << "\n  " << e3 << "\n";
    if (geteuid() != 0) {
      fs::permissions(dir.str(), fs::perms::owner_all);
      fs::permissions(empty, fs::perms::owner_all);
      fs::permissions(existing, fs::perms::owner_all);
    }
  });
  if (code == 77) GTEST_SKIP() << "cannot make a read-only folder here";
  EXPECT_EQ(code, 0);
  // The existing store is untouched.
  KeyframeStore store(config_for(existing));
  expect_same(*store.get(r.id), r);
}

TEST(KeyframeStore, ForeignAndDamagedFilesGiveClearErrors) {
  test::TempDir dir("cslam_kfstore_foreign");
  // Writes into an SQLite file behind the store's back (another program's file, another version).
  auto run_sql = [](const std::string& path, const char* sql) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
    sqlite3_close(db);
  };
  auto expect_refused = [&](const std::string& folder, const std::string& expected) {
    const std::string e = open_error(config_for(folder));
    EXPECT_NE(e.find(folder), std::string::npos) << e;
    EXPECT_NE(e.find(expected), std::string::npos) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  };
  // Garbage bytes at the path.
  {
    const std::string folder = dir / "garbage";
    fs::create_directories(folder);
    std::mt19937_64 rng(1);
    std::ofstream(folder + "/keyframes.sqlite", std::ios::binary) << random_bytes(rng, 100000);
    expect_refused(folder, "not a keyframe store");
  }
  // Another program's SQLite file, and a store of another schema version.
  {
    const std::string folder = dir / "foreign";
    fs::create_directories(folder);
    run_sql(folder + "/keyframes.sqlite", "CREATE TABLE notes(text); INSERT INTO notes VALUES('hello');");
    expect_refused(folder, "not a keyframe store");
  }
  {
    const std::string folder = dir / "version";
    { KeyframeStore store(config_for(folder)); }
    run_sql(folder + "/keyframes.sqlite", "PRAGMA user_version=2;");
    expect_refused(folder, "schema version 2");
  }
  // A folder where the file should be, a file where the folder should be.
  {
    const std::string folder = dir / "dir_at_path";
    fs::create_directories(folder + "/keyframes.sqlite");
    expect_refused(folder, "not a regular file");
    const std::string file = dir / "plain_file";
    std::ofstream(file) << "x";
    EXPECT_NE(open_error(config_for(file)).find(file), std::string::npos);
  }
  // A damaged value in a row (edited by hand): get() reports it and names the keyframe.
  {
    const std::string folder = dir / "edited";
    {
      KeyframeStore store(config_for(folder));
      ASSERT_EQ(store.put(make_record({1, 1})), PutStatus::kStored);
      ASSERT_EQ(store.put(make_record({1, 2})), PutStatus::kStored);
    }
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((folder + "/keyframes.sqlite").c_str(), &db), SQLITE_OK);
    sqlite3_exec(
        db,
        "UPDATE keyframes SET rgb_codec='webp' WHERE id=(1<<32)+1; UPDATE keyframes SET depth=42 WHERE id=(1<<32)+2;",
        nullptr, nullptr, nullptr);
    sqlite3_close(db);
    KeyframeStore store(config_for(folder));
    for (std::uint32_t seq : {1u, 2u}) {
      try {
        store.get({1, seq});
        ADD_FAILURE() << "no error for kf1:" << seq;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("kf1:" + std::to_string(seq)), std::string::npos) << e.what();
      }
    }
    EXPECT_EQ(store.stats().errors, 2u);
  }
  // Truncated and bit-flipped stores: open refuses them, or reading reports damage; never a crash,
  // never an exception other than InputError.
  {
    const std::string good = dir / "good";
    {
      KeyframeStore store(config_for(good));
      for (std::uint32_t i = 0; i < 12; ++i) ASSERT_EQ(store.put(make_record({1, i}, 30000)), PutStatus::kStored);
      ASSERT_TRUE(store.put_camera(1, camera_tum_fr1()));
    }
    const std::string file = good + "/keyframes.sqlite";
    std::string original;
    {
      std::ifstream in(file, std::ios::binary);
      original.assign(std::istreambuf_iterator<char>(in), {});
    }
    ASSERT_GT(original.size(), 100000u);
    std::mt19937_64 rng(7);
    int refused = 0, damaged_reads = 0;
    for (int trial = 0; trial < 40; ++trial) {
      std::string damaged = original;
      const std::size_t pages = original.size() / 4096;
      if (trial < 16) {
        damaged.resize(original.size() * std::size_t(trial) / 16);
      } else if (trial < 28) {  // anywhere: mostly image bytes, which SQLite does not checksum
        for (int k = 0; k < 1 + trial % 8; ++k) damaged[rng() % damaged.size()] ^= char(1 << (rng() % 8));
      } else {  // b-tree page headers, cell pointers and overflow links (the first bytes of a page)
        for (int k = 0; k < 1 + trial % 4; ++k) damaged[(rng() % pages) * 4096 + rng() % 16] ^= char(1 << (rng() % 8));
      }
      const std::string folder = dir / ("damaged_" + std::to_string(trial));
      fs::create_directories(folder);
      std::ofstream(folder + "/keyframes.sqlite", std::ios::binary) << damaged;
      try {
        KeyframeStore store(config_for(folder));
        for (KeyFrameId id : store.ids()) {
          try {
            store.get(id);
          } catch (const InputError& e) {
            ++damaged_reads;
            EXPECT_NE(std::string(e.what()).find(folder), std::string::npos) << e.what();
          }
        }
        try {
          store.camera(1);
        } catch (const InputError&) {
        }
      } catch (const InputError& e) {
        ++refused;
        EXPECT_NE(std::string(e.what()).find(folder), std::string::npos) << e.what();
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      }
    }
    std::cout << "damaged stores: " << refused << " of 40 refused at open, " << damaged_reads
              << " damaged reads reported\n";
  }
}

TEST(KeyframeStore, SecondProcessIsRefusedWhileTheStoreIsOpen) {
  test::TempDir dir("cslam_kfstore_lock");
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  std::fflush(stdout);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    close(fds[0]);
    try {
      KeyframeStore store(config_for(dir.str()));
      store.put(make_record({1, 0}));
      const char one = 1;
      if (write(fds[1], &one, 1) != 1) _exit(3);
      pause();
    } catch (...) {
      _exit(4);
    }
    _exit(0);
  }
  close(fds[1]);
  char buf;
  ASSERT_EQ(read(fds[0], &buf, 1), 1);
  close(fds[0]);
  const std::string e = open_error(config_for(dir.str()));
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  EXPECT_NE(e.find("in use by another process"), std::string::npos) << e;
  KeyframeStore store(config_for(dir.str()));
  EXPECT_TRUE(store.get({1, 0}).has_value());
}

TEST(KeyframeStore, ConcurrentWriterAndReaders) {
  test::TempDir dir("cslam_kfstore_threads");
  KeyframeStore store(config_for(dir.str()));
  constexpr std::uint32_t kRecords = 400;
  std::atomic<bool> done{false};
  std::atomic<int> bad{0};
  std::atomic<std::uint64_t> reads{0};
  std::mutex read_mutex;
  std::condition_variable read_cv;
  // The writer puts every record and erases every 5th one soon after. Halfway it waits for a first
  // read, so that the readers read while it writes even when the machine is too loaded to start
  // them before it is through.
  std::thread writer([&] {
    for (std::uint32_t i = 0; i < kRecords; ++i) {
      if (i == kRecords / 2) {
        std::unique_lock<std::mutex> lock(read_mutex);
        read_cv.wait(lock, [&] { return reads.load() > 0; });
      }
      if (store.put(make_record({ClientId(i % 3), i}, 20000)) != PutStatus::kStored) ++bad;
      if (i % 5 == 4 && !store.erase({ClientId((i - 2) % 3), i - 2})) ++bad;
      if (i % 50 == 0) store.put_camera(ClientId(i % 3), camera_tum_fr1());
    }
    done = true;
  });
  std::vector<std::thread> readers;
  for (int t = 0; t < 3; ++t) {
    readers.emplace_back([&, t] {
      std::mt19937 rng(t);
      while (!done) {
        const auto ids = store.ids();
        if (!std::is_sorted(ids.begin(), ids.end())) ++bad;
        for (int k = 0; k < 5 && !ids.empty(); ++k) {
          const KeyFrameId id = ids[rng() % ids.size()];
          const auto got = store.get(id);  // may have been erased since ids()
          if (got) {
            const KeyframeRecord want = make_record(id, 20000);
            if (got->images.rgb != want.images.rgb || got->images.depth != want.images.depth ||
                got->timestamp != want.timestamp)
              ++bad;
          }
          {
            std::lock_guard<std::mutex> lock(read_mutex);
            ++reads;
          }
          read_cv.notify_all();
        }
        const auto s = store.stats();
        if (s.errors != 0 || s.payload_bytes > s.max_bytes) ++bad;
        store.camera(ClientId(t));
      }
    });
  }
  writer.join();
  for (auto& r : readers) r.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_GT(reads.load(), 0u);
  const auto ids = store.ids();
  std::uint64_t payload = 0;
  for (KeyFrameId id : ids) {
    EXPECT_NE(id.seq % 5, 2u) << id << " should have been erased";
    payload += store.get(id)->images.bytes();
  }
  EXPECT_EQ(ids.size(), kRecords - kRecords / 5);
  const auto s = store.stats();
  EXPECT_EQ(s.keyframes, ids.size());
  EXPECT_EQ(s.payload_bytes, payload);
  EXPECT_EQ(s.errors, 0u);
}

// Size on disk against the payload for keyframes of ~90 KB (the default codecs' frame size on
// TUM), and put latency. Figures are printed; only the size is checked.
TEST(KeyframeStore, BytesOnDiskAreThePayload) {
  test::TempDir dir("cslam_kfstore_size");
  constexpr int kRecords = 500;
  std::vector<double> ms;
  std::uint64_t payload = 0;
  {
    KeyframeStore store(config_for(dir.str()));
    std::mt19937_64 rng(3);
    for (int i = 0; i < kRecords; ++i) {
      KeyframeRecord r;
      r.id = {ClientId(i % 4), std::uint32_t(i)};
      r.timestamp = i / 30.0;
      r.images.rgb = random_bytes(rng, 35000 + rng() % 20000);    // JPEG q75, 640x480
      r.images.depth = random_bytes(rng, 40000 + rng() % 10000);  // zstd-delta depth
      payload += r.images.bytes();
      const auto t0 = std::chrono::steady_clock::now();
      ASSERT_EQ(store.put(r), PutStatus::kStored);
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    const auto s = store.stats();
    EXPECT_EQ(s.payload_bytes, payload);
    std::sort(ms.begin(), ms.end());
    std::cout << "keyframe store, " << kRecords << " keyframes of " << payload / kRecords << " bytes: file+wal "
              << s.file_bytes << " bytes, " << double(s.file_bytes) / payload << " x payload, "
              << (double(s.file_bytes) - payload) / kRecords << " bytes/keyframe over; put ms median "
              << ms[ms.size() / 2] << " min " << ms.front() << " max " << ms.back() << "\n";
    EXPECT_LT(double(s.file_bytes), 1.15 * double(payload));
  }
  KeyframeStore store(config_for(dir.str()));  // closed: WAL checkpointed into the file
  const auto s = store.stats();
  std::cout << "after reopening: file " << s.file_bytes << " bytes, " << double(s.file_bytes) / payload
            << " x payload, " << (double(s.file_bytes) - payload) / kRecords << " bytes/keyframe over\n";
  EXPECT_LT(double(s.file_bytes), 1.03 * double(payload));
}

}  // namespace
}  // namespace cslam::server
