#pragma once
// The one place that knows both the snapshot schema (snapshot.proto) and the SLAM library's
// state types (SystemState, MapState, FrameData). A snapshot file is a 32-byte header (magic
// "CSLAMSNP", format version, flags, payload length, CRC-32 of the payload) followed by the
// serialized Snapshot message; see docs/persistence.md.
#include <cstdint>
#include <string>

#include "core/error.h"
#include "system/system_state.h"

namespace cslam::snapshot {

constexpr std::uint32_t kFormatVersion = 1;
constexpr std::size_t kHeaderBytes = 32;

struct EncodeOptions {
  std::string producer = "cslam";
  std::uint32_t vocabulary_words = 0;
};

// What the header and the Snapshot header say (for cslam-map info).
struct FileInfo {
  std::uint32_t version = 0;
  std::uint64_t payload_bytes = 0;
  std::uint32_t crc32 = 0;
  std::string producer;
  double created_unix_s = 0;
  std::uint32_t vocabulary_words = 0;
};

// SystemState -> file bytes (header + payload).
std::string encode(const SystemState& state, const EncodeOptions& options = {});
// File bytes -> SystemState. Throws InputError(source, one line) on a truncated, corrupt,
// foreign or wrong-version file and on inconsistent contents; never crashes on any input.
// BoW vectors are left empty (ClientSlam::restore_state recomputes them with its vocabulary).
SystemState decode(const std::string& bytes, const std::string& source, FileInfo* info = nullptr);

// Reads a whole file (InputError naming it if it cannot be read) and decodes it.
SystemState read_file(const std::string& path, FileInfo* info = nullptr);

}  // namespace cslam::snapshot
