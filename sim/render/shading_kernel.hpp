// The per-pixel kernel of shading.hpp, written once over a lane type L (one float, eight, or
// sixteen): each of shading_{scalar,avx2,avx512}.cpp defines its L and includes this file, so
// the three paths are the same operations in the same order. Everything here has internal
// linkage and uses no library template: a function compiled for AVX-512 must never be the copy
// the linker keeps for a caller on another path.
//
// L provides: N; F (floats), I (int32), M (lane masks); set, seti, load, loadi, store; add, sub,
// mul, div, sqrt, max (a > b ? a : b), min (a < b ? a : b); lt, le, gt, eq (ordered), lei,
// eqi; mand, mor, mnot, any, all; storei; sel (m ? a : b), seli; prefetch (p[i] of the lanes
// in m asked of the cache, nothing waits); gather (m ? p[i] : 0), gatheri
// (m ? p[i] : -1), gatheri_run (the same, the indices in a run of 32 the caller knows);
// permute_fields (where m's indices lie in one run of 32 and the unit permutes: out[k] =
// m ? p[k stride + i] : out[k] for `count` arrays `stride` apart, each readable 32 past the
// last index, and true; else false); cvtt (truncation, INT_MIN outside int), cvt; addi,
// subi, muli, mini, maxi;
// reduce_max, lane (one lane's value), first (the first lane set in a mask, -1: none);
// lut16, lut32 (16- and 32-entry float tables); store_rgb (three lanes of bytes, interleaved;
// with kStoreSaturates, of values from INT_MIN up, unsigned, stored as min(value, 255));
// optionally noise_offsets (noise_offset for a row's first n chunks, several at a time).
#pragma once

#include <cstddef>
#include <cstdint>
#include <xmmintrin.h>

#include "sim/render/shading.hpp"

namespace sim::shading {
namespace {

inline std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * kMix1;
  z = (z ^ (z >> 27)) * kMix2;
  return z ^ (z >> 31);
}

// The noise run of (row, channel, chunk of kNoiseChunk pixels): an offset into the pool. Inline
// in each path, so that a row's offsets are computed several at a time.
inline std::uint32_t noise_offset(const Frame& f, int v, int channel, int chunk) {
  const std::uint64_t key = (static_cast<std::uint64_t>(v) * 3 + static_cast<std::uint64_t>(channel)) * 65536u +
                            static_cast<std::uint64_t>(chunk) + 1;
  // the hash's top 32 bits scaled to [0, span) (a multiply, not a division)
  return static_cast<std::uint32_t>(((mix64(f.noise_seed ^ (kNoiseKeyScale * key)) >> 32) * f.noise_span) >> 32);
}

// floor, as an int (exact for |x| < 2^31; INT_MIN beyond, either side, and for NaN)
template <class L>
inline typename L::I floor_int(typename L::F x) {
  // one conversion rounding down, where the unit has it
  if constexpr (requires { L::cvt_floor(x); }) {
    return L::cvt_floor(x);
  } else {
    const typename L::I t = L::cvtt(x);
    // truncation rounded towards zero: one less where that went up (and not where it was out
    // of range, INT_MIN, which one less would wrap)
    const typename L::M down = L::mand(L::gt(L::cvt(t), x), L::mnot(L::eqi(t, L::seti(-2147483647 - 1))));
    return L::subi(t, L::seli(down, L::seti(1), L::seti(0)));
  }
}

// The light of spot (row, col) at the lanes `m`'s surface points, if they lie within its reach.
template <class L>
inline void add_spot(const Frame& f, typename L::M m, typename L::I row, typename L::I col, typename L::F pu,
                     typename L::F pv, typename L::F reach2, typename L::F inv_sigma, typename L::F weight,
                     typename L::F& r, typename L::F& g, typename L::F& b) {
  using F = typename L::F;
  using I = typename L::I;
  const F zero = L::set(0.0f);
  const F dv = L::sub(pv, L::add(L::set(f.grid_y0), L::mul(L::cvt(row), L::set(f.pitch))));
  const F du = L::sub(pu, L::add(L::set(f.grid_x0), L::mul(L::cvt(col), L::set(f.pitch))));
  const F rho2 = L::add(L::mul(du, du), L::mul(dv, dv));
  m = L::mand(m, L::le(rho2, reach2));
  if (!L::any(m)) return;
  // the blurred disc's edge profile at (rho - radius) / sigma: a cubic per segment
  const F x = L::mul(L::sub(L::sqrt(rho2), L::set(f.radius)), inv_sigma);
  const F at = L::mul(L::add(x, L::set(kEdgeReach)), L::set(kEdgeSegments / (2 * kEdgeReach)));
  const typename L::M inside = L::mand(L::le(zero, at), L::lt(at, L::set(static_cast<float>(kEdgeSegments))));
  const I k = L::seli(inside, L::cvtt(at), L::seti(0));
  const F t = L::sub(at, L::cvt(k));
  const F cubic = L::add(L::lut32(f.edge[0], k),
                         L::mul(t, L::add(L::lut32(f.edge[1], k),
                                          L::mul(t, L::add(L::lut32(f.edge[2], k), L::mul(t, L::lut32(f.edge[3], k)))))));
  const F profile = L::sel(inside, cubic, L::sel(L::lt(at, zero), L::set(1.0f), zero));
  const F e = L::sel(m, L::mul(profile, weight), zero);
  const I symbol = L::gatheri(f.spot_symbol, L::addi(L::muli(row, L::seti(f.cols)), col), m);
  const I s = L::seli(m, symbol, L::seti(kUnlitSymbol));
  r = L::add(r, L::mul(e, L::lut16(f.colour_r, s)));
  g = L::add(g, L::mul(e, L::lut16(f.colour_g, s)));
  b = L::add(b, L::mul(e, L::lut16(f.colour_b, s)));
}

// Light arriving at the lanes' surface points from the spots within reach, added to r, g, b.
// A spot lights a point when the point lies within its reach (radius + 3 sigma) on the
// projector's plane; the spots are added row by row, column by column.
template <class L>
inline void add_spots(const Frame& f, typename L::M lit, typename L::F pu, typename L::F pv, typename L::F sigma,
                      typename L::F weight, typename L::F& r, typename L::F& g, typename L::F& b) {
  using F = typename L::F;
  using I = typename L::I;
  using M = typename L::M;
  const F reach = L::add(L::set(f.radius), L::mul(L::set(3.0f), sigma));
  const F reach2 = L::mul(reach, reach);
  const F inv_sigma = L::div(L::set(1.0f), sigma);
  const F gx = L::mul(L::sub(pu, L::set(f.grid_x0)), L::set(f.inv_pitch));
  const F gy = L::mul(L::sub(pv, L::set(f.grid_y0)), L::set(f.inv_pitch));
  const F span = L::mul(reach, L::set(f.inv_pitch));
  // Focused spots reach less than 0.45 of a pitch: only the nearest spot can light a point,
  // and no rounding can make another one (the general path below finds the same one alone)
  const I last_col = L::seti(f.cols - 1), last_row = L::seti(f.rows - 1), origin = L::seti(0);
  if (L::all(L::mor(L::mnot(lit), L::lt(span, L::set(0.45f))))) {
    const I col = floor_int<L>(L::add(gx, L::set(0.5f))), row = floor_int<L>(L::add(gy, L::set(0.5f)));
    const M on_grid = L::mand(L::mand(L::lei(origin, col), L::lei(col, last_col)),
                              L::mand(L::lei(origin, row), L::lei(row, last_row)));
    add_spot<L>(f, L::mand(lit, on_grid), row, col, pu, pv, reach2, inv_sigma, weight, r, g, b);
    return;
  }
  // the grid columns and rows that may lie within reach, one more each side than the spans
  // say (their rounding must not drop a spot the distance test takes): [lo, hi]; and at most
  // kMaxSpotsAway pitches from the point, however blurred (a scenario's blur is bounded only
  // loosely: its spots wash into one another long before, and the work per pixel stays bounded)
  const I none = L::seti(-1), one = L::seti(1), away = L::seti(kMaxSpotsAway);
  const I c_mid = floor_int<L>(gx), r_mid = floor_int<L>(gy);
  const I c_lo = L::maxi(L::maxi(L::subi(L::subi(origin, floor_int<L>(L::sub(span, gx))), one), origin),
                         L::subi(c_mid, away));
  const I c_hi = L::seli(lit, L::mini(L::mini(L::addi(floor_int<L>(L::add(gx, span)), one), last_col), L::addi(c_mid, away)),
                         none);
  const I r_lo = L::maxi(L::maxi(L::subi(L::subi(origin, floor_int<L>(L::sub(span, gy))), one), origin),
                         L::subi(r_mid, away));
  const I r_hi = L::seli(lit, L::mini(L::mini(L::addi(floor_int<L>(L::add(gy, span)), one), last_row), L::addi(r_mid, away)),
                         none);
  // row by row, column by column, as long as some lane's range holds them (the lanes' ranges
  // end one after another: once none holds one, none holds a later one)
  for (int kr = 0;; ++kr) {
    const I row = L::addi(r_lo, L::seti(kr));
    const M in_row = L::mand(lit, L::lei(row, r_hi));
    if (!L::any(in_row)) break;
    for (int kc = 0;; ++kc) {
      const I col = L::addi(c_lo, L::seti(kc));
      const M m = L::mand(in_row, L::lei(col, c_hi));
      if (!L::any(m)) break;
      add_spot<L>(f, m, row, col, pu, pv, reach2, inv_sigma, weight, r, g, b);
    }
  }
}

// The white reference frame (Frame::white): every lit lane takes the projector's full light in
// all three channels. Lit lanes are those of the beam window (Light::beam), the pattern's extent
// widened by the farthest a blurred spot reaches: wherever a spot's light can land, the white
// frame's does, so no defocused rim is divided by the ambient light alone.
template <class L>
inline void add_white(typename L::M lit, typename L::F weight, typename L::F& r, typename L::F& g, typename L::F& b) {
  const typename L::F e = L::sel(lit, weight, L::set(0.0f));
  r = L::add(r, e);
  g = L::add(g, e);
  b = L::add(b, e);
}

// Lanes whose point the projector's depth `inv_depth` puts in shadow: its nearest surface at `at`
// (1/z as q) lies before the point (at z) by more than 0.2 % and 2 mm: z q > 1 + 2e-3 + 2e-3 q.
template <class L>
inline typename L::M shadowed(const float* inv_depth, typename L::I at, typename L::F z, typename L::M m) {
  // 0 where not looked up: nothing there. A gather, not a search for runs of 32: the lanes'
  // cells spread over 1 to 4+ runs about equally on a curved surface, and the branches that
  // looked for the runs cost more than they saved (the cylinder's frame 4-8 %)
  const typename L::F q = L::gather(inv_depth, at, m);
  const typename L::F limit = L::add(L::set(1.0f + 2e-3f), L::mul(L::set(2e-3f), q));
  return L::mand(L::gt(q, L::set(0.0f)), L::gt(L::mul(z, q), limit));
}

// A textured surface's colour at the lanes' pixels (rays dx, dy; triangles `tri`), multiplied
// into r, g, b: the texel nearest to the point's texture coordinates, repeated beyond [0, 1)
// (sim::texel_at's rule). Lanes of untextured triangles keep their light.
template <class L>
inline void apply_texture(const Frame& f, typename L::I tri, typename L::F dx, typename L::F dy, typename L::F& r,
                          typename L::F& g, typename L::F& b) {
  using F = typename L::F;
  using I = typename L::I;
  const std::size_t fields = triangle_stride(f.triangle_count);
  const I first = L::gatheri(f.texel, tri, L::lei(L::seti(0), tri));
  const typename L::M tex = L::lei(L::seti(0), first);
  if (!L::any(tex)) return;
  const auto field = [&](int k) { return L::gather(f.texture_map + static_cast<std::size_t>(k) * fields, tri, tex); };
  const auto dot = [&](int k) { return L::add(L::add(L::mul(field(k), dx), L::mul(field(k + 1), dy)), field(k + 2)); };
  const F z = L::div(L::set(1.0f), dot(kTexG0));
  const F tu = L::add(L::mul(dot(kTexAu0), z), field(kTexKu));
  const F tv = L::add(L::mul(dot(kTexAv0), z), field(kTexKv));
  // the fractions (anything not finite turns into a far index, clamped below)
  const F fu = L::sub(tu, L::cvt(floor_int<L>(tu)));
  const F fv = L::sub(tv, L::cvt(floor_int<L>(tv)));
  const I w = L::gatheri(f.texel + fields, tri, tex), h = L::gatheri(f.texel + 2 * fields, tri, tex);
  const I zero = L::seti(0), one = L::seti(1);
  const I x = L::maxi(zero, L::mini(L::cvtt(L::mul(fu, L::cvt(w))), L::subi(w, one)));
  const I y = L::maxi(zero, L::mini(L::cvtt(L::mul(L::sub(L::set(1.0f), fv), L::cvt(h))), L::subi(h, one)));
  const I at = L::addi(first, L::addi(L::muli(y, w), x));
  const I plane = L::muli(w, h);
  const F keep = L::set(1.0f);
  r = L::mul(r, L::sel(tex, L::gather(f.texels, at, tex), keep));
  g = L::mul(g, L::sel(tex, L::gather(f.texels, L::addi(at, plane), tex), keep));
  b = L::mul(b, L::sel(tex, L::gather(f.texels, L::addi(at, L::addi(plane, plane)), tex), keep));
}

// A coloured surface returns each channel's share of the light its brightest returns (tint); a
// printed one, its texel's too (apply_texture). Grey scenes never call it.
template <class L>
inline void surface_colour(const Frame& f, typename L::I tri, typename L::F dx, typename L::F dy, typename L::F& r,
                           typename L::F& g, typename L::F& b) {
  if (f.tint) {
    const std::size_t fields = triangle_stride(f.triangle_count);
    const typename L::M has = L::lei(L::seti(0), tri);
    r = L::mul(r, L::sel(has, L::gather(f.tint, tri, has), L::set(1.0f)));
    g = L::mul(g, L::sel(has, L::gather(f.tint + fields, tri, has), L::set(1.0f)));
    b = L::mul(b, L::sel(has, L::gather(f.tint + 2 * fields, tri, has), L::set(1.0f)));
  }
  if (f.texel) apply_texture<L>(f, tri, dx, dy, r, g, b);
}

// Added to a projector depth cell (fewer than 2^30) where the point's plane is never in the
// static scene's shadow: the static lookup is skipped there.
constexpr int kFreeCell = 1 << 30;

// The row buffers shade_rows works through (kRowArrays x Frame::stride values).
enum RowArray { kRowTriangle, kRowPu, kRowPv, kRowZp, kRowSigma, kRowWeight, kRowAmbient, kRowLit };

// The row buffers of shade_rows, laid out in its scratch (kRowArrays x Frame::stride values).
struct Rows {
  Rows(float* scratch, std::size_t stride)
      : tri(reinterpret_cast<std::int32_t*>(scratch + kRowTriangle * stride)), pu(scratch + kRowPu * stride),
        pv(scratch + kRowPv * stride), zp(scratch + kRowZp * stride), sigma(scratch + kRowSigma * stride),
        weight(scratch + kRowWeight * stride), ambient(scratch + kRowAmbient * stride),
        lit(reinterpret_cast<std::int32_t*>(scratch + kRowLit * stride)) {}
  std::int32_t* tri;
  float *pu, *pv, *zp, *sigma, *weight, *ambient;
  // per pixel: the projector depth's cell to look up (plus kFreeCell where the static scene
  // casts no shadow on the point's plane), or -1 (no surface, or beyond the beam); after the
  // lookups, 0 (lit) or -1
  std::int32_t* lit;
};

// The kernel's stages work on whole rows, each a loop of lookups independent of one another;
// always inlined, they compile to the one loop nest they were written as.
#define CELL_STAGE [[gnu::always_inline]] inline

// 1. the triangle behind each pixel (the z-buffer's band holds every cell these rows see)
template <class L>
CELL_STAGE void find_triangles(const Frame& f, std::size_t first, const Rows& rows) {
  using I = typename L::I;
  using M = typename L::M;
  const I base = L::seti(static_cast<int>(f.cell_base));
  for (int u = 0; u < f.width; u += L::N) {
    const I at = L::loadi(f.zcell + first + u);
    const I cell = L::subi(at, base);
    const M seen = L::mand(L::mand(L::lei(L::seti(0), at), L::lei(L::seti(0), cell)),
                           L::lei(cell, L::seti(static_cast<int>(f.cells) - 1)));
    const int run = f.zrun[(first + u) / 16];
    L::storei(rows.tri + u, L::gatheri_run(f.cell_triangle, f.cells, cell, seen,
                                          run < 0 ? -1 : run - static_cast<std::int64_t>(f.cell_base)));
  }
}

// The ambient light of lanes whose triangles all lie outside the beam (Frame::outside_from):
// neither the point nor the projector is needed (the full path gives the same: G = 0).
template <class L>
CELL_STAGE typename L::F ambient_alone(const Frame& f, typename L::I tri, typename L::M has) {
  using F = typename L::F;
  using M = typename L::M;
  const std::size_t fields = triangle_stride(f.triangle_count);
  const float* ambient = f.triangles + kAmbient * fields;
  F a = L::set(0.0f);
  if (!L::permute_fields(ambient, fields, 1, tri, has, &a)) {
    const int t = L::lane(tri, L::first(has));
    const M same = L::mand(has, L::eqi(tri, L::seti(t)));
    a = L::sel(same, L::set(ambient[t]), L::set(0.0f));
    const M left = L::mand(has, L::mnot(same));
    if (L::any(left)) a = L::sel(left, L::gather(ambient, tri, left), a);
  }
  return a;
}

// The lanes' triangles' fields: where their ids lie in one run of 32 (a wall's one plane, a
// tessellated surface's few neighbouring ones), two loads and a permutation per field, where
// the unit has them; else each distinct one broadcast (a row of pixels crosses few), up to
// four, then gathers.
template <class L>
CELL_STAGE void triangle_fields(const Frame& f, typename L::I tri, typename L::M has, typename L::F (&field)[kTriangleFields]) {
  using M = typename L::M;
  const std::size_t fields = triangle_stride(f.triangle_count);
  for (auto& x : field) x = L::set(0.0f);
  M left = has;
  const auto broadcast = [&] {
    const int t = L::lane(tri, L::first(left));
    const M same = L::mand(left, L::eqi(tri, L::seti(t)));
    for (int k = 0; k < kTriangleFields; ++k) field[k] = L::sel(same, L::set(f.triangles[k * fields + t]), field[k]);
    left = L::mand(left, L::mnot(same));
  };
  if (!L::permute_fields(f.triangles, fields, kTriangleFields, tri, has, field)) {
    for (int pass = 0; pass < 4 && L::any(left); ++pass) broadcast();
    if (L::any(left))
      for (int k = 0; k < kTriangleFields; ++k)
        field[k] = L::sel(left, L::gather(f.triangles + k * fields, tri, left), field[k]);
  }
}

// 2. the surface point of N pixels: where it lies on the projector's plane, how blurred, what
// it returns; and the projector depth cell its shadow test reads (Rows::lit)
template <class L>
CELL_STAGE void surface_point(const Frame& f, std::size_t first, int u, const Rows& rows) {
  using F = typename L::F;
  using I = typename L::I;
  using M = typename L::M;
  const F zero = L::set(0.0f);
  const I none = L::seti(-1);
  const DepthView& pd = f.projector_depth;
  const I tri = L::loadi(rows.tri + u);
  const M has = L::lei(L::seti(0), tri);
  if (!L::any(has) || !L::any(L::mand(has, L::lei(tri, L::seti(f.outside_from - 1))))) {
    L::store(rows.ambient + u, L::any(has) ? ambient_alone<L>(f, tri, has) : zero);
    L::storei(rows.lit + u, none);
    return;
  }
  F field[kTriangleFields];
  triangle_fields<L>(f, tri, has, field);
  const F dx = L::load(f.ray_x + first + u), dy = L::load(f.ray_y + first + u);
  const F inv_zc = L::add(L::add(L::mul(field[kG0], dx), L::mul(field[kG1], dy)), field[kG2]);
  const auto row_of = [&](int k) {
    const float* m = f.m[k];
    return L::add(L::add(L::add(L::mul(L::set(m[0]), dx), L::mul(L::set(m[1]), dy)), L::set(m[2])),
                  L::mul(L::set(m[3]), inv_zc));
  };
  const F h0 = row_of(0), h1 = row_of(1), h2 = row_of(2);
  L::store(rows.ambient + u, L::sel(has, field[kAmbient], zero));
  // z_c = 1 / s and 1 / h_2 from one division
  const F both = L::div(L::set(1.0f), L::mul(inv_zc, h2));
  const F zc = L::mul(both, h2);
  const F zp = L::mul(h2, zc);
  const M ok = L::mand(has, L::mand(L::gt(inv_zc, L::set(1e-6f)), L::gt(zp, L::set(1e-3f))));
  if (!L::any(ok)) {
    L::storei(rows.lit + u, none);
    return;
  }
  const F inv_h2 = L::mul(both, inv_zc);
  const F pu = L::mul(h0, inv_h2), pv = L::mul(h1, inv_h2);
  // the projector's depth cell nearest to (u_p, v_p): beyond its window no spot reaches, and a
  // point there takes the ambient light alone (most of a frame: the walls beside the beam), so
  // its blur and returned light are not needed
  const I x = L::addi(floor_int<L>(L::add(pu, L::set(0.5f))), L::seti(pd.offset_x));
  const I y = L::addi(floor_int<L>(L::add(pv, L::set(0.5f))), L::seti(pd.offset_y));
  const M inside = L::mand(L::mand(L::lei(L::seti(0), x), L::lei(x, L::seti(pd.width - 1))),
                           L::mand(L::lei(L::seti(0), y), L::lei(y, L::seti(pd.height - 1))));
  const M beam = L::mand(ok, inside);
  if (!L::any(beam)) {
    L::storei(rows.lit + u, none);
    return;
  }
  // the projector's defocus at z_p, with the camera pixel's own size on its plane
  const F outside = L::max(L::max(zero, L::sub(L::set(f.focus_near), zp)), L::sub(zp, L::set(f.focus_far)));
  const F blur = L::add(L::set(f.focused_blur), L::mul(L::set(f.defocus_per_m), outside));
  const F pixel = L::mul(L::set(f.pixel_scale), inv_h2);
  const F sigma = L::add(L::sqrt(L::add(L::mul(blur, blur), L::mul(L::mul(L::set(0.083f), pixel), pixel))), L::set(1e-6f));
  // the light returned: K / |L|^3
  const F lx = L::sub(L::set(f.qx), L::mul(dx, zc));
  const F ly = L::sub(L::set(f.qy), L::mul(dy, zc));
  const F lz = L::sub(L::set(f.qz), zc);
  const F dist2 = L::add(L::add(L::mul(lx, lx), L::mul(ly, ly)), L::mul(lz, lz));
  // K < 0: the plane is never in the static scene's shadow (Light::never_shadowed), |K| its K
  const M free = L::lt(field[kReturn], zero);
  const F k_return = L::max(field[kReturn], L::sub(zero, field[kReturn]));
  L::store(rows.weight + u, L::div(k_return, L::mul(dist2, L::sqrt(dist2))));
  L::store(rows.pu + u, pu);
  L::store(rows.pv + u, pv);
  L::store(rows.zp + u, zp);
  L::store(rows.sigma + u, sigma);
  const I at = L::addi(L::muli(y, L::seti(pd.width)), x);
  // step 3 looks these cells up a row later: asked for now, they arrive meanwhile (the lookups
  // of a curved surface's shadowed points wander over the projector's depth, and waiting for
  // them was a fifth of the cylinder's frame)
  L::prefetch(pd.inv_depth, at, L::mand(beam, L::mnot(free)));
  if (f.arm_depth.inv_depth) L::prefetch(f.arm_depth.inv_depth, at, beam);
  L::storei(rows.lit + u, L::seli(beam, L::seli(free, L::addi(at, L::seti(kFreeCell)), at), none));
}

// 3. shadows: again lookups independent of one another
template <class L>
CELL_STAGE void shadow_tests(const Frame& f, const Rows& rows) {
  using F = typename L::F;
  using I = typename L::I;
  using M = typename L::M;
  for (int u = 0; u < f.width; u += L::N) {
    const I marked = L::loadi(rows.lit + u);
    const M look = L::lei(L::seti(0), marked);
    if (!L::any(look)) continue;
    const M free = L::lei(L::seti(kFreeCell), marked);
    const I at = L::seli(free, L::subi(marked, L::seti(kFreeCell)), marked);
    const M check = L::mand(look, L::mnot(free));
    const F zp = L::load(rows.zp + u);
    M dark = L::any(check) ? shadowed<L>(f.projector_depth.inv_depth, at, zp, check) : check;
    if (f.arm_depth.inv_depth) dark = L::mor(dark, shadowed<L>(f.arm_depth.inv_depth, at, zp, look));
    L::storei(rows.lit + u, L::seli(L::mand(look, L::mnot(dark)), L::seti(0), L::seti(-1)));
  }
}

// The sensor on N pixels' light of one channel: exposure, read and shot noise, rounded and
// clamped to 8 bits. `known`/`known_sd`: the standard deviation of the last values seen, kept
// while the values repeat (the ambient on one surface).
template <class L>
CELL_STAGE typename L::I sense(const Frame& f, typename L::F light, const float* noise, typename L::F& known,
                               typename L::F& known_sd) {
  using F = typename L::F;
  const F value = L::mul(L::set(f.gain), light);
  F level = value;
  if (f.noisy) {
    if (!L::all(L::eq(value, known))) {
      known_sd = L::sqrt(L::add(L::set(f.read_var), L::mul(L::set(f.shot), L::max(value, L::set(0.0f)))));
      known = value;
    }
    level = L::add(value, L::mul(known_sd, L::load(noise)));
  }
  // rounded, clamped to [0, 255] (where the unit's byte store saturates, the store clamps
  // above: the truncation of anything from 255 up is 255 or more, INT_MIN beyond int)
  const F above_zero = L::max(L::add(level, L::set(0.5f)), L::set(0.0f));
  if constexpr (requires { L::kStoreSaturates; })
    return L::cvtt(above_zero);
  else
    return L::cvtt(L::min(above_zero, L::set(255.0f)));
}

// 4. the spots' light, then the sensor, into image row v
template <class L>
CELL_STAGE void expose_row(const Frame& f, int v, int v1, std::size_t first, const Rows& rows, std::uint8_t* row,
                           const std::uint32_t* offsets) {
  using F = typename L::F;
  using I = typename L::I;
  using M = typename L::M;
  constexpr int N = L::N;
  std::uint8_t bytes[3 * 16];
  F known = L::set(-1.0f), known_sd = L::set(0.0f);
  for (int u = 0; u < f.width; u += N) {
    // the next row's lens tables (3.7 MB a frame, beyond the core's cache) asked for while
    // this one is finished: step 1 of each row waited for them
    if (v + 1 < v1) {
      const std::size_t next = first + static_cast<std::size_t>(f.stride) + static_cast<std::size_t>(u);
      _mm_prefetch(reinterpret_cast<const char*>(f.zcell + next), _MM_HINT_T0);
      _mm_prefetch(reinterpret_cast<const char*>(f.ray_x + next), _MM_HINT_T0);
      _mm_prefetch(reinterpret_cast<const char*>(f.ray_y + next), _MM_HINT_T0);
    }
    F r = L::load(rows.ambient + u), g = r, b = r;
    const M lit = L::lei(L::seti(0), L::loadi(rows.lit + u));
    if (L::any(lit) && f.white)
      add_white<L>(lit, L::load(rows.weight + u), r, g, b);
    else if (L::any(lit))
      add_spots<L>(f, lit, L::load(rows.pu + u), L::load(rows.pv + u), L::load(rows.sigma + u), L::load(rows.weight + u),
                   r, g, b);
    if (f.tint || f.texel)
      surface_colour<L>(f, L::loadi(rows.tri + u), L::load(f.ray_x + first + u), L::load(f.ray_y + first + u), r, g, b);
    const F rgb[3] = {r, g, b};
    I out[3];
    const std::size_t noise_at = static_cast<std::size_t>(u % kNoiseChunk);
    for (int c = 0; c < 3; ++c)
      out[c] = sense<L>(f, rgb[c], f.noise_pool + offsets[c * 256 + u / kNoiseChunk] + noise_at, known, known_sd);
    if (u + N <= f.width) {
      L::store_rgb(row + 3 * u, out[0], out[1], out[2]);
    } else {
      L::store_rgb(bytes, out[0], out[1], out[2]);
      for (int k = 0; k < 3 * (f.width - u); ++k) row[3 * u + k] = bytes[k];
    }
  }
}

template <class L>
void shade_rows(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch) {
  const std::size_t stride = static_cast<std::size_t>(f.stride);
  const Rows rows(scratch, stride);
  const int chunks = (f.stride + kNoiseChunk - 1) / kNoiseChunk;
  std::uint32_t offsets_buf[3 * 256];  // widths are bounded at load (Intrinsics: at most 4096)
  for (int v = v0; v < v1; ++v) {
    const std::size_t first = static_cast<std::size_t>(v) * stride;
    find_triangles<L>(f, first, rows);
    for (int u = 0; u < f.width; u += L::N) surface_point<L>(f, first, u, rows);
    shadow_tests<L>(f, rows);
    // each channel's noise offsets for the row's chunks
    for (int c = 0; c < 3; ++c) {
      if constexpr (requires { L::noise_offsets(f, v, c, chunks, offsets_buf); })
        L::noise_offsets(f, v, c, chunks < 256 ? chunks : 256, offsets_buf + c * 256);  // where the unit has 64-bit lanes
      else
        for (int k = 0; k < chunks && k < 256; ++k) offsets_buf[c * 256 + k] = noise_offset(f, v, c, k);
    }
    expose_row<L>(f, v, v1, first, rows, image + static_cast<std::size_t>(v) * step, offsets_buf);
  }
}

#undef CELL_STAGE

}  // namespace
}  // namespace sim::shading
