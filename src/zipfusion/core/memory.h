#pragma once
//! \file
//! Process-wide memory settings for real-time use.

namespace zipfusion {

//! Keeps memory that is freed in the process for its next use, instead of returning it to the
//! operating system: glibc gives blocks above its mmap threshold back on free and trims the top of
//! its heaps, and the next frame set then touches those pages anew (minor page faults, each a trip
//! into the kernel). Where one frame set's buffers happened to lie decided how often: zippering
//! samba-4cam frame 0 on one thread (zf_zipper_repeat, 20 calls) took 28 or 24 ms depending only on
//! whether a 3×3 bilateral filter before it had left its scratch on the heap (49 000 against
//! 22 000 page faults). Call once at program start; a no-op where the C library is not glibc.
void keep_freed_memory();

}  // namespace zipfusion
