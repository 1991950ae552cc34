// The BC1 and BC4 refits' ranking of quantised endpoint pairs, 4 pairs per SSE2 register: the
// moment form -2 v0 ax - 2 v1 bx + v0^2 aa + 2 v0 v1 ab + v1^2 bb of the encoders' scalar loops,
// each lane with the loop's operations in its order (the files build without FMA contraction), and
// the first smallest rank in index order. Internal to bc1_encoder.cpp and bc4_encoder.cpp.
#pragma once
#if defined(__SSE2__)
#include <emmintrin.h>

namespace terrain::cook {

// A row of pairs sharing v0, with v1 = the four lanes of `v1`.
struct PairRanks {
  float ax, bx, aa, ab, bb;
  __m128 v1, t2, t5;  // the lanes' v1, 2 v1 bx and v1^2 bb
  PairRanks(float ax_, float bx_, float aa_, float ab_, float bb_, __m128 v1_)
      : ax(ax_), bx(bx_), aa(aa_), ab(ab_), bb(bb_), v1(v1_),
        t2(_mm_mul_ps(_mm_mul_ps(_mm_set1_ps(2.0f), v1_), _mm_set1_ps(bx_))),
        t5(_mm_mul_ps(_mm_mul_ps(v1_, v1_), _mm_set1_ps(bb_))) {}
  __m128 row(float v0) const {
    const __m128 t1 = _mm_set1_ps(-2.0f * v0 * ax), t3 = _mm_set1_ps(v0 * v0 * aa);
    const __m128 t4 = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(2.0f * v0), v1), _mm_set1_ps(ab));
    return _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_sub_ps(t1, t2), t3), t4), t5);
  }
};

// Index of the first e[i] below `rank` and smaller than every earlier one (-1 if none), as the
// scalar loops' strict comparison keeps it; rank becomes that value.
inline int first_smallest(const float* e, int n, float& rank) {
  int first = -1;
  for (int i = 0; i < n; ++i) {
    const bool lower = e[i] < rank;
    rank = lower ? e[i] : rank;
    first = lower ? i : first;
  }
  return first;
}

}  // namespace terrain::cook
#endif
