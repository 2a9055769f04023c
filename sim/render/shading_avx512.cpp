// shading.hpp's kernel sixteen pixels at a time. Compiled for the AVX-512 subsets of
// vector_unit.hpp (CMake); called only where the CPU has them.
#include <immintrin.h>

#include <cstdint>

#include "sim/render/shading.hpp"

namespace sim::shading {
namespace {

struct Lanes {
  static constexpr int N = 16;
  using F = __m512;
  using I = __m512i;
  using M = __mmask16;
  static F set(float x) { return _mm512_set1_ps(x); }
  static I seti(int x) { return _mm512_set1_epi32(x); }
  static F load(const float* p) { return _mm512_loadu_ps(p); }
  static I loadi(const std::int32_t* p) { return _mm512_loadu_si512(p); }
  static void store(float* p, F a) { _mm512_storeu_ps(p, a); }
  static void storei(std::int32_t* p, I a) { _mm512_storeu_si512(p, a); }
  static M mor(M a, M b) { return a | b; }
  static F add(F a, F b) { return _mm512_add_ps(a, b); }
  static F sub(F a, F b) { return _mm512_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm512_mul_ps(a, b); }
  static F div(F a, F b) { return _mm512_div_ps(a, b); }
  static F sqrt(F a) { return _mm512_sqrt_ps(a); }
  static F max(F a, F b) { return _mm512_max_ps(a, b); }  // a > b ? a : b
  static F min(F a, F b) { return _mm512_min_ps(a, b); }  // a < b ? a : b
  static M lt(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
  static M le(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
  static M gt(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ); }
  static M eq(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_EQ_OQ); }
  static M lei(I a, I b) { return _mm512_cmple_epi32_mask(a, b); }
  static M eqi(I a, I b) { return _mm512_cmpeq_epi32_mask(a, b); }
  static M mand(M a, M b) { return a & b; }
  static M mnot(M a) { return static_cast<M>(~a); }
  static bool any(M m) { return m != 0; }
  static bool all(M m) { return m == 0xFFFF; }
  static F sel(M m, F a, F b) { return _mm512_mask_blend_ps(m, b, a); }
  static I seli(M m, I a, I b) { return _mm512_mask_blend_epi32(m, b, a); }
  static F gather(const float* p, I i, M m) { return _mm512_mask_i32gather_ps(_mm512_setzero_ps(), m, i, p, 4); }
  static I gatheri(const std::int32_t* p, I i, M m) { return _mm512_mask_i32gather_epi32(_mm512_set1_epi32(-1), m, i, p, 4); }
  // asks the cache for p[i] in the lanes of m, without waiting
  static void prefetch(const float* p, I i, M m) {
    alignas(64) std::int32_t at[N];
    _mm512_store_si512(at, i);
    // a lane whose line the lane before asks for already is left out (neighbouring pixels'
    // cells share lines: a row's sixteen ask for two or three)
    const __m512i line = _mm512_srai_epi32(_mm512_add_epi32(i, _mm512_set1_epi32(static_cast<int>(
                                                                  (reinterpret_cast<std::uintptr_t>(p) & 63) / 4))),
                                           4);
    const __m512i before = _mm512_alignr_epi32(line, _mm512_set1_epi32(-(1 << 30)), 15);
    unsigned b = m & static_cast<M>(_mm512_cmpneq_epi32_mask(line, before) | static_cast<M>(~(m << 1)));
    for (; b != 0; b &= b - 1) _mm_prefetch(reinterpret_cast<const char*>(p + at[__builtin_ctz(b)]), _MM_HINT_T0);
  }
  // gatheri where the lanes' indices (those in m) are known to lie in [lo, lo + 32) (lo < 0:
  // not known): two loads and a permutation (a pixel's cells, a lens's rows of 16)
  static I gatheri_run(const std::int32_t* p, std::size_t size, I i, M m, std::int64_t lo) {
    if (lo < 0 || static_cast<std::uint64_t>(lo) + 32 > size) return gatheri(p, i, m);
    const __m512i at = _mm512_sub_epi32(i, _mm512_set1_epi32(static_cast<int>(lo)));
    if (_mm512_mask_cmplt_epu32_mask(m, at, _mm512_set1_epi32(32)) != m) return gatheri(p, i, m);
    const __m512i v = _mm512_permutex2var_epi32(_mm512_loadu_si512(p + lo), at, _mm512_loadu_si512(p + lo + 16));
    return _mm512_mask_blend_epi32(m, _mm512_set1_epi32(-1), v);
  }
  // the lanes of a tessellated surface name a few neighbouring planes: one run of 32, then two
  // loads and a permutation per field; where a surface's edge meets another object, two runs
  static bool permute_fields(const float* p, std::size_t stride, int count, I i, M m, F* out) {
    const __m512i run = _mm512_set1_epi32(32);
    // the run: first guessed about lane 0's id (a strip's neighbours lie within 16 of it: two
    // comparisons), else from the lanes' least and greatest ids (two reductions, longer)
    const int guess = _mm_cvtsi128_si32(_mm512_castsi512_si128(i));
    int lo = guess < 16 ? 0 : guess - 16;
    __m512i at = _mm512_sub_epi32(i, _mm512_set1_epi32(lo));
    if (guess >= 0 && _mm512_mask_cmplt_epu32_mask(m, at, run) == m) {
      permute_run(p, stride, count, lo, at, m, out);
      return true;
    }
    lo = _mm512_mask_reduce_min_epi32(m, i);
    const int hi = _mm512_mask_reduce_max_epi32(m, i);
    if (lo < 0) return false;
    at = _mm512_sub_epi32(i, _mm512_set1_epi32(lo));
    if (hi - lo < 32) {
      permute_run(p, stride, count, lo, at, m, out);
      return true;
    }
    // the least id's run and the greatest's (a silhouette: the object's planes, the wall's)
    const M low = _mm512_mask_cmplt_epu32_mask(m, at, run);
    const int lo2 = hi - 31;
    const __m512i at2 = _mm512_sub_epi32(i, _mm512_set1_epi32(lo2));
    const M high = _mm512_mask_cmplt_epu32_mask(m, at2, run);
    if ((low | high) != m) return false;
    permute_run(p, stride, count, lo, at, low, out);
    permute_run(p, stride, count, lo2, at2, static_cast<M>(high & ~low), out);
    return true;
  }
  // out[k] = m ? p[k stride + lo + at] : out[k], at in [0, 32)
  static void permute_run(const float* p, std::size_t stride, int count, int lo, I at, M m, F* out) {
    for (int k = 0; k < count; ++k) {
      const float* q = p + k * stride + lo;
      out[k] = _mm512_mask_blend_ps(m, out[k], _mm512_permutex2var_ps(_mm512_loadu_ps(q), at, _mm512_loadu_ps(q + 16)));
    }
  }
  // shading_kernel.hpp's noise_offset for chunks [0, n) of (row v, channel c), eight at a time
  // (the same 64-bit hash and scaling, lane by lane); out holds n rounded up to 8
  static void noise_offsets(const Frame& f, int v, int c, int n, std::uint32_t* out) {
    const __m512i seed = _mm512_set1_epi64(static_cast<long long>(f.noise_seed));
    const __m512i golden = _mm512_set1_epi64(static_cast<long long>(kNoiseKeyScale));
    const __m512i c1 = _mm512_set1_epi64(static_cast<long long>(kMix1));
    const __m512i c2 = _mm512_set1_epi64(static_cast<long long>(kMix2));
    const __m512i span = _mm512_set1_epi64(f.noise_span);
    const std::uint64_t base = (static_cast<std::uint64_t>(v) * 3 + static_cast<std::uint64_t>(c)) * 65536u + 1;
    __m512i key = _mm512_add_epi64(_mm512_set1_epi64(static_cast<long long>(base)), _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 6, 7));
    for (int k = 0; k < n; k += 8) {
      __m512i z = _mm512_xor_si512(seed, _mm512_mullo_epi64(golden, key));
      z = _mm512_mullo_epi64(_mm512_xor_si512(z, _mm512_srli_epi64(z, 30)), c1);
      z = _mm512_mullo_epi64(_mm512_xor_si512(z, _mm512_srli_epi64(z, 27)), c2);
      z = _mm512_xor_si512(z, _mm512_srli_epi64(z, 31));
      const __m512i at = _mm512_srli_epi64(_mm512_mul_epu32(_mm512_srli_epi64(z, 32), span), 32);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + k), _mm512_cvtepi64_epi32(at));
      key = _mm512_add_epi64(key, _mm512_set1_epi64(8));
    }
  }
  static I cvtt(F a) { return _mm512_cvttps_epi32(a); }
  // floor_int in one conversion rounding down (INT_MIN beyond int and for NaN)
  static I cvt_floor(F a) { return _mm512_cvt_roundps_epi32(a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }
  static F cvt(I a) { return _mm512_cvtepi32_ps(a); }
  static I addi(I a, I b) { return _mm512_add_epi32(a, b); }
  static I subi(I a, I b) { return _mm512_sub_epi32(a, b); }
  static I muli(I a, I b) { return _mm512_mullo_epi32(a, b); }
  static I mini(I a, I b) { return _mm512_min_epi32(a, b); }
  static I maxi(I a, I b) { return _mm512_max_epi32(a, b); }
  static int reduce_max(I a, M m) { return m ? _mm512_mask_reduce_max_epi32(m, a) : -1; }
  static int lane(I a, int k) {
    alignas(64) std::int32_t v[16];
    _mm512_store_si512(v, a);
    return v[k];
  }
  static int first(M m) { return m ? __builtin_ctz(m) : -1; }
  static F lut16(const float* t, I i) { return _mm512_permutexvar_ps(i, _mm512_loadu_ps(t)); }
  static F lut32(const float* t, I i) { return _mm512_permutex2var_ps(_mm512_loadu_ps(t), i, _mm512_loadu_ps(t + 16)); }
  // the bytes narrowed with unsigned saturation: anything from 255 up (INT_MIN too, as unsigned)
  // is stored as 255, so the kernel need not clamp there
  static constexpr bool kStoreSaturates = true;
  static void store_rgb(std::uint8_t* out, I r, I g, I b) {
    const __m128i r8 = _mm512_cvtusepi32_epi8(r), g8 = _mm512_cvtusepi32_epi8(g), b8 = _mm512_cvtusepi32_epi8(b);
    // byte j of the 48 is channel j % 3 of pixel j / 3: three shuffles per 16 bytes
    static const Masks masks;
    for (int k = 0; k < 3; ++k) {
      const __m128i part = _mm_or_si128(_mm_or_si128(_mm_shuffle_epi8(r8, masks.m[k][0]), _mm_shuffle_epi8(g8, masks.m[k][1])),
                                        _mm_shuffle_epi8(b8, masks.m[k][2]));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + 16 * k), part);
    }
  }
  struct Masks {
    __m128i m[3][3];
    Masks() {
      for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) {
          alignas(16) std::int8_t s[16];
          for (int j = 0; j < 16; ++j) {
            const int at = 16 * k + j;
            s[j] = at % 3 == c ? static_cast<std::int8_t>(at / 3) : static_cast<std::int8_t>(-128);
          }
          m[k][c] = _mm_load_si128(reinterpret_cast<const __m128i*>(s));
        }
    }
  };
};

}  // namespace
}  // namespace sim::shading

#include "sim/render/shading_kernel.hpp"

namespace sim::shading {

void shade_rows_avx512(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch) {
  shade_rows<Lanes>(f, v0, v1, image, step, scratch);
}

}  // namespace sim::shading
