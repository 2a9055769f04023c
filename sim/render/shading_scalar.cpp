// shading.hpp's kernel one pixel at a time: the path for CPUs without AVX2, and the one the
// vector paths are held to.
#include <emmintrin.h>

#include <cstdint>
#include <cstring>

#include "sim/render/shading.hpp"

namespace sim::shading {
namespace {

struct Lanes {
  static constexpr int N = 1;
  using F = float;
  using I = std::int32_t;
  using M = bool;
  static F set(float x) { return x; }
  static I seti(int x) { return x; }
  static F load(const float* p) { return *p; }
  static I loadi(const std::int32_t* p) { return *p; }
  static void store(float* p, F a) { *p = a; }
  static void storei(std::int32_t* p, I a) { *p = a; }
  static M mor(M a, M b) { return a || b; }
  static F add(F a, F b) { return a + b; }
  static F sub(F a, F b) { return a - b; }
  static F mul(F a, F b) { return a * b; }
  static F div(F a, F b) { return a / b; }
  static F sqrt(F a) { return _mm_cvtss_f32(_mm_sqrt_ss(_mm_set_ss(a))); }
  static F max(F a, F b) { return a > b ? a : b; }
  static F min(F a, F b) { return a < b ? a : b; }
  static M lt(F a, F b) { return a < b; }
  static M le(F a, F b) { return a <= b; }
  static M gt(F a, F b) { return a > b; }
  static M eq(F a, F b) { return a == b; }
  static M lei(I a, I b) { return a <= b; }
  static M eqi(I a, I b) { return a == b; }
  static M mand(M a, M b) { return a && b; }
  static M mnot(M a) { return !a; }
  static bool any(M m) { return m; }
  static bool all(M m) { return m; }
  static F sel(M m, F a, F b) { return m ? a : b; }
  static I seli(M m, I a, I b) { return m ? a : b; }
  static F gather(const float* p, I i, M m) { return m ? p[i] : 0.0f; }
  static I gatheri(const std::int32_t* p, I i, M m) { return m ? p[i] : -1; }
  // the vector units' conversions: INT_MIN for what does not fit (a C++ cast would be undefined)
  static void prefetch(const float*, I, M) {}  // one lookup at a time: nothing to overlap
  static I gatheri_run(const std::int32_t* p, std::size_t, I i, M m, std::int64_t) { return gatheri(p, i, m); }
  static bool permute_fields(const float*, std::size_t, int, I, M, F*) { return false; }
  static I cvtt(F a) { return _mm_cvttss_si32(_mm_set_ss(a)); }
  static F cvt(I a) { return static_cast<float>(a); }
  // wrapping, as the vector units' integer lanes do
  static I addi(I a, I b) { return static_cast<I>(static_cast<std::uint32_t>(a) + static_cast<std::uint32_t>(b)); }
  static I subi(I a, I b) { return static_cast<I>(static_cast<std::uint32_t>(a) - static_cast<std::uint32_t>(b)); }
  static I muli(I a, I b) { return static_cast<I>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b)); }
  static I mini(I a, I b) { return a < b ? a : b; }
  static I maxi(I a, I b) { return a > b ? a : b; }
  static int reduce_max(I a, M m) { return m ? a : -1; }
  static int lane(I a, int) { return a; }
  static int first(M m) { return m ? 0 : -1; }
  static F lut16(const float* t, I i) { return t[i & 15]; }
  static F lut32(const float* t, I i) { return t[i & 31]; }
  static void store_rgb(std::uint8_t* out, I r, I g, I b) {
    out[0] = static_cast<std::uint8_t>(r);
    out[1] = static_cast<std::uint8_t>(g);
    out[2] = static_cast<std::uint8_t>(b);
  }
};

}  // namespace
}  // namespace sim::shading

#include "sim/render/shading_kernel.hpp"

namespace sim::shading {

void shade_rows_scalar(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch) {
  shade_rows<Lanes>(f, v0, v1, image, step, scratch);
}

}  // namespace sim::shading
