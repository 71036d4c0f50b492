// Snapshot files: crash-safe writes that never replace the last good snapshot, and fuzzed files
// (truncation at every 1/64, random bit flips, wrong version, foreign files) that always give a
// one-line error naming the file and never crash.
#include <csignal>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include "proto/snapshot_adapter.h"
#include "proto/snapshot_file.h"
#include "snapshot_fixture.h"

namespace cslam {
namespace {

const std::string& snapshot_bytes() {
  static const std::string bytes = [] {
    test::SnapshotScene s;
    ClientSlam a(s.info, s.config, s.vocabulary);
    test::feed_with_seq(a, 1, s.pairs(0, 30), 1);
    SystemState state;
    state.clients.push_back(a.export_state());
    return snapshot::encode(state);
  }();
  return bytes;
}

std::string file_bytes(const std::string& path) { return snapshot::read_bytes(path); }

void write_bytes(const std::string& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

// Decoding must throw an InputError whose message is one line naming the source.
void expect_clear_error(const std::string& bytes, const std::string& source,
                        const std::string& expect_in_message = "") {
  try {
    snapshot::decode(bytes, source);
    ADD_FAILURE() << "decoded a damaged snapshot (" << source << ")";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(source + ": ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    if (!expect_in_message.empty()) {
      EXPECT_NE(what.find(expect_in_message), std::string::npos) << what;
    }
  }
}

TEST(SnapshotFile, DecodesItsOwnEncoding) {
  const SystemState s = snapshot::decode(snapshot_bytes(), "good.snapshot");
  ASSERT_EQ(s.clients.size(), 1u);
  EXPECT_FALSE(s.clients[0].maps[0].keyframes.empty());
}

TEST(SnapshotFuzz, TruncationAtEvery64thIsAClearError) {
  const std::string& bytes = snapshot_bytes();
  for (int k = 0; k < 64; ++k) {
    const std::size_t n = bytes.size() * std::size_t(k) / 64;
    expect_clear_error(bytes.substr(0, n), "cut" + std::to_string(k) + ".snapshot");
  }
  expect_clear_error(bytes.substr(0, bytes.size() - 1), "last-byte.snapshot", "truncated");
}

TEST(SnapshotFuzz, RandomBitFlipsAreClearErrors) {
  const std::string& bytes = snapshot_bytes();
  std::mt19937_64 rng(18);
  for (int i = 0; i < 300; ++i) {
    std::string damaged = bytes;
    // A third of the flips in the 32-byte header, the rest anywhere.
    const std::size_t at = i % 3 == 0 ? rng() % snapshot::kHeaderBytes : rng() % damaged.size();
    damaged[at] = char(damaged[at] ^ (1 << (rng() % 8)));
    expect_clear_error(damaged, "flip" + std::to_string(i) + ".snapshot");
  }
}

TEST(SnapshotFuzz, WrongVersionAndForeignFiles) {
  std::string v2 = snapshot_bytes();
  v2[8] = 2;
  expect_clear_error(v2, "v2.snapshot", "version 2 is not supported");
  expect_clear_error("", "empty.snapshot", "not a cslam snapshot");
  expect_clear_error("\x89PNG\r\n\x1a\n0000000000000000000000000000", "image.png", "not a cslam snapshot");
  expect_clear_error("# timestamp tx ty tz qx qy qz qw\n1 0 0 0 0 0 0 1\n", "trajectory.txt", "not a cslam snapshot");
  // A valid header over a payload that is not a snapshot message.
  std::string foreign = snapshot_bytes().substr(0, snapshot::kHeaderBytes);
  expect_clear_error(foreign, "header-only.snapshot", "truncated");
}

TEST(SnapshotFile, ProgramsReportADamagedFileInOneLine) {
  test::TempDir dir("cslam_snapshot_cli");
  const std::string path = dir / "damaged.snapshot";
  write_bytes(path, snapshot_bytes().substr(0, snapshot_bytes().size() / 2));
  const auto r = test::run_program("cslam-map", "info " + path);
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find(path), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("truncated"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;

  const std::string good = dir / "good.snapshot";
  write_bytes(good, snapshot_bytes());
  const auto ok = test::run_program("cslam-map", "info " + good);
  EXPECT_EQ(ok.status, 0) << ok.output;
  EXPECT_NE(ok.output.find("client 1"), std::string::npos) << ok.output;
}

TEST(SnapshotFile, WriteKeepsThePreviousSnapshot) {
  test::TempDir dir("cslam_snapshot_write");
  const std::string state = dir / "state";
  snapshot::write_atomic(state, "first");
  snapshot::write_atomic(state, "second");
  EXPECT_EQ(file_bytes(snapshot::current_path(state)), "second");
  EXPECT_EQ(file_bytes(snapshot::previous_path(state)), "first");
  snapshot::write_atomic(state, "third");
  EXPECT_EQ(file_bytes(snapshot::current_path(state)), "third");
  EXPECT_EQ(file_bytes(snapshot::previous_path(state)), "second");
  EXPECT_FALSE(std::filesystem::exists(snapshot::current_path(state) + ".tmp"));
  EXPECT_EQ(*snapshot::newest_snapshot(state), snapshot::current_path(state));
  // Interrupted between the two renames of the very first write: only the previous one exists.
  std::filesystem::remove(snapshot::current_path(state));
  EXPECT_EQ(*snapshot::newest_snapshot(state), snapshot::previous_path(state));
}

TEST(SnapshotFile, AFailedWriteNeverReplacesTheLastGoodSnapshot) {
  test::TempDir dir("cslam_snapshot_full");
  const std::string state = dir / "state";
  snapshot::write_atomic(state, snapshot_bytes());
  // A full disk, as the process sees it: writes beyond 64 KiB fail (EFBIG instead of SIGXFSZ).
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit old{};
  getrlimit(RLIMIT_FSIZE, &old);
  rlimit small = old;
  small.rlim_cur = 64 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string error;
  try {
    snapshot::write_atomic(state, std::string(1 << 20, 'x'));
  } catch (const snapshot::WriteError& e) {
    error = e.what();
  }
  setrlimit(RLIMIT_FSIZE, &old);
  EXPECT_NE(error.find("map.snapshot.tmp"), std::string::npos) << error;
  EXPECT_NE(error.find("write failed"), std::string::npos) << error;
  EXPECT_EQ(file_bytes(snapshot::current_path(state)), snapshot_bytes());
  EXPECT_FALSE(std::filesystem::exists(snapshot::current_path(state) + ".tmp"));
  EXPECT_NO_THROW(snapshot::decode(file_bytes(snapshot::current_path(state)), "after-failure"));
}

}  // namespace
}  // namespace cslam
