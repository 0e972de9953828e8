#include "zipfusion/core/memory.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>
#if __GLIBC_PREREQ(2, 33)
#define ZF_HAS_MALLINFO2 1
#endif
#endif

namespace zipfusion {
namespace {

#if defined(ZF_HAS_MALLINFO2)
// Where the allocation goes is observable, so the compiler may not drop it.
void* volatile g_block = nullptr;

// A block far above glibc's default mmap threshold (128 KiB at start) comes from the heap and
// stays there when freed.
TEST(KeepFreedMemory, LargeBlocksStayInTheProcess) {
  keep_freed_memory();
  constexpr size_t kSize = size_t{16} << 20;
  g_block = std::malloc(kSize);
  ASSERT_NE(g_block, nullptr);
  std::memset(g_block, 1, kSize);
  EXPECT_EQ(mallinfo2().hblkhd, 0u);  // not a block of its own mapping
  std::free(g_block);
  g_block = nullptr;
  EXPECT_GE(mallinfo2().fordblks, kSize);  // free, but not given back
}
#endif

}  // namespace
}  // namespace zipfusion
