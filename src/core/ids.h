#pragma once
// Identifiers that cross threads and the network are values that carry their client.
// Counters live on the map objects that hand them out, never in statics.
#include <cstdint>
#include <functional>
#include <ostream>

namespace cslam {

using ClientId = std::uint16_t;

// A typed (client, sequence) pair. Tag keeps KeyFrameId and MapPointId apart.
template <typename Tag>
struct ClientSeqId {
  ClientId client = 0;
  std::uint32_t seq = 0;

  friend bool operator==(ClientSeqId a, ClientSeqId b) { return a.client == b.client && a.seq == b.seq; }
  friend bool operator!=(ClientSeqId a, ClientSeqId b) { return !(a == b); }
  friend bool operator<(ClientSeqId a, ClientSeqId b) {
    return a.client != b.client ? a.client < b.client : a.seq < b.seq;
  }
  std::uint64_t packed() const { return (std::uint64_t(client) << 32) | seq; }
  friend std::ostream& operator<<(std::ostream& os, ClientSeqId id) {
    return os << Tag::prefix << id.client << ":" << id.seq;
  }
};

struct KeyFrameTag {
  static constexpr const char* prefix = "kf";
};
struct MapPointTag {
  static constexpr const char* prefix = "mp";
};
struct FrameTag {
  static constexpr const char* prefix = "f";
};

// Orders objects held by pointer (keyframes, map points) by their id, never by address: iteration
// order, and every result that depends on it, is then the same in every run of the same input.
struct ById {
  template <typename T>
  bool operator()(const T* a, const T* b) const {
    return a->id < b->id;
  }
};

// A fused group of maps (maps of one group share a frame), named after the map that founded it:
// client * 100 + the map's index within its client. Invalid (-1) until the map is registered.
class GroupId {
 public:
  GroupId() = default;
  static GroupId of_map(ClientId client, int map_index) { return GroupId(int(client) * 100 + map_index); }
  // A value read back from a snapshot, a request or a test (-1: none).
  static GroupId from_value(int value) { return GroupId(value); }
  int value() const { return value_; }
  bool valid() const { return value_ >= 0; }
  friend bool operator==(GroupId a, GroupId b) { return a.value_ == b.value_; }
  friend bool operator!=(GroupId a, GroupId b) { return a.value_ != b.value_; }
  friend bool operator<(GroupId a, GroupId b) { return a.value_ < b.value_; }
  friend std::ostream& operator<<(std::ostream& os, GroupId g) { return os << g.value_; }

 private:
  explicit GroupId(int value) : value_(value) {}
  int value_ = -1;
};

using KeyFrameId = ClientSeqId<KeyFrameTag>;
using MapPointId = ClientSeqId<MapPointTag>;
using FrameId = ClientSeqId<FrameTag>;

}  // namespace cslam

namespace std {
template <>
struct hash<cslam::GroupId> {
  size_t operator()(cslam::GroupId g) const noexcept { return std::hash<int>()(g.value()); }
};
template <typename Tag>
struct hash<cslam::ClientSeqId<Tag>> {
  size_t operator()(cslam::ClientSeqId<Tag> id) const noexcept { return std::hash<std::uint64_t>()(id.packed()); }
};
}  // namespace std
