#pragma once
// A set of pointers for a per-call pass that is cleared often: open addressing with linear
// probing, each slot tagged with the pass that wrote it, so clear() is O(1) and the table is
// reused from pass to pass without allocating. Keys are compared and hashed as addresses only
// (nothing is dereferenced). Not thread-safe: one owner.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cslam {

class PointerSet {
 public:
  // Empties the set; at least `expected` insertions will fit without growing.
  void clear(std::size_t expected = 0) {
    if (++pass_ == 0) {  // tags wrapped: forget every slot
      for (Slot& s : slots_) s.pass = 0;
      pass_ = 1;
    }
    size_ = 0;
    if (2 * expected > slots_.size()) rebuild(capacity_for(expected));
  }

  // True if `p` was not in the set (and is now).
  bool insert(const void* p) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    for (std::size_t i = slot_of(p);; i = (i + 1) & mask_) {
      Slot& s = slots_[i];
      if (s.pass != pass_) {
        s = {p, pass_};
        ++size_;
        return true;
      }
      if (s.key == p) return false;
    }
  }

  bool contains(const void* p) const {
    if (slots_.empty()) return false;
    for (std::size_t i = slot_of(p);; i = (i + 1) & mask_) {
      const Slot& s = slots_[i];
      if (s.pass != pass_) return false;
      if (s.key == p) return true;
    }
  }

  std::size_t size() const { return size_; }
  std::size_t capacity() const { return slots_.size() / 2; }

 private:
  struct Slot {
    const void* key = nullptr;
    std::uint32_t pass = 0;  // the pass that wrote it; 0: never
  };

  static std::size_t capacity_for(std::size_t n) {
    std::size_t c = 16;
    while (c < 2 * n) c *= 2;
    return c;
  }
  std::size_t slot_of(const void* p) const {
    // Fibonacci hashing of the address (allocations are aligned: the low bits carry little).
    const std::uint64_t h = std::uint64_t(reinterpret_cast<std::uintptr_t>(p)) * 0x9E3779B97F4A7C15ull;
    return std::size_t(h >> 32) & mask_;
  }
  void rebuild(std::size_t slots) {
    std::vector<Slot> old;
    old.swap(slots_);
    slots_.assign(slots, Slot{});
    mask_ = slots - 1;
    const std::uint32_t live = pass_;
    pass_ = 1;
    size_ = 0;
    for (const Slot& s : old)
      if (s.pass == live) insert(s.key);
  }
  void grow() { rebuild(slots_.empty() ? 32 : 2 * slots_.size()); }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0, size_ = 0;
  std::uint32_t pass_ = 1;
};

}  // namespace cslam
