#pragma once
// The process heap as the allocator sees it. The programs allocate through tcmalloc
// (cmake/Dependencies.cmake), which keeps freed spans in its page heap for reuse: resident memory
// then stays at its peak after a burst (a reconstruction job, a submap re-integration) unless the
// free pages are handed back. Without tcmalloc: glibc's malloc_trim, and no figures.
#include <cstddef>

namespace cslam::server {

struct HeapStats {
  bool known = false;           // the allocator reports figures (tcmalloc)
  std::size_t allocated = 0;    // bytes the program holds
  std::size_t free_mapped = 0;  // freed, still resident (page heap + caches)
  std::size_t unmapped = 0;     // freed and handed back to the system
};

HeapStats heap_stats();
// Resident set size of this process (bytes), from /proc/self/statm; 0 if unreadable.
std::size_t resident_bytes();
// Hands every free page back to the system.
void release_free_memory();

}  // namespace cslam::server
