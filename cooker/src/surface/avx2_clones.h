// TERRAIN_AVX2_CLONES before a function definition builds it twice, for AVX2 and for the baseline,
// and picks one when the program loads (GCC's target_clones). Only the lanes widen: AVX2 does not
// enable FMA, so both clones compute the same bits. Not under ThreadSanitizer (its runtime and the
// ifunc resolver do not mix) or other compilers and CPUs: there the baseline alone.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_THREAD__)
#define TERRAIN_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define TERRAIN_AVX2_CLONES
#endif
