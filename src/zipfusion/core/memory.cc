#include "zipfusion/core/memory.h"

#include <cstdlib>  // defines __GLIBC__ under glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace zipfusion {

void keep_freed_memory() {
#if defined(__GLIBC__)
  // Blocks up to 32 MiB from the heap (mallopt(3)'s documented maximum on 64-bit systems; a frame
  // set's largest buffers are a few MiB), and a heap trimmed only once 1 GiB lies free at its top.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

}  // namespace zipfusion
