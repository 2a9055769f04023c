#include "sim/render/rasterizer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <immintrin.h>

#include "sim/render/lane_masks.hpp"
#include "sim/render/vector_unit.hpp"

namespace sim {
namespace {

constexpr double kNear = 0.01;  // metres

struct ScreenVertex {
  double u, v, inv_z;
};

// fill_triangle's row spans for rows y..y+3, with AVX2: per edge the same c = b y + c,
// -(c + 1e-9) / a, std::max / std::min (maxpd and minpd return their second operand for a
// NaN, as std::max(lo, v) keeps lo), the same ceil, floor and truncating conversion (an
// out-of-range value becomes INT_MIN in both). A row outside an edge parallel to the rows is
// empty (the scalar loop's hi = lo - 1).
__attribute__((target("avx2"))) void spans4(int y, int x0, int x1, const Affine* edges, int n, int* xa, int* xb) {
  const __m256d yv = _mm256_setr_pd(y, y + 1, y + 2, y + 3);
  __m256d lo = _mm256_set1_pd(x0), hi = _mm256_set1_pd(x1);
  __m256d empty = _mm256_setzero_pd();
  for (int k = 0; k < n; ++k) {
    const Affine& e = edges[k];
    const __m256d c = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(e.b), yv), _mm256_set1_pd(e.c));
    if (e.a > 1e-15 || e.a < -1e-15) {
      const __m256d bound = _mm256_div_pd(_mm256_xor_pd(_mm256_add_pd(c, _mm256_set1_pd(1e-9)), _mm256_set1_pd(-0.0)),
                                          _mm256_set1_pd(e.a));
      if (e.a > 0) lo = _mm256_max_pd(bound, lo);
      else hi = _mm256_min_pd(bound, hi);
    } else {
      empty = _mm256_or_pd(empty, _mm256_cmp_pd(c, _mm256_set1_pd(-1e-9), _CMP_LT_OQ));
    }
  }
  __m128i a = _mm_max_epi32(_mm_set1_epi32(x0), _mm256_cvttpd_epi32(_mm256_ceil_pd(lo)));
  __m128i b = _mm_min_epi32(_mm_set1_epi32(x1), _mm256_cvttpd_epi32(_mm256_floor_pd(hi)));
  b = _mm_blendv_epi8(b, _mm_sub_epi32(a, _mm_set1_epi32(1)), lanes32(empty));
  _mm_store_si128(reinterpret_cast<__m128i*>(xa), a);
  _mm_store_si128(reinterpret_cast<__m128i*>(xb), b);
}

// Four rows' spans filled together, with AVX2. 1/z along a row is the scalar loop's running
// sum q += dq, one rounding per pixel; the four rows' sums run side by side in one vector
// (the same additions, each row's in its own lane), then each row's pixels are compared and
// written eight at a time (q > inv_depth, as the scalar loop: nearer wins, NaN never).
// The four rows' running sums, row r's at sums[r * len]; len = 0: no row has a span.
__attribute__((target("avx2"))) std::size_t running_sums4(const int* xa, const int* xb, const float* q0, float dq,
                                                         std::vector<float>& sums) {
  int longest = 0;
  for (int r = 0; r < 4; ++r) longest = std::max(longest, xb[r] - xa[r] + 1);
  if (longest <= 0) return 0;
  const std::size_t len = (static_cast<std::size_t>(longest) + 3) & ~std::size_t{3};
  if (sums.size() < 4 * len) sums.resize(4 * len);
  __m128 q = _mm_loadu_ps(q0);
  const __m128 step = _mm_set1_ps(dq);
  for (std::size_t k = 0; k < len; k += 4) {
    __m128 a = q, b = _mm_add_ps(a, step), c = _mm_add_ps(b, step), d = _mm_add_ps(c, step);
    q = _mm_add_ps(d, step);
    _MM_TRANSPOSE4_PS(a, b, c, d);  // a: row 0's sums k..k+3, b: row 1's, ...
    _mm_storeu_ps(&sums[k], a);
    _mm_storeu_ps(&sums[len + k], b);
    _mm_storeu_ps(&sums[2 * len + k], c);
    _mm_storeu_ps(&sums[3 * len + k], d);
  }
  return len;
}

// Row r of the four: its running sums and the buffer's cells from its first pixel; n = 0 when
// the row has no span.
struct RowSpan {
  const float* sum;
  float* inv_depth;
  std::int32_t* tri;
  int n;
};
RowSpan row_span(int r, int y, const int* xa, const int* xb, std::size_t len, const std::vector<float>& sums,
                 DepthBuffer& out) {
  if (xa[r] > xb[r]) return {nullptr, nullptr, nullptr, 0};
  const std::size_t first = static_cast<std::size_t>(y + r - out.row0) * out.width + xa[r];
  return {&sums[r * len], &out.inv_depth[first], &out.triangle[first], xb[r] - xa[r] + 1};
}

__attribute__((target("avx2"))) void fill_spans4(int y, const int* xa, const int* xb, const float* q0, float dq,
                                                 std::int32_t id, DepthBuffer& out, std::vector<float>& sums) {
  const std::size_t len = running_sums4(xa, xb, q0, dq, sums);
  if (len == 0) return;
  const __m256i ids = _mm256_set1_epi32(id);
  for (int r = 0; r < 4; ++r) {
    const auto [sum, inv_depth, tri, n] = row_span(r, y, xa, xb, len, sums, out);
    int x = 0;
    for (; x + 8 <= n; x += 8) {
      const __m256 qv = _mm256_loadu_ps(sum + x), dv = _mm256_loadu_ps(inv_depth + x);
      const __m256 nearer = _mm256_cmp_ps(qv, dv, _CMP_GT_OQ);
      _mm256_storeu_ps(inv_depth + x, _mm256_blendv_ps(dv, qv, nearer));
      const __m256i tv = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(tri + x));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(tri + x),
                          _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(tv), _mm256_castsi256_ps(ids), nearer)));
    }
    for (; x < n; ++x)
      if (sum[x] > inv_depth[x]) {
        inv_depth[x] = sum[x];
        tri[x] = id;
      }
  }
}

// Sixteen rows' spans of at most kThinColumns pixels (`count`: each row's pixels less one,
// `rows`: the rows with any, `q`: their first 1/z), each row's running sums in one vector, with
// the same number of additions for all sixteen (lanes past a row's span are not written), then
// its pixels compared and written under a mask (a remainder loop mispredicted its branch on
// every short span: the tessellated cylinder's are short).
__attribute__((target(SIM_AVX512_TARGET))) void thin_rows(int y, int y1, __m512i xa, __m512i count, __mmask16 rows,
                                                            __m512 q, __m512 step, __m512i ids, DepthBuffer& out) {
  const int columns = _mm512_mask_reduce_max_epi32(rows, count) + 1;
  // each row's first cell, (y + r - row0) width + xa (0 for an empty row), its 1/z and which of
  // its columns it covers
  const __m512i row = _mm512_add_epi32(_mm512_set1_epi32(y - out.row0), _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9,
                                                                                           10, 11, 12, 13, 14, 15));
  alignas(64) std::int32_t cell[16], covered[16];
  _mm512_store_si512(cell, _mm512_maskz_add_epi32(rows, _mm512_mullo_epi32(row, _mm512_set1_epi32(out.width)), xa));
  // (1 << (count + 1)) - 1, 0 for an empty row
  _mm512_store_si512(covered, _mm512_maskz_sub_epi32(rows, _mm512_sllv_epi32(_mm512_set1_epi32(2), count),
                                                    _mm512_set1_epi32(1)));
  const int last = std::min(15, y1 - y);
  for (int r = 0; r <= last; ++r) {
    // lane k: the first 1/z and k additions of dq (the same additions, one rounding each)
    // (row r's first 1/z in every lane, from q's lane r: no trip through memory)
    __m512 qv = _mm512_permutexvar_ps(_mm512_set1_epi32(r), q);
    for (int j = 1; j < columns; ++j) qv = _mm512_mask_add_ps(qv, static_cast<__mmask16>(0xFFFFu << j), qv, step);
    const __mmask16 in = static_cast<__mmask16>(covered[r]);
    float* inv_depth = out.inv_depth.data() + cell[r];
    const __m512 dv = _mm512_maskz_loadu_ps(in, inv_depth);
    const __mmask16 nearer = _mm512_mask_cmp_ps_mask(in, qv, dv, _CMP_GT_OQ);  // as the scalar q > inv_depth
    _mm512_mask_storeu_ps(inv_depth, nearer, qv);
    _mm512_mask_storeu_epi32(out.triangle.data() + cell[r], nearer, ids);
  }
}

// running_sums4 for sixteen rows, `columns` long (rounded up to 4): row r's at sums[r * len].
// The four groups of four rows run side by side, so that each group's chain of additions (one
// per pixel, as the scalar loop's) waits on the others' and not on itself.
__attribute__((target(SIM_AVX512_TARGET))) std::size_t running_sums16(int columns, const float* q0, float dq,
                                                                        std::vector<float>& sums) {
  const std::size_t len = (static_cast<std::size_t>(columns) + 3) & ~std::size_t{3};
  if (sums.size() < 16 * len) sums.resize(16 * len);
  __m128 q[4] = {_mm_load_ps(q0), _mm_load_ps(q0 + 4), _mm_load_ps(q0 + 8), _mm_load_ps(q0 + 12)};
  const __m128 step = _mm_set1_ps(dq);
  float* out = sums.data();
  for (std::size_t k = 0; k < len; k += 4)
    for (int g = 0; g < 4; ++g) {
      __m128 a = q[g], b = _mm_add_ps(a, step), c = _mm_add_ps(b, step), d = _mm_add_ps(c, step);
      q[g] = _mm_add_ps(d, step);
      _MM_TRANSPOSE4_PS(a, b, c, d);  // a: row 4g's sums k..k+3, b: row 4g + 1's, ...
      float* at = out + 4 * g * len + k;
      _mm_storeu_ps(at, a);
      _mm_storeu_ps(at + len, b);
      _mm_storeu_ps(at + 2 * len, c);
      _mm_storeu_ps(at + 3 * len, d);
    }
  return len;
}

// fill_polygon with AVX-512, sixteen rows at a time: the rows' spans as spans4 finds them (the
// same divisions, comparisons and roundings, eight rows per vector of doubles) and their first
// 1/z, then the rows' pixels: short spans (a tessellated surface's strips, 2-4 px) by
// thin_rows, long ones (a wall's) from running_sums16. Row by row, a short span's own bounds,
// first 1/z and variable-length loop cost more than its pixels did (a third of the cylinder's
// frame was its rasteriser), and a long one's running sums waited on each other; here sixteen
// rows share them.
constexpr int kThinColumns = 16;
__attribute__((target(SIM_AVX512_TARGET))) void fill_rows16_avx512(int y0, int y1, int x0, int x1,
                                                                     const Affine* edges, int n, const Affine& iz,
                                                                     std::int32_t id, DepthBuffer& out,
                                                                     std::vector<float>& sums) {
  const __m512i ids = _mm512_set1_epi32(id);
  const __m512 step = _mm512_set1_ps(static_cast<float>(iz.a));
  const __m512d up = _mm512_setr_pd(0, 1, 2, 3, 4, 5, 6, 7);
  for (int y = y0; y <= y1; y += 16) {
    __m256i xa_h[2], xb_h[2];
    __m256 q_h[2];
    for (int h = 0; h < 2; ++h) {
      const __m512d yv = _mm512_add_pd(_mm512_set1_pd(y + 8 * h), up);
      __m512d lo = _mm512_set1_pd(x0), hi = _mm512_set1_pd(x1);
      __mmask8 empty = 0;
      for (int k = 0; k < n; ++k) {
        const Affine& e = edges[k];
        const __m512d c = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(e.b), yv), _mm512_set1_pd(e.c));
        if (e.a > 1e-15 || e.a < -1e-15) {
          const __m512d bound = _mm512_div_pd(_mm512_xor_pd(_mm512_add_pd(c, _mm512_set1_pd(1e-9)), _mm512_set1_pd(-0.0)),
                                              _mm512_set1_pd(e.a));
          if (e.a > 0) lo = _mm512_max_pd(bound, lo);
          else hi = _mm512_min_pd(bound, hi);
        } else {
          empty |= _mm512_cmp_pd_mask(c, _mm512_set1_pd(-1e-9), _CMP_LT_OQ);
        }
      }
      // rows past the polygon's last are empty
      empty |= _mm512_cmp_pd_mask(yv, _mm512_set1_pd(y1), _CMP_GT_OQ);
      const __m256i a = _mm256_max_epi32(_mm256_set1_epi32(x0),
                                         _mm512_cvttpd_epi32(_mm512_roundscale_pd(lo, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC)));
      const __m256i b = _mm256_min_epi32(_mm256_set1_epi32(x1),
                                         _mm512_cvttpd_epi32(_mm512_roundscale_pd(hi, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)));
      xa_h[h] = a;
      xb_h[h] = _mm256_mask_blend_epi32(empty, b, _mm256_sub_epi32(a, _mm256_set1_epi32(1)));
      // the row's first 1/z, iz.at(xa, y) in double, then rounded to float
      const __m512d at = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(iz.a), _mm512_cvtepi32_pd(a)),
                                                     _mm512_mul_pd(_mm512_set1_pd(iz.b), yv)),
                                       _mm512_set1_pd(iz.c));
      q_h[h] = _mm512_cvtpd_ps(at);
    }
    const __m512i xa = _mm512_inserti64x4(_mm512_castsi256_si512(xa_h[0]), xa_h[1], 1);
    const __m512i xb = _mm512_inserti64x4(_mm512_castsi256_si512(xb_h[0]), xb_h[1], 1);
    __m512 q = _mm512_insertf32x8(_mm512_castps256_ps512(q_h[0]), q_h[1], 1);
    const __m512i count = _mm512_sub_epi32(xb, xa);  // the span's pixels less one
    const __mmask16 rows = _mm512_cmpge_epi32_mask(count, _mm512_setzero_si512());
    if (!rows) continue;
    const int columns = _mm512_mask_reduce_max_epi32(rows, count) + 1;
    if (columns <= kThinColumns) {
      thin_rows(y, y1, xa, count, rows, q, step, ids, out);
    } else {
      // long spans (a wall's): the running sums of the sixteen rows, then each row sixteen
      // pixels at a time
      alignas(64) std::int32_t first_x[16], last_x[16];
      alignas(64) float first[16];
      _mm512_store_si512(first_x, xa);
      _mm512_store_si512(last_x, _mm512_mask_blend_epi32(rows, _mm512_sub_epi32(xa, _mm512_set1_epi32(1)),
                                                         _mm512_add_epi32(xa, count)));
      _mm512_store_ps(first, q);
      const std::size_t len = running_sums16(columns, first, static_cast<float>(iz.a), sums);
      const int last = std::min(15, y1 - y);
      for (int r = 0; r <= last; ++r) {
        const int n_r = last_x[r] - first_x[r] + 1;
        if (n_r <= 0) continue;
        const std::size_t at = static_cast<std::size_t>(y + r - out.row0) * out.width + first_x[r];
        const float* sum = &sums[r * len];
        float* inv_depth = &out.inv_depth[at];
        std::int32_t* tri = &out.triangle[at];
        for (int x = 0; x < n_r; x += 16) {
          const __mmask16 in = n_r - x >= 16 ? __mmask16{0xFFFF} : static_cast<__mmask16>((1u << (n_r - x)) - 1);
          const __m512 qv = _mm512_maskz_loadu_ps(in, sum + x), dv = _mm512_maskz_loadu_ps(in, inv_depth + x);
          const __mmask16 nearer = _mm512_mask_cmp_ps_mask(in, qv, dv, _CMP_GT_OQ);  // as the scalar q > inv_depth
          _mm512_mask_storeu_ps(inv_depth + x, nearer, qv);
          _mm512_mask_storeu_epi32(tri + x, nearer, ids);
        }
      }
    }
  }
}

// The rows a polygon spanning image rows [v_lo, v_hi] may cover in a buffer with margin m
// (before any clip).
void polygon_rows(double v_lo, double v_hi, double m, int& y0, int& y1) {
  const double lo = std::ceil(v_lo + m), hi = std::floor(v_hi + m);
  // beyond any buffer (or NaN): no rows (the casts below would be undefined)
  if (!(lo > -1e9 && hi < 1e9)) {
    y0 = 1;
    y1 = 0;
    return;
  }
  y0 = static_cast<int>(lo);
  y1 = static_cast<int>(hi);
}

// A convex polygon of 3 or 4 vertices (a triangle, or a flat quad: two coplanar triangles of a
// mesh), counter-clockwise or clockwise: the pixels inside every edge, 1/z from the plane of its
// first three vertices (solve_edges).
void fill_polygon(const ScreenTriangle& t, DepthBuffer& out, const RasterClip& clip, VectorUnit unit,
                  std::vector<float>& sums) {
  const int x0 = std::max(clip.x0, t.x0);
  const int x1 = std::min({out.width - 1, clip.x1, t.x1});
  const int y0 = std::max({clip.y0, out.row0, t.y0});
  const int y1 = std::min({out.height - 1, out.row0 + out.rows - 1, clip.y1, t.y1});
  if (x0 > x1 || y0 > y1) return;
  const Affine* const edges = t.edge;
  const int n = t.n;
  const Affine& iz = t.iz;
  const std::int32_t id = t.id;
  const auto fill_span = [&](int y, int xa, int xb) {
    float q = static_cast<float>(iz.at(xa, y));
    const float dq = static_cast<float>(iz.a);
    float* inv_depth = &out.inv_depth[static_cast<std::size_t>(y - out.row0) * out.width];
    std::int32_t* tri = &out.triangle[static_cast<std::size_t>(y - out.row0) * out.width];
    for (int x = xa; x <= xb; ++x, q += dq) {
      if (q > inv_depth[x]) {  // nearer
        inv_depth[x] = q;
        tri[x] = id;
      }
    }
  };
  if (unit == VectorUnit::kAvx512) {
    fill_rows16_avx512(y0, y1, x0, x1, edges, n, iz, id, out, sums);
    return;
  }
  if (unit == VectorUnit::kAvx2) {
    // the spans of four rows at once: the same divisions, comparisons and roundings
    alignas(16) int xa[4], xb[4];
    alignas(16) float q0[4];
    for (int y = y0; y <= y1; y += 4) {
      spans4(y, x0, x1, edges, n, xa, xb);
      for (int r = 0; r < 4; ++r) {
        if (y + r > y1) xb[r] = xa[r] - 1;  // past the triangle's last row
        q0[r] = xa[r] <= xb[r] ? static_cast<float>(iz.at(xa[r], y + r)) : 0.f;
      }
      fill_spans4(y, xa, xb, q0, static_cast<float>(iz.a), id, out, sums);
    }
    return;
  }
  for (int y = y0; y <= y1; ++y) {
    // the span of this row inside all three edges, solved per edge (a x + b y + c >= 0), so
    // the loop below visits only covered pixels (thin triangles leave most of their box empty)
    double lo = x0, hi = x1;
    for (int k = 0; k < n; ++k) {
      const Affine* e = &edges[k];
      const double c = e->b * y + e->c;
      if (e->a > 1e-15) lo = std::max(lo, -(c + 1e-9) / e->a);
      else if (e->a < -1e-15) hi = std::min(hi, -(c + 1e-9) / e->a);
      else if (c < -1e-9) hi = lo - 1;  // parallel to this edge and outside it
    }
    const int xa = std::max(x0, static_cast<int>(std::ceil(lo))), xb = std::min(x1, static_cast<int>(std::floor(hi)));
    if (xa <= xb) fill_span(y, xa, xb);
  }
}

}  // namespace

int closed_orientation(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& triangles) {
  // each directed edge once, and its reverse present: closed and consistently wound
  std::unordered_map<std::uint64_t, int> edges;
  edges.reserve(3 * triangles.size());
  const auto key = [](int a, int b) { return static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32 | static_cast<std::uint32_t>(b); };
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e)
      if (++edges[key(t[e], t[(e + 1) % 3])] > 1) return 0;
  double volume = 0;  // six times the signed volume: positive when the normals point out
  for (const auto& t : triangles) {
    for (int e = 0; e < 3; ++e)
      if (!edges.count(key(t[(e + 1) % 3], t[e]))) return 0;
    volume += vertices[static_cast<std::size_t>(t[0])].dot(
        vertices[static_cast<std::size_t>(t[1])].cross(vertices[static_cast<std::size_t>(t[2])]));
  }
  return volume > 0 ? 1 : volume < 0 ? -1 : 0;
}

Eigen::Matrix<double, 2, 4> texture_map(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                        const std::array<Eigen::Vector2d, 3>& uv) {
  // x = a + s e1 + t e2 on the plane; s and t from the dual basis of (e1, e2) in it
  const Eigen::Vector3d e1 = b - a, e2 = c - a, n = e1.cross(e2);
  const double nn = n.squaredNorm();
  const Eigen::Vector3d ds = e2.cross(n) / nn, dt = n.cross(e1) / nn;
  Eigen::Matrix<double, 2, 3> m = (uv[1] - uv[0]) * ds.transpose() + (uv[2] - uv[0]) * dt.transpose();
  Eigen::Matrix<double, 2, 4> out;
  out.leftCols<3>() = m;
  out.col(3) = uv[0] - m * a;
  return out;
}

namespace {
// Whether the next triangle may shade as the same surface as the one before, as far as the
// texture goes: both untextured, or both textured with one map
bool same_texturing(const SceneTriangles& t, std::size_t p) {
  if (t.textured.size() <= p + 1) return t.textured.size() <= p || !t.textured[p];
  if (t.textured[p] != t.textured[p + 1]) return false;
  return !t.textured[p] || (t.uv_map[p] - t.uv_map[p + 1]).cwiseAbs().maxCoeff() <= 1e-9 * (1 + t.uv_map[p].cwiseAbs().maxCoeff());
}
}  // namespace

void append_triangles(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& triangles,
                      const Eigen::Isometry3d& world_T_mesh, int object, float albedo, SceneTriangles& t, int outward,
                      const std::vector<std::array<Eigen::Vector2d, 3>>* corner_uv,
                      const std::vector<std::uint8_t>* textured) {
  const auto base = static_cast<std::int32_t>(t.vertex_w.size());
  for (const Eigen::Vector3d& v : vertices) t.vertex_w.push_back(world_T_mesh * v);
  const bool mapped = corner_uv && textured && corner_uv->size() == triangles.size() && textured->size() == triangles.size();
  const std::array<int, 3>* previous = nullptr;  // the last triangle kept
  for (const auto& tri : triangles) {
    const Eigen::Vector3d& a = t.vertex_w[static_cast<std::size_t>(base + tri[0])];
    const Eigen::Vector3d& b = t.vertex_w[static_cast<std::size_t>(base + tri[1])];
    const Eigen::Vector3d& c = t.vertex_w[static_cast<std::size_t>(base + tri[2])];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-15) continue;  // degenerate: no surface
    t.a.push_back(a);
    t.b.push_back(b);
    t.c.push_back(c);
    t.corner.push_back({base + tri[0], base + tri[1], base + tri[2]});
    t.normal_w.push_back(n.normalized());
    t.offset.push_back(t.normal_w.back().dot(a));
    t.object.push_back(object);
    t.albedo.push_back(albedo);
    t.outward.push_back(static_cast<std::int8_t>(outward));
    t.quad_extra.push_back(-1);
    t.quad_edge.push_back(-1);
    if (mapped) {
      const std::size_t j = static_cast<std::size_t>(&tri - triangles.data());
      t.textured.resize(t.a.size() - 1, 0);
      t.uv_map.resize(t.a.size() - 1, Eigen::Matrix<double, 2, 4>::Zero());
      t.textured.push_back((*textured)[j]);
      t.uv_map.push_back((*textured)[j] ? texture_map(a, b, c, (*corner_uv)[j]) : Eigen::Matrix<double, 2, 4>::Zero());
    }
    const auto i = static_cast<std::int32_t>(t.a.size() - 1);
    std::int32_t plane = i;
    if (previous) {
      int shared = 0;
      for (int a : tri)
        for (int b : *previous) shared += a == b;
      const std::size_t p = static_cast<std::size_t>(i - 1);
      if (shared == 2 && t.normal_w[p].dot(t.normal_w.back()) > 1 - 1e-12 && std::abs(t.offset[p] - t.offset.back()) < 1e-12 &&
          same_texturing(t, p)) {
        plane = t.plane_of[p];
        // the quad the two make: the vertices they have in common, by position
        const Eigen::Vector3d* w[3] = {&t.a[p + 1], &t.b[p + 1], &t.c[p + 1]};
        const Eigen::Vector3d* mine[3] = {&t.a[p], &t.b[p], &t.c[p]};
        int extra = -1, in_both = 0;
        for (int q = 0; q < 3; ++q) {
          const bool in = *w[q] == *mine[0] || *w[q] == *mine[1] || *w[q] == *mine[2];
          in_both += in;
          if (!in) extra = q;
        }
        for (int e = 0; e < 3 && in_both == 2; ++e) {
          const Eigen::Vector3d& from = *mine[e];
          const Eigen::Vector3d& to = *mine[(e + 1) % 3];
          if ((from == *w[0] || from == *w[1] || from == *w[2]) && (to == *w[0] || to == *w[1] || to == *w[2])) {
            t.quad_extra[p] = static_cast<std::int8_t>(extra);
            t.quad_edge[p] = static_cast<std::int8_t>(e);
            break;
          }
        }
      }
    }
    t.plane_of.push_back(plane);
    previous = &tri;
  }
}

std::vector<float> beam_window(const DepthBuffer& d, const RasterClip& w) {
  std::vector<float> out;
  if (w.x0 > w.x1 || w.y0 > w.y1) return out;
  const std::size_t width = static_cast<std::size_t>(w.x1 - w.x0 + 1);
  out.reserve(width * static_cast<std::size_t>(w.y1 - w.y0 + 1));
  for (int y = w.y0; y <= w.y1; ++y) {
    const auto row = d.inv_depth.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(y) * d.width + w.x0);
    out.insert(out.end(), row, row + static_cast<std::ptrdiff_t>(width));
  }
  return out;
}

SceneTriangles collect_triangles(const World& world) {
  SceneTriangles t;
  const auto& objects = world.objects();
  for (std::size_t o = 0; o < objects.size(); ++o)
    append_triangles(objects[o].vertices_w, objects[o].triangles, Eigen::Isometry3d::Identity(), static_cast<int>(o),
                     static_cast<float>(objects[o].albedo), t, closed_orientation(objects[o].vertices_w, objects[o].triangles),
                     objects[o].texture ? &objects[o].corner_uv : nullptr, objects[o].texture ? &objects[o].textured : nullptr);
  return t;
}

void rasterize(const SceneTriangles& tris, const Eigen::Isometry3d& viewer_T_world, const Intrinsics& k, int margin,
               DepthBuffer& out, bool vector, bool avx512, bool cull) {
  clear_band(k, margin, 0, k.height + 2 * margin, out);
  rasterize_more(tris, 0, viewer_T_world, k, out, RasterClip{}, vector, avx512, cull);
}

void clear_band(const Intrinsics& k, int margin, int row0, int rows, DepthBuffer& out) {
  out.margin = margin;
  out.width = k.width + 2 * margin;
  out.height = k.height + 2 * margin;
  out.row0 = std::clamp(row0, 0, out.height);
  out.rows = std::clamp(rows, 0, out.height - out.row0);
  const std::size_t n = static_cast<std::size_t>(out.width) * out.rows;
  out.inv_depth.assign(n, 0.0f);
  out.triangle.assign(n, -1);
}

namespace {

// a quad on the screen that is convex, turning one way at every corner, and not degenerate
bool convex_quad(const ScreenVertex (&q)[4]) {
  double turn_sign = 0;
  for (int c = 0; c < 4; ++c) {
    const ScreenVertex &o = q[c], &p1 = q[(c + 1) % 4], &p2 = q[(c + 2) % 4];
    const double cross = (p1.u - o.u) * (p2.v - p1.v) - (p1.v - o.v) * (p2.u - p1.u);
    if (std::abs(cross) < 1e-9 || (turn_sign != 0 && (cross > 0) != (turn_sign > 0))) return false;
    turn_sign = cross;
  }
  return true;
}

// a triangle clipped against the near plane (Sutherland-Hodgman): a triangle or a quad
// remains; returns its corner count
int clip_near(const Eigen::Vector3d (&v)[3], Eigen::Vector3d (&poly)[4]) {
  int count = 0;
  for (int e = 0; e < 3; ++e) {
    const Eigen::Vector3d& p = v[e];
    const Eigen::Vector3d& q = v[(e + 1) % 3];
    const bool pin = p.z() >= kNear, qin = q.z() >= kNear;
    if (pin) poly[count++] = p;
    if (pin != qin) poly[count++] = p + (q - p) * ((kNear - p.z()) / (q.z() - p.z()));
  }
  return count;
}

ScreenVertex to_screen(const Intrinsics& k, const Eigen::Vector3d& p) {
  const Eigen::Vector2d s = pinhole_pixel(k, p);
  return ScreenVertex{s.x(), s.y(), 1.0 / p.z()};
}

// each vertex of triangles [first, end) once: in the viewer's frame, and on its image where in
// front of the near plane
void project_vertices(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                      const Intrinsics& k, std::vector<Eigen::Vector3d>& seen, std::vector<ScreenVertex>& screen) {
  std::size_t v_first = tris.vertex_w.size();
  for (std::size_t i = first; i < tris.a.size(); ++i)
    for (const std::int32_t v : tris.corner[i]) v_first = std::min(v_first, static_cast<std::size_t>(v));
  seen.resize(tris.vertex_w.size());
  screen.resize(tris.vertex_w.size());
  for (std::size_t v = v_first; v < tris.vertex_w.size(); ++v) {
    seen[v] = viewer_T_world * tris.vertex_w[v];
    if (seen[v].z() >= kNear) screen[v] = to_screen(k, seen[v]);
  }
}

}  // namespace

void project_triangles(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                       const Intrinsics& k, int margin, bool cull, std::vector<ScreenTriangle>& out, bool by_plane,
                       const std::vector<std::uint8_t>* moved, std::int32_t moved_by) {
  const auto add = [&](const ScreenVertex* p, int n, std::int32_t id) {
    ScreenTriangle& t = out.emplace_back();  // built in place (a polygon is 250 bytes), zeroed
    for (int i = 0; i < n; ++i) t.u[i] = p[i].u, t.v[i] = p[i].v, t.inv_z[i] = p[i].inv_z;
    t.n = n;
    t.id = id;
    solve_edges(t, margin);
    if (!(t.y0 <= t.y1 && t.x0 <= t.x1)) out.pop_back();
  };
  const Eigen::Vector3d viewer = viewer_T_world.inverse().translation();
  cull = cull && tris.outward.size() == tris.a.size();
  by_plane = by_plane && tris.plane_of.size() == tris.a.size();
  const auto id_of = [&](std::size_t i) {
    const std::int32_t id = by_plane ? tris.plane_of[i] : static_cast<std::int32_t>(i);
    return moved && i < moved->size() && (*moved)[i] ? id + moved_by : id;
  };
  const auto culled = [&](std::size_t i) {
    return cull && faces_away(tris, i, viewer);
  };
  const std::size_t end = tris.a.size();
  // (append_triangles builds them; triangles without them are projected one by one, unpaired)
  const bool indexed = tris.corner.size() == end && tris.quad_extra.size() == end && tris.quad_edge.size() == end;
  thread_local std::vector<Eigen::Vector3d> seen;
  thread_local std::vector<ScreenVertex> screen;
  if (indexed) project_vertices(tris, first, viewer_T_world, k, seen, screen);
  for (std::size_t i = first; i < end; ++i) {
    if (culled(i)) continue;
    Eigen::Vector3d v[3];
    if (indexed)
      for (int q = 0; q < 3; ++q) v[q] = seen[static_cast<std::size_t>(tris.corner[i][q])];
    else
      v[0] = viewer_T_world * tris.a[i], v[1] = viewer_T_world * tris.b[i], v[2] = viewer_T_world * tris.c[i];
    const int behind = (v[0].z() < kNear) + (v[1].z() < kNear) + (v[2].z() < kNear);
    if (behind == 3) continue;
    const std::int32_t id = id_of(i);
    if (behind == 0) {
      ScreenVertex s[3];
      for (int q = 0; q < 3; ++q) s[q] = indexed ? screen[static_cast<std::size_t>(tris.corner[i][q])] : to_screen(k, v[q]);
      // the next triangle, the other half of a flat quad: one polygon
      const std::size_t j = i + 1;
      if (by_plane && indexed && j < end && tris.quad_extra[i] >= 0 && tris.plane_of[j] == tris.plane_of[i] &&
          id_of(j) == id && !culled(j)) {
        const auto extra = static_cast<std::size_t>(tris.corner[j][static_cast<std::size_t>(tris.quad_extra[i])]);
        if (seen[extra].z() >= kNear) {
          // the quad: the new vertex between the shared edge's ends, in this triangle's order
          const int e = tris.quad_edge[i];
          const ScreenVertex q[4] = {s[e], screen[extra], s[(e + 1) % 3], s[(e + 2) % 3]};
          if (convex_quad(q)) {
            add(q, 4, id);
            ++i;  // the other half is in the quad
            continue;
          }
        }
      }
      add(s, 3, id);
      continue;
    }
    Eigen::Vector3d poly[4];
    const int count = clip_near(v, poly);
    for (int f = 1; f + 1 < count; ++f) {
      const ScreenVertex s[3] = {to_screen(k, poly[0]), to_screen(k, poly[f]), to_screen(k, poly[f + 1])};
      add(s, 3, id);
    }
  }
}

void solve_edges(ScreenTriangle& t, int margin) {
  const ScreenVertex p[4] = {{t.u[0], t.v[0], t.inv_z[0]}, {t.u[1], t.v[1], t.inv_z[1]}, {t.u[2], t.v[2], t.inv_z[2]},
                             {t.u[3], t.v[3], t.inv_z[3]}};
  const int n = t.n;
  const ScreenVertex &p0 = p[0], &p1 = p[1], &p2 = p[2];
  const double m = margin;
  double u_lo = p0.u, u_hi = p0.u, v_lo = p0.v, v_hi = p0.v;
  for (int i = 1; i < n; ++i) {
    u_lo = std::min(u_lo, p[i].u), u_hi = std::max(u_hi, p[i].u);
    v_lo = std::min(v_lo, p[i].v), v_hi = std::max(v_hi, p[i].v);
  }
  polygon_rows(v_lo, v_hi, m, t.y0, t.y1);
  const double area = (p1.u - p0.u) * (p2.v - p0.v) - (p1.v - p0.v) * (p2.u - p0.u);
  const double left = std::ceil(u_lo + m), right = std::floor(u_hi + m);
  // no area (or NaN): no columns; far beyond any buffer, as far as a cast can hold
  if (!(std::abs(area) >= 1e-12) || !(left <= right)) {
    t.x0 = 1;
    t.x1 = 0;
    return;
  }
  t.x0 = static_cast<int>(std::clamp(left, -1e9, 1e9));
  t.x1 = static_cast<int>(std::clamp(right, -1e9, 1e9));
  const double inv_area = 1.0 / area;
  const auto edge = [&](const ScreenVertex& s, const ScreenVertex& e) {
    // ((e.u - s.u) (y - s.v) - (e.v - s.v) (x - s.u)) / area, in buffer coordinates
    const double a = -(e.v - s.v) * inv_area, b = (e.u - s.u) * inv_area;
    return Affine{a, b, -(a * (s.u + m) + b * (s.v + m))};
  };
  // the first triangle's barycentric weights give 1/z; the polygon's edges bound it
  const Affine w0 = edge(p1, p2), w1 = edge(p2, p0), w2 = edge(p0, p1);
  t.iz = Affine{w0.a * p0.inv_z + w1.a * p1.inv_z + w2.a * p2.inv_z, w0.b * p0.inv_z + w1.b * p1.inv_z + w2.b * p2.inv_z,
                w0.c * p0.inv_z + w1.c * p1.inv_z + w2.c * p2.inv_z};
  if (n == 4) {
    for (int i = 0; i < 4; ++i) t.edge[i] = edge(p[i], p[(i + 1) % 4]);
  } else {
    t.edge[0] = w0, t.edge[1] = w1, t.edge[2] = w2;
  }
}

void fill_triangles(const std::vector<ScreenTriangle>& tris, DepthBuffer& out, const RasterClip& clip, bool vector,
                    bool avx512) {
  const VectorUnit unit = vector_unit(!vector, avx512);
  const int lo = std::max(clip.y0, out.row0), hi = std::min(clip.y1, out.row0 + out.rows - 1);
  thread_local std::vector<float> sums;  // the running sums of fill_spans4 and fill_rows16_avx512
  for (const ScreenTriangle& t : tris)
    if (t.y1 >= lo && t.y0 <= hi) fill_polygon(t, out, clip, unit, sums);
}

void fill_triangles(const std::vector<ScreenTriangle>& tris, const std::vector<std::int32_t>& which, DepthBuffer& out,
                    const RasterClip& clip, bool vector, bool avx512) {
  const VectorUnit unit = vector_unit(!vector, avx512);
  thread_local std::vector<float> sums;
  for (const std::int32_t i : which) fill_polygon(tris[static_cast<std::size_t>(i)], out, clip, unit, sums);
}

void rasterize_more(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                    const Intrinsics& k, DepthBuffer& out, const RasterClip& clip, bool vector, bool avx512,
                    bool cull) {
  std::vector<ScreenTriangle> screen;
  project_triangles(tris, first, viewer_T_world, k, out.margin, cull, screen);
  fill_triangles(screen, out, clip, vector, avx512);
}

}  // namespace sim
