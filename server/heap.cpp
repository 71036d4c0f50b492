#include "server/heap.h"

#include <unistd.h>

#include <fstream>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

// tcmalloc's C API, weak: null when the program does not allocate through tcmalloc.
extern "C" void MallocExtension_ReleaseFreeMemory(void) __attribute__((weak));
extern "C" int MallocExtension_GetNumericProperty(const char* property, std::size_t* value) __attribute__((weak));

namespace cslam::server {

HeapStats heap_stats() {
  HeapStats s;
  if (!MallocExtension_GetNumericProperty) return s;
  std::size_t pageheap_free = 0, thread_caches = 0, central = 0, transfer = 0;
  s.known = MallocExtension_GetNumericProperty("generic.current_allocated_bytes", &s.allocated) &&
            MallocExtension_GetNumericProperty("tcmalloc.pageheap_free_bytes", &pageheap_free) &&
            MallocExtension_GetNumericProperty("tcmalloc.pageheap_unmapped_bytes", &s.unmapped);
  MallocExtension_GetNumericProperty("tcmalloc.current_total_thread_cache_bytes", &thread_caches);
  MallocExtension_GetNumericProperty("tcmalloc.central_cache_free_bytes", &central);
  MallocExtension_GetNumericProperty("tcmalloc.transfer_cache_free_bytes", &transfer);
  s.free_mapped = pageheap_free + thread_caches + central + transfer;
  return s;
}

std::size_t resident_bytes() {
  std::ifstream in("/proc/self/statm");
  std::size_t pages_total = 0, pages_resident = 0;
  if (!(in >> pages_total >> pages_resident)) return 0;
  return pages_resident * std::size_t(::sysconf(_SC_PAGESIZE));
}

void release_free_memory() {
  if (MallocExtension_ReleaseFreeMemory) {
    MallocExtension_ReleaseFreeMemory();
    return;
  }
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace cslam::server
