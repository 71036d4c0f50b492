// keep_freed_memory_for_reuse: image-sized blocks come from the heap (not from mmap, which hands
// out freshly zeroed pages every time) and freeing them does not give the pages back.
#include <cstdlib>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "core/allocator_tuning.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

TEST(AllocatorTuning, ImageSizedBlocksComeFromTheHeapAndStayForReuse) {
  ASSERT_TRUE(cslam::keep_freed_memory_for_reuse());
#if defined(__GLIBC__)
  const std::size_t mmapped_before = mallinfo2().hblkhd;
  constexpr std::size_t kImage = 640 * 480 * 3;  // one colour frame; glibc's default mmaps it
  std::vector<void*> blocks;
  for (int i = 0; i < 8; ++i) {
    blocks.push_back(std::malloc(kImage));
    ASSERT_NE(blocks.back(), nullptr);
    std::memset(blocks.back(), i, kImage);
  }
  EXPECT_EQ(mallinfo2().hblkhd, mmapped_before) << "image-sized blocks were served by mmap";
  const std::size_t heap_in_use = mallinfo2().arena;
  for (void* b : blocks) std::free(b);
  // Freed memory stays in the heap (below the 64 MB trim threshold), ready for the next frame.
  EXPECT_GE(mallinfo2().arena, heap_in_use);
#else
  GTEST_SKIP() << "allocator tuning is a no-op without glibc";
#endif
}
