#pragma once
//! \file
//! ZF_ROW_KERNEL: marks a row kernel, a plain loop over the pixels of a row, or over a block of
//! points (FRBR's tests, the seams' windows), that the compiler vectorises; the loads of a block of
//! points are gathers, which GCC makes only when the kernel's pointers are `__restrict`. On x86-64
//! it is compiled three times, for AVX-512 (16 floats a vector), AVX2 (8) and the baseline SSE2
//! (4), and the best the CPU has is chosen when the process loads, so one binary runs everywhere
//! and uses what it finds. AVX-512 could fuse a multiply and an add where the others cannot; the
//! libraries, where the row kernels are, are compiled with -ffp-contract=off, so each clone
//! computes the same floats, and the same meshes come out on every CPU.

#include <bit>
#include <cstdint>

// Not under ThreadSanitizer: a clone's resolver runs as the program is relocated, before the
// sanitizer's runtime has started, and its instrumented entry crashes there.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__SANITIZE_THREAD__)
#define ZF_ROW_KERNEL __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define ZF_ROW_KERNEL
#endif

namespace zipfusion {

//! Element function for row kernels: `if_set` where `condition` (0 or 1) is 1, else `otherwise`,
//! chosen by a bit mask. A product would turn 0·inf into NaN, and GCC vectorises neither a select
//! on a comparison that may trap (for AVX2 and SSE) nor a branch.
inline float select_if(unsigned condition, float if_set, float otherwise) {
  const std::uint32_t mask = 0u - condition;
  return std::bit_cast<float>((std::bit_cast<std::uint32_t>(if_set) & mask) | (std::bit_cast<std::uint32_t>(otherwise) & ~mask));
}

}  // namespace zipfusion
