// shading.hpp's kernel eight pixels at a time. Compiled for AVX2 (CMake); called only where
// the CPU has it.
#include <immintrin.h>

#include <cstdint>

#include "sim/render/shading.hpp"

namespace sim::shading {
namespace {

struct Lanes {
  static constexpr int N = 8;
  using F = __m256;
  using I = __m256i;
  using M = __m256i;  // all ones or zeros per lane
  static F set(float x) { return _mm256_set1_ps(x); }
  static I seti(int x) { return _mm256_set1_epi32(x); }
  static F load(const float* p) { return _mm256_loadu_ps(p); }
  static I loadi(const std::int32_t* p) { return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)); }
  static void store(float* p, F a) { _mm256_storeu_ps(p, a); }
  static void storei(std::int32_t* p, I a) { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), a); }
  static M mor(M a, M b) { return _mm256_or_si256(a, b); }
  static F add(F a, F b) { return _mm256_add_ps(a, b); }
  static F sub(F a, F b) { return _mm256_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm256_mul_ps(a, b); }
  static F div(F a, F b) { return _mm256_div_ps(a, b); }
  static F sqrt(F a) { return _mm256_sqrt_ps(a); }
  static F max(F a, F b) { return _mm256_max_ps(a, b); }  // a > b ? a : b
  static F min(F a, F b) { return _mm256_min_ps(a, b); }  // a < b ? a : b
  static M lt(F a, F b) { return _mm256_castps_si256(_mm256_cmp_ps(a, b, _CMP_LT_OQ)); }
  static M le(F a, F b) { return _mm256_castps_si256(_mm256_cmp_ps(a, b, _CMP_LE_OQ)); }
  static M gt(F a, F b) { return _mm256_castps_si256(_mm256_cmp_ps(a, b, _CMP_GT_OQ)); }
  static M eq(F a, F b) { return _mm256_castps_si256(_mm256_cmp_ps(a, b, _CMP_EQ_OQ)); }
  static M lei(I a, I b) { return _mm256_xor_si256(_mm256_cmpgt_epi32(a, b), _mm256_set1_epi32(-1)); }
  static M eqi(I a, I b) { return _mm256_cmpeq_epi32(a, b); }
  static M mand(M a, M b) { return _mm256_and_si256(a, b); }
  static M mnot(M a) { return _mm256_xor_si256(a, _mm256_set1_epi32(-1)); }
  static int bits(M m) { return _mm256_movemask_ps(_mm256_castsi256_ps(m)); }
  static bool any(M m) { return bits(m) != 0; }
  static bool all(M m) { return bits(m) == 0xFF; }
  static F sel(M m, F a, F b) { return _mm256_blendv_ps(b, a, _mm256_castsi256_ps(m)); }
  static I seli(M m, I a, I b) { return _mm256_blendv_epi8(b, a, m); }
  static F gather(const float* p, I i, M m) {
    return _mm256_mask_i32gather_ps(_mm256_setzero_ps(), p, i, _mm256_castsi256_ps(m), 4);
  }
  static I gatheri(const std::int32_t* p, I i, M m) {
    return _mm256_mask_i32gather_epi32(_mm256_set1_epi32(-1), reinterpret_cast<const int*>(p), i, m, 4);
  }
  static void prefetch(const float* p, I i, M m) {
    alignas(32) std::int32_t at[N];
    _mm256_store_si256(reinterpret_cast<__m256i*>(at), i);
    for (unsigned b = static_cast<unsigned>(bits(m)); b != 0; b &= b - 1)
      _mm_prefetch(reinterpret_cast<const char*>(p + at[__builtin_ctz(b)]), _MM_HINT_T0);
  }
  static I gatheri_run(const std::int32_t* p, std::size_t, I i, M m, std::int64_t) { return gatheri(p, i, m); }
  static bool permute_fields(const float*, std::size_t, int, I, M, F*) { return false; }
  static I cvtt(F a) { return _mm256_cvttps_epi32(a); }
  // floor_int: rounded down, then converted (INT_MIN beyond int and for NaN)
  static I cvt_floor(F a) { return _mm256_cvttps_epi32(_mm256_round_ps(a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)); }
  static F cvt(I a) { return _mm256_cvtepi32_ps(a); }
  static I addi(I a, I b) { return _mm256_add_epi32(a, b); }
  static I subi(I a, I b) { return _mm256_sub_epi32(a, b); }
  static I muli(I a, I b) { return _mm256_mullo_epi32(a, b); }
  static I mini(I a, I b) { return _mm256_min_epi32(a, b); }
  static I maxi(I a, I b) { return _mm256_max_epi32(a, b); }
  static int reduce_max(I a, M m) {
    alignas(32) std::int32_t v[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(v), a);
    const int b = bits(m);
    int best = -1;
    bool seen = false;
    for (int k = 0; k < 8; ++k)
      if (b >> k & 1) {
        best = seen && best > v[k] ? best : v[k];
        seen = true;
      }
    return best;
  }
  static int lane(I a, int k) {
    alignas(32) std::int32_t v[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(v), a);
    return v[k];
  }
  static int first(M m) {
    const int b = bits(m);
    return b ? __builtin_ctz(static_cast<unsigned>(b)) : -1;
  }
  static F lut16(const float* t, I i) {
    const F lo = _mm256_permutevar8x32_ps(_mm256_loadu_ps(t), i);
    const F hi = _mm256_permutevar8x32_ps(_mm256_loadu_ps(t + 8), i);
    return sel(_mm256_cmpgt_epi32(i, _mm256_set1_epi32(7)), hi, lo);
  }
  static F lut32(const float* t, I i) { return _mm256_i32gather_ps(t, _mm256_and_si256(i, _mm256_set1_epi32(31)), 4); }
  static void store_rgb(std::uint8_t* out, I r, I g, I b) {
    // the 24 values as bytes: r g in one register, b in another
    const __m128i r16 = _mm_packs_epi32(_mm256_castsi256_si128(r), _mm256_extracti128_si256(r, 1));
    const __m128i g16 = _mm_packs_epi32(_mm256_castsi256_si128(g), _mm256_extracti128_si256(g, 1));
    const __m128i b16 = _mm_packs_epi32(_mm256_castsi256_si128(b), _mm256_extracti128_si256(b, 1));
    const __m128i rg = _mm_packus_epi16(r16, g16);   // r0..r7 g0..g7
    const __m128i bb = _mm_packus_epi16(b16, b16);   // b0..b7 b0..b7
    static const Masks masks;
    const __m128i lo = _mm_or_si128(_mm_shuffle_epi8(rg, masks.rg[0]), _mm_shuffle_epi8(bb, masks.b[0]));
    const __m128i hi = _mm_or_si128(_mm_shuffle_epi8(rg, masks.rg[1]), _mm_shuffle_epi8(bb, masks.b[1]));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), lo);
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + 16), hi);
  }
  struct Masks {
    __m128i rg[2], b[2];
    Masks() {
      for (int k = 0; k < 2; ++k) {
        alignas(16) std::int8_t s_rg[16], s_b[16];
        for (int j = 0; j < 16; ++j) {
          const int at = 16 * k + j, pixel = at / 3, c = at % 3;
          const bool real = at < 24;
          s_rg[j] = real && c == 0 ? static_cast<std::int8_t>(pixel)
                    : real && c == 1 ? static_cast<std::int8_t>(8 + pixel)
                                     : static_cast<std::int8_t>(-128);
          s_b[j] = real && c == 2 ? static_cast<std::int8_t>(pixel) : static_cast<std::int8_t>(-128);
        }
        rg[k] = _mm_load_si128(reinterpret_cast<const __m128i*>(s_rg));
        b[k] = _mm_load_si128(reinterpret_cast<const __m128i*>(s_b));
      }
    }
  };
};

}  // namespace
}  // namespace sim::shading

#include "sim/render/shading_kernel.hpp"

namespace sim::shading {

void shade_rows_avx2(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch) {
  shade_rows<Lanes>(f, v0, v1, image, step, scratch);
}

}  // namespace sim::shading
