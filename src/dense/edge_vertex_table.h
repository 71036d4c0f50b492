#pragma once
// The mesh vertex of each cube edge, by edge key, for TsdfVolume::extract_mesh: open addressing
// with linear probing in one array, no node per vertex (a mesh has hundreds of thousands). Keys
// never have the two top bits set, so ~0 marks an empty slot. Not thread-safe: one owner.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace cslam {

class EdgeVertexTable {
 public:
  explicit EdgeVertexTable(std::size_t expected) { slots_.assign(capacity_for(expected), {kEmpty, 0}); }
  // The vertex of `key`, or `vertex` stored as its vertex if it had none (then second is true).
  std::pair<std::uint32_t, bool> try_emplace(std::uint64_t key, std::uint32_t vertex) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    for (std::size_t i = slot_of(key);; i = (i + 1) & (slots_.size() - 1)) {
      Slot& s = slots_[i];
      if (s.key == key) return {s.vertex, false};
      if (s.key == kEmpty) {
        s = {key, vertex};
        ++size_;
        return {vertex, true};
      }
    }
  }
  std::size_t size() const { return size_; }

 private:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t(0);
  struct Slot {
    std::uint64_t key;
    std::uint32_t vertex;
  };
  static std::size_t capacity_for(std::size_t expected) {
    std::size_t c = 1024;
    while (c < 2 * expected) c *= 2;
    return c;
  }
  std::size_t slot_of(std::uint64_t key) const {
    return std::size_t((key * 0x9E3779B97F4A7C15ull) >> 32) & (slots_.size() - 1);
  }
  void grow() {
    std::vector<Slot> old(2 * slots_.size(), {kEmpty, 0});
    old.swap(slots_);
    size_ = 0;
    for (const Slot& s : old)
      if (s.key != kEmpty) try_emplace(s.key, s.vertex);
  }
  std::vector<Slot> slots_;
  std::size_t size_ = 0;
};

}  // namespace cslam
