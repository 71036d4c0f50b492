#pragma once
// Heap settings for programs that process image streams. Every frame allocates and frees
// image-sized buffers (colour 0.9 MB, depth 0.6 MB, pyramid levels, decode buffers). With glibc's
// defaults such blocks come from mmap or from heap tops that are trimmed back to the kernel when
// freed, so each frame faults in freshly zeroed pages again (fr1/rpy, one client: 229,000 page
// faults and 0.5 CPU s of kernel time per run; 23,000 and 0.2 s with the memory kept for reuse).
namespace cslam {

// Serves blocks up to 32 MB from the heap and returns freed heap memory to the kernel only above
// 64 MB of free space at a heap's top (glibc mallopt; a no-op elsewhere). Call once at the start
// of main, before other threads exist. Returns false if the C library refused.
bool keep_freed_memory_for_reuse();

}  // namespace cslam
