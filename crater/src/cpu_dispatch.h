// AREOMAP_ALSO_FOR_AVX2: the crater module's per-pixel loops marked with it also get an AVX2
// build, chosen at load time where the CPU has AVX2 (GCC's target_clones through an ELF ifunc,
// as glibc picks its string functions). Internal to the crater module.
//
// The values are the same at any vector width: integer operations, and float operations that
// IEEE rounds exactly (+, -, x, /, sqrt; no fused multiply-add, which AVX2 alone does not
// enable). Elsewhere, and with AREOMAP_CPU_DISPATCH off in CMake (the asan preset, so that CI
// tests both builds), the baseline build runs alone.
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__ELF__) && \
    !defined(AREOMAP_NO_CPU_DISPATCH)
#define AREOMAP_ALSO_FOR_AVX2 __attribute__((target_clones("avx2", "default")))
#else
#define AREOMAP_ALSO_FOR_AVX2
#endif
