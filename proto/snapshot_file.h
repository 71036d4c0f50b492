#pragma once
// Snapshot files in a state folder, written crash-safely (the LevelDB/SQLite/etcd protocol):
//   map.snapshot      the newest good snapshot
//   map.snapshot.prev the one before it (kept)
//   map.snapshot.tmp  being written
// write_atomic: write tmp, fsync it, hard-link the current file to .prev, rename tmp over the
// current file, fsync the folder. A failed or partial write (full disk, crash) never replaces the
// current file: it is either the old snapshot or the complete new one.
#include <optional>
#include <stdexcept>
#include <string>

namespace cslam::snapshot {

constexpr const char* kCurrentName = "map.snapshot";

// A snapshot could not be written (one line naming the file and the system error).
class WriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

std::string current_path(const std::string& dir);
std::string previous_path(const std::string& dir);

// Creates `dir` if needed and writes `bytes` as its current snapshot. Throws WriteError.
void write_atomic(const std::string& dir, const std::string& bytes);

// The snapshot to load at start: the current file, or the previous one if the current is missing
// (an interrupted first rename). nullopt when the folder holds no snapshot.
std::optional<std::string> newest_snapshot(const std::string& dir);

// Writes one file crash-safely (temp file in the same folder, fsync, rename, fsync folder).
void write_file_atomic(const std::string& path, const std::string& bytes);

// Reads a file's bytes; throws InputError naming it.
std::string read_bytes(const std::string& path);

}  // namespace cslam::snapshot
