// A comparison of four doubles (AVX2: four 64-bit lanes of all ones or zeros) as four 32-bit
// lanes, for the int and float operations that follow it. Used in functions compiled with
// target("avx2") only.
#pragma once

#include <immintrin.h>

namespace sim {

__attribute__((target("avx2"))) inline __m128i lanes32(__m256d mask) {
  return _mm256_castsi256_si128(
      _mm256_permutevar8x32_epi32(_mm256_castpd_si256(mask), _mm256_setr_epi32(0, 2, 4, 6, 0, 0, 0, 0)));
}

}  // namespace sim
