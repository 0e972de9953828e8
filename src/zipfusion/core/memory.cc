#include "zipfusion/core/memory.h"

#include <cstdlib>  // defines __GLIBC__ under glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace zipfusion {

void keep_freed_memory() {
#if defined(__GLIBC__)
  // Blocks up to 32 MiB (the largest threshold glibc accepts on 64-bit systems; a frame set's
  // largest buffers are a few MiB) from the heap, and the heap never trimmed.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

}  // namespace zipfusion
