#pragma once
// Heap settings for programs that process image streams. Every frame allocates and frees
// image-sized buffers (colour 0.9 MB, depth 0.6 MB, pyramid levels, decode buffers). With glibc's
// defaults such blocks come from mmap or from heap tops that are trimmed back to the kernel when
// freed, so each frame faults in freshly zeroed pages again: on fr1/rpy about 0.4 CPU s of kernel
// time per run (docs/performance.md). Keeping freed memory in the process for reuse removes it.
namespace cslam {

// Serves blocks up to 32 MB from the heap and returns freed heap memory to the kernel only above
// 64 MB of free space at a heap's top (glibc mallopt; a no-op elsewhere). Call once at the start
// of main, before other threads exist. Returns false if the C library refused.
bool keep_freed_memory_for_reuse();

}  // namespace cslam
