#include "sim/render/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

#include <immintrin.h>
#include <opencv2/core/utility.hpp>

#include "servo/pattern/palette.hpp"
#include "sim/render/lane_masks.hpp"
#include "sim/render/render_parts.hpp"
#include "sim/render/vector_unit.hpp"

namespace sim {
namespace {

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// 0.5 erfc(x / sqrt 2), tabulated: std::erfc costs ~30 ns and runs once per lit pixel.
class EdgeProfile {
 public:
  EdgeProfile() {
    for (int i = 0; i < kN; ++i) table_[i] = static_cast<float>(0.5 * std::erfc((kLo + i * kStep) / std::sqrt(2.0)));
  }
  float operator()(double x) const {
    const double f = (x - kLo) / kStep;
    if (f <= 0) return 1.0f;
    if (f >= kN - 1) return 0.0f;
    const int i = static_cast<int>(f);
    const float t = static_cast<float>(f - i);
    return table_[i] + t * (table_[i + 1] - table_[i]);
  }
  const float* table() const { return table_.data(); }

  static constexpr int kN = 2049;
  static constexpr double kLo = -6.0, kStep = 12.0 / (kN - 1);

 private:
  std::array<float, kN> table_{};
};

const EdgeProfile& edge_profile() {
  static const EdgeProfile profile;  // immutable table, built once
  return profile;
}

}  // namespace

namespace render_parts {

float edge_fraction(double x) { return edge_profile()(x); }

std::array<Eigen::Vector3f, 10> spot_colours(const CameraSpec& cam) {
  std::array<Eigen::Vector3f, 10> spot_rgb;
  for (int i = 0; i < 10; ++i) {
    const pattern::Rgb c = pattern::symbol_colour(i);
    const Eigen::Vector3f raw(c.r / 255.f, c.g / 255.f, c.b / 255.f);
    const float x = static_cast<float>(cam.crosstalk);
    spot_rgb[i] = (1 - 2 * x) * raw + x * Eigen::Vector3f(raw.y() + raw.z(), raw.x() + raw.z(), raw.x() + raw.y());
  }
  return spot_rgb;
}

Sensor::Sensor(const Cell& cell, const CameraSpec& cam, std::uint64_t noise_seed)
    : gain(static_cast<float>(255.0 * cam.exposure)),
      read_var(static_cast<float>(cam.noise_sigma * cam.noise_sigma)),
      shot(static_cast<float>(cam.shot_noise)),
      noisy(cam.noise_sigma > 0 || cam.shot_noise > 0),
      pool(cell.noise_pool.data()),
      pool_span(1),
      seed(noise_seed) {
  const std::size_t row_len = static_cast<std::size_t>(cell.scenario.camera.intrinsics.width) * 3;
  pool_span = cell.noise_pool.size() > row_len ? cell.noise_pool.size() - row_len : 1;
}

namespace {
// The sensor over one row. The compiler vectorises this loop for the baseline instruction set.
void expose(const float* __restrict in, std::uint8_t* __restrict row, const float* __restrict noise, std::size_t n,
            float g, float rv, float sh, bool noisy) {
  if (noisy) {
    for (std::size_t i = 0; i < n; ++i) {
      const float value = g * in[i];
      const float noisy_value = value + std::sqrt(rv + sh * std::max(value, 0.f)) * noise[i];
      row[i] = static_cast<std::uint8_t>(std::min(std::max(noisy_value + 0.5f, 0.f), 255.f));
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) row[i] = static_cast<std::uint8_t>(std::min(std::max(g * in[i] + 0.5f, 0.f), 255.f));
  }
}

// The same with AVX2, eight values at a time, the same operations in the same order (no FMA).
// The noise's standard deviation, a square root per value, is reused while the values are
// those it was computed for: most of a frame is the ambient light on one surface, the same
// value pixel after pixel.
__attribute__((target("avx2"))) void expose_avx2(const float* __restrict in, std::uint8_t* __restrict row,
                                                 const float* __restrict noise, std::size_t n, float g, float rv,
                                                 float sh, bool noisy) {
  if (!noisy) return expose(in, row, noise, n, g, rv, sh, noisy);
  const __m256 gain = _mm256_set1_ps(g), read_var = _mm256_set1_ps(rv), shot = _mm256_set1_ps(sh);
  const __m256 zero = _mm256_setzero_ps(), half = _mm256_set1_ps(0.5f), top = _mm256_set1_ps(255.f);
  __m256 known = _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN()), known_sd = zero;  // NaN equals nothing
  std::size_t i = 0;
  for (; i + 32 <= n; i += 32) {
    __m256i bytes[4];
    for (int k = 0; k < 4; ++k) {
      const __m256 value = _mm256_mul_ps(gain, _mm256_loadu_ps(in + i + 8 * k));
      if (_mm256_movemask_ps(_mm256_cmp_ps(value, known, _CMP_EQ_OQ)) != 0xFF) {
        // std::max(value, 0.f) keeps value unless value < 0: maxps(value, 0) differs only for
        // -0, and sh * -0 added to rv >= 0 gives rv all the same
        known_sd = _mm256_sqrt_ps(_mm256_add_ps(read_var, _mm256_mul_ps(shot, _mm256_max_ps(value, zero))));
        known = value;
      }
      const __m256 noisy_value = _mm256_add_ps(value, _mm256_mul_ps(known_sd, _mm256_loadu_ps(noise + i + 8 * k)));
      bytes[k] = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(_mm256_add_ps(noisy_value, half), zero), top));
    }
    // 32 values in [0, 255] as bytes, in order (packs work within 128-bit lanes)
    const __m256i words = _mm256_packs_epi32(bytes[0], bytes[1]), words2 = _mm256_packs_epi32(bytes[2], bytes[3]);
    const __m256i packed = _mm256_packus_epi16(words, words2);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(row + i),
                        _mm256_permutevar8x32_epi32(packed, _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7)));
  }
  expose(in + i, row + i, noise + i, n - i, g, rv, sh, noisy);
}

// expose_avx2 sixteen values at a time
__attribute__((target(SIM_AVX512_TARGET))) void expose_avx512(const float* __restrict in, std::uint8_t* __restrict row,
                                                         const float* __restrict noise, std::size_t n, float g,
                                                         float rv, float sh, bool noisy) {
  if (!noisy) return expose(in, row, noise, n, g, rv, sh, noisy);
  const __m512 gain = _mm512_set1_ps(g), read_var = _mm512_set1_ps(rv), shot = _mm512_set1_ps(sh);
  const __m512 zero = _mm512_setzero_ps(), half = _mm512_set1_ps(0.5f), top = _mm512_set1_ps(255.f);
  __m512 known = _mm512_set1_ps(std::numeric_limits<float>::quiet_NaN()), known_sd = zero;  // NaN equals nothing
  std::size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m512 value = _mm512_mul_ps(gain, _mm512_loadu_ps(in + i));
    if (_mm512_cmp_ps_mask(value, known, _CMP_EQ_OQ) != 0xFFFF) {
      known_sd = _mm512_sqrt_ps(_mm512_add_ps(read_var, _mm512_mul_ps(shot, _mm512_max_ps(value, zero))));
      known = value;
    }
    const __m512 noisy_value = _mm512_add_ps(value, _mm512_mul_ps(known_sd, _mm512_loadu_ps(noise + i)));
    const __m512i bytes = _mm512_cvttps_epi32(_mm512_min_ps(_mm512_max_ps(_mm512_add_ps(noisy_value, half), zero), top));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(row + i), _mm512_cvtepi32_epi8(bytes));
  }
  expose(in + i, row + i, noise + i, n - i, g, rv, sh, noisy);
}
}  // namespace

const float* Sensor::row_noise(int v) const {
  // a contiguous run of the pool at a seeded offset: the loop over it vectorises
  std::uint64_t state = seed ^ (0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(v + 1));
  return pool + splitmix64(state) % pool_span;
}

void Sensor::expose_row(int v, const float* radiance, std::uint8_t* out, std::size_t n) const {
  const VectorUnit unit = vector_unit(scalar, avx512);
  (unit == VectorUnit::kAvx512 ? expose_avx512 : unit == VectorUnit::kAvx2 ? expose_avx2 : expose)(
      radiance, out, row_noise(v), n, gain, read_var, shot, noisy);
}

// The image region one spot can light: the projected rim and centre hits on one object,
// widened by the defocus blur. A spot straddling a depth edge gives one box per object.
void spot_boxes(const Cell& cell, const std::vector<SpotHit>& hits, const Eigen::Isometry3d& c_T_w,
                std::vector<SpotBox>& out) {
  out.clear();
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const ProjectorSpec& ps = cell.projector->spec();
  const Eigen::Vector3d P = ps.world_T_projector.translation();
  for (std::size_t i = 0; i < hits.size(); ++i) {
    const SpotHit& h = hits[i];
    // group hits by object: up to a few boxes per spot
    std::array<int, 4> objects{-1, -1, -1, -1};
    std::array<Eigen::AlignedBox2d, 4> boxes;
    std::array<double, 4> margin{0, 0, 0, 0};
    double sigma_max = 0;
    const auto add = [&](const RayHit& hit) {
      const Eigen::Vector3d X_c = c_T_w * hit.point_w;
      if (X_c.z() <= 1e-3) return;
      int g = 0;
      while (g < 4 && objects[g] != -1 && objects[g] != hit.object) ++g;
      if (g == 4) return;
      objects[g] = hit.object;
      boxes[g].extend(cell.camera->project(X_c));
      // blur (3 sigma) on the projector's plane, carried to the surface and into the camera
      const double z_p = (hit.point_w - P).norm();
      // blur plus the size of a camera pixel seen on the projector's plane (anti-aliasing)
      const double pixel_px = (X_c.z() / k.fx) * (ps.intrinsics.fx / z_p);
      const double sigma_px = cell.projector->defocus_sigma_px(z_p) + 0.5 * pixel_px;
      sigma_max = std::max(sigma_max, sigma_px);
      margin[g] = std::max(margin[g], 3.0 * sigma_px / pixel_px + 1.0);
    };
    if (h.centre) add(*h.centre);
    for (const auto& r : h.rim)
      if (r) add(*r);
    for (int g = 0; g < 4 && objects[g] != -1; ++g) {
      const Eigen::AlignedBox2d& b = boxes[g];
      SpotBox box{static_cast<int>(i), ps.spot_radius_px + 3.0 * sigma_max + 1.0,
                  static_cast<int>(std::floor(b.min().x() - margin[g])),
                  static_cast<int>(std::floor(b.min().y() - margin[g])), static_cast<int>(std::ceil(b.max().x() + margin[g])),
                  static_cast<int>(std::ceil(b.max().y() + margin[g]))};
      box.u0 = std::max(box.u0, 0);
      box.v0 = std::max(box.v0, 0);
      box.u1 = std::min(box.u1, k.width - 1);
      box.v1 = std::min(box.v1, k.height - 1);
      // a footprint larger than a quarter of the image is a grazing ray, not a spot
      if (box.u0 <= box.u1 && box.v0 <= box.v1 && (box.u1 - box.u0) < k.width / 4 && (box.v1 - box.v0) < k.height / 4)
        out.push_back(box);
    }
  }
}

}  // namespace render_parts

namespace {

// The scene's triangles with the arm's at its link poses: the static part is copied once per
// buffer, then only the arm is replaced.
SceneTriangles& posed_triangles(const Cell& cell, const LinkPoses& links, ArmFrameBuffers& buf) {
  const MovingMeshes& arm = cell.arm_meshes;
  const int object_offset = static_cast<int>(cell.object_names.size());
  const std::size_t first = cell.triangles.a.size();
  // the static part is copied once per buffer, then only the arm is replaced
  if (buf.triangles.a.size() < first || buf.triangles.object.empty() || buf.triangles.object[0] != cell.triangles.object[0] ||
      buf.triangles.a.front() != cell.triangles.a.front())
    buf.triangles = cell.triangles;
  SceneTriangles& t = buf.triangles;
  for (auto* v : {&t.a, &t.b, &t.c, &t.normal_w}) v->resize(first);
  t.offset.resize(first);
  t.object.resize(first);
  t.albedo.resize(first);
  for (std::size_t i = 0; i < arm.size(); ++i) {
    const auto l = static_cast<std::size_t>(arm.link(i));
    if (l >= links.size()) continue;
    append_triangles(arm.mesh(i).vertices, arm.mesh(i).triangles, links[l], object_offset + static_cast<int>(i),
                     arm.albedo(i), t);
  }
  return t;
}

// The arm's box on the projector's image plane; `behind` when some of it is behind the
// projector (the box then says nothing).
Eigen::AlignedBox2d arm_box_in_projector(const Cell& cell, const LinkPoses& links, bool& behind) {
  const MovingMeshes& arm = cell.arm_meshes;
  const Projector& proj = *cell.projector;
  const Intrinsics& kp = proj.spec().intrinsics;
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  Eigen::AlignedBox2d box;
  behind = false;
  for (std::size_t i = 0; i < arm.size(); ++i) {
    const auto l = static_cast<std::size_t>(arm.link(i));
    if (l >= links.size()) continue;
    const Eigen::Isometry3d p_T_mesh = p_T_w * links[l];
    for (const auto& v : arm.mesh(i).vertices) {
      const Eigen::Vector3d x = p_T_mesh * v;
      if (x.z() < 1e-3) {
        behind = true;
        continue;
      }
      box.extend(Eigen::Vector2d(kp.fx * x.x() / x.z() + kp.cx, kp.fy * x.y() / x.z() + kp.cy));
    }
  }
  return box;
}

// The projector's depth with the arm: only the region the arm's box covers is redrawn over
// the static depth, and only where spots can shine.
const DepthBuffer& arm_projector_depth(const Cell& cell, const SceneTriangles& triangles, std::size_t first,
                                       const Eigen::AlignedBox2d& box, bool behind, ArmFrameBuffers& buf) {
  const Projector& proj = *cell.projector;
  const Intrinsics& kp = proj.spec().intrinsics;
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  DepthBuffer& d = buf.arm_projector_depth;
  const DepthBuffer& full = cell.projector_depth;
  const std::size_t n = static_cast<std::size_t>(full.width) * full.height;
  if (d.width != full.width || d.height != full.height || d.margin != full.margin || d.inv_depth.size() != n) {
    d.width = full.width;
    d.height = full.height;
    d.margin = full.margin;
    d.inv_depth.assign(n, 0.0f);
    d.triangle.assign(n, -1);
    buf.dirty_u1 = buf.dirty_v1 = -1;
  }
  for (int v = std::max(0, buf.dirty_v0); v <= std::min(d.height - 1, buf.dirty_v1); ++v) {
    const std::size_t row = static_cast<std::size_t>(v) * d.width;
    const int u0 = std::max(0, buf.dirty_u0), u1 = std::min(d.width - 1, buf.dirty_u1);
    if (u0 > u1) break;
    std::fill(d.inv_depth.begin() + static_cast<std::ptrdiff_t>(row + u0), d.inv_depth.begin() + static_cast<std::ptrdiff_t>(row + u1 + 1), 0.0f);
    std::fill(d.triangle.begin() + static_cast<std::ptrdiff_t>(row + u0), d.triangle.begin() + static_cast<std::ptrdiff_t>(row + u1 + 1), -1);
  }
  // only where spots can shine is the projector's depth ever read: the pattern's region,
  // widened by the farthest a blurred spot reaches
  const Eigen::Vector2d a = proj.spot_pixel(0, 0), b = proj.spot_pixel(proj.pattern().rows - 1, proj.pattern().cols - 1);
  const double spread = proj.spec().spot_radius_px + 3.0 * proj.defocus_sigma_px(cell.farthest_spot_m + 0.5) + 4.0;
  RasterClip clip{static_cast<int>(std::floor(std::min(a.x(), b.x()) - spread)) + d.margin,
                  static_cast<int>(std::floor(std::min(a.y(), b.y()) - spread)) + d.margin,
                  static_cast<int>(std::ceil(std::max(a.x(), b.x()) + spread)) + d.margin,
                  static_cast<int>(std::ceil(std::max(a.y(), b.y()) + spread)) + d.margin};
  clip.x0 = std::max(clip.x0, 0);
  clip.y0 = std::max(clip.y0, 0);
  if (!behind) {
    clip.x0 = std::max(clip.x0, static_cast<int>(std::floor(box.min().x())) + d.margin - 2);
    clip.y0 = std::max(clip.y0, static_cast<int>(std::floor(box.min().y())) + d.margin - 2);
    clip.x1 = std::min(clip.x1, static_cast<int>(std::ceil(box.max().x())) + d.margin + 2);
    clip.y1 = std::min(clip.y1, static_cast<int>(std::ceil(box.max().y())) + d.margin + 2);
  }
  rasterize_more(triangles, first, p_T_w, kp, d, clip, !buf.scalar);
  buf.dirty_u0 = clip.x0;
  buf.dirty_v0 = clip.y0;
  buf.dirty_u1 = clip.x1;
  buf.dirty_v1 = clip.y1;
  return d;
}

}  // namespace

FrameScene pose_scene(const Cell& cell, const LinkPoses* links, ArmFrameBuffers& buf, bool with_triangles) {
  FrameScene scene{&cell.triangles, &cell.spot_hits, &cell.projector_depth, nullptr, false};
  if (!links || links->empty() || cell.arm_meshes.size() == 0) return scene;
  if (with_triangles) scene.triangles = &posed_triangles(cell, *links, buf);
  // is any of the arm in the projector's beam? its box on the projector's image plane
  const Projector& proj = *cell.projector;
  const Intrinsics& kp = proj.spec().intrinsics;
  bool behind = false;
  const Eigen::AlignedBox2d box = arm_box_in_projector(cell, *links, behind);
  const double reach = proj.spec().spot_radius_px + 2;
  const Eigen::AlignedBox2d image(Eigen::Vector2d(-reach, -reach), Eigen::Vector2d(kp.width + reach, kp.height + reach));
  if (!behind && (box.isEmpty() || !box.intersects(image))) return scene;
  scene.arm_in_beam = true;
  buf.spot_hits = cell.spot_hits;
  const int object_offset = static_cast<int>(cell.object_names.size());
  for (SpotHit& h : buf.spot_hits) {
    const Eigen::Vector2d c = proj.spot_pixel(h.row, h.col);
    if (!behind && (c.x() < box.min().x() - reach || c.x() > box.max().x() + reach || c.y() < box.min().y() - reach ||
                    c.y() > box.max().y() + reach))
      continue;
    proj.recast(h, cell.arm_meshes, *links, object_offset);
  }
  scene.spot_hits = &buf.spot_hits;
  if (with_triangles)
    scene.arm_projector_depth = &arm_projector_depth(cell, *scene.triangles, cell.triangles.a.size(), box, behind, buf);
  return scene;
}

std::uint64_t frame_seed(std::uint64_t scenario_seed, std::uint64_t frame) {
  std::uint64_t s = scenario_seed ^ (0xD1B54A32D192ED03ull * (frame + 1));
  return splitmix64(s);
}

namespace {

// Rows rendered together: the spots' light, then the sensor, while the rows' radiance is still
// in the cache (a whole frame of radiance is 3.7 MB; eight rows are 61 kB).
constexpr int kTileRows = 8;

// What every spot's light has in common at one pixel of a tile: where the pixel's surface
// lies on the projector's image plane and how far from it, the blur there, whether the
// projector sees that point, and the light the surface returns. Computed once per pixel that
// some spot's box covers; the boxes of blurred spots overlap several times over, and each
// spot then only measures its distance on the projector's plane.
struct TileLight {
  enum State : std::uint8_t { kUnknown = 0, kNoSurface, kShadow, kLit };
  // a tile row is `stride` pixels, the image's width rounded up to the widest vector unit's 8 lanes
  std::size_t stride;
  std::vector<double> pu, pv, zp, sigma, reach2;
  std::vector<float> weight;
  std::vector<std::uint8_t> state;
  std::vector<float> radiance;  // linear RGB, 1 = full scale at exposure 1
  TileLight(int rows, int width)
      : stride((static_cast<std::size_t>(width) + 7) & ~std::size_t{7}),
        pu(rows * stride), pv(pu.size()), zp(pu.size()), sigma(pu.size()), reach2(pu.size()), weight(pu.size()),
        state(pu.size()), radiance(3 * pu.size()) {}
};

// One frame's light: the ambient on every surface and each spot's disc, blurred, on the
// surfaces it reaches.
class FrameLight {
 public:
  FrameLight(const Cell& cell, const FrameScene& scene, const RenderScratch& s, const Eigen::Isometry3d& world_T_camera,
             const CameraSpec& cam)
      : cell_(cell), proj_(*cell.projector), ps_(proj_.spec()), kp_(ps_.intrinsics), k_(cell.scenario.camera.intrinsics),
        tris_(*scene.triangles), hits_(*scene.spot_hits), projector_depth_(*scene.projector_depth),
        arm_depth_(scene.arm_projector_depth), s_(s), ambient_(static_cast<float>(cam.ambient)),
        spot_rgb_(render_parts::spot_colours(cam)), R_(world_T_camera.linear()), C_(world_T_camera.translation()),
        P_(ps_.world_T_projector.translation()), radius_(ps_.spot_radius_px),
        focus_mid_(0.5 * (ps_.focus_near_m + ps_.focus_far_m)), rays_(cell.camera->pixel_rays().data()),
        proj_per_cam_px_(kp_.fx / k_.fx) {
    const Eigen::Isometry3d p_T_c = proj_.projector_T_world() * world_T_camera;
    p_R_c_ = p_T_c.linear();
    p_t_c_ = p_T_c.translation();
  }

  // Rows [v0, v1) into the tile's radiance. With the AVX2 unit four pixels at a time, with
  // AVX-512 eight (the same operations in the same order: the same bits).
  void shade(int v0, int v1, TileLight& tile, VectorUnit unit) const {
    std::fill(tile.state.begin(), tile.state.end(), TileLight::kUnknown);
    for (int v = v0; v < v1; ++v) {
      const std::size_t first = static_cast<std::size_t>(v) * k_.width, row = (v - v0) * tile.stride;
      const int vector_end = unit == VectorUnit::kAvx512 ? ambient_avx512(first, row, tile) : 0;
      for (int u = vector_end; u < k_.width; ++u) {
        const std::int32_t zi = cell_.pixel_to_zbuffer[first + u];
        const std::int32_t t = zi >= 0 ? s_.camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
        float* out = &tile.radiance[3 * (row + u)];
        out[0] = out[1] = out[2] = t >= 0 ? ambient_ * tris_.albedo[t] : 0.f;
      }
      for (std::size_t u = k_.width; u < tile.stride; ++u) tile.state[row + u] = TileLight::kNoSurface;
    }
    for (const SpotBox& box : s_.boxes) {
      const int bv0 = std::max(box.v0, v0), bv1 = std::min(box.v1, v1 - 1);
      if (bv0 > bv1) continue;
      if (unit == VectorUnit::kAvx512)
        shade_spot_avx512(box, bv0, bv1, v0, tile);
      else if (unit == VectorUnit::kAvx2)
        shade_spot_avx2(box, bv0, bv1, v0, tile);
      else
        shade_spot(box, bv0, bv1, v0, tile);
    }
  }

 private:
  void shade_spot(const SpotBox& box, int bv0, int bv1, int v0, TileLight& tile) const {
    const SpotFrame f = spot_frame(box);
    const double cx = f.cx, cy = f.cy, reach_max2 = f.reach_max2;
    const Eigen::Vector3f& colour = *f.colour;
    for (int v = bv0; v <= bv1; ++v) {
      const std::size_t row = static_cast<std::size_t>(v - v0) * tile.stride;
      for (int u = box.u0; u <= box.u1; ++u) {
        const std::size_t i = row + u;
        if (tile.state[i] == TileLight::kUnknown) surface_light(static_cast<std::size_t>(v) * k_.width + u, i, tile);
        if (tile.state[i] == TileLight::kNoSurface) continue;
        const double du = tile.pu[i] - cx;
        const double dv = tile.pv[i] - cy;
        const double rho2 = du * du + dv * dv;
        if (rho2 > reach_max2) continue;  // most of the box: between spots
        if (rho2 > tile.reach2[i]) continue;
        if (!lit_from(du + cx, dv + cy, i, tile)) continue;
        add_light(tile, i, edge_((std::sqrt(rho2) - radius_) / tile.sigma[i]) * tile.weight[i], colour);
      }
    }
  }

  // Pixel `px` of the image, `i` of the tile: the surface its ray meets, seen from the projector.
  void surface_light(std::size_t px, std::size_t i, TileLight& tile) const {
    tile.state[i] = TileLight::kNoSurface;
    const std::int32_t zi = cell_.pixel_to_zbuffer[px];
    const std::int32_t t = zi >= 0 ? s_.camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
    if (t < 0) return;
    const Eigen::Vector3d d_c(rays_[2 * px], rays_[2 * px + 1], 1.0);
    // exact intersection of this pixel's ray with the triangle's plane (camera frame)
    const double denom = s_.normal_c[t].dot(d_c);
    if (std::abs(denom) < 1e-12) return;
    const double z_c = s_.offset_c[t] / denom;
    if (z_c <= 0) return;
    const Eigen::Vector3d X_p = z_c * (p_R_c_ * d_c) + p_t_c_;
    if (X_p.z() <= 1e-3) return;
    const double inv_z = 1.0 / X_p.z();
    tile.pu[i] = kp_.fx * X_p.x() * inv_z + kp_.cx;
    tile.pv[i] = kp_.fy * X_p.y() * inv_z + kp_.cy;
    tile.zp[i] = X_p.z();
    const double blur = proj_.defocus_sigma_px(X_p.z());
    // a camera pixel at depth z seen from the projector at z_p
    const double pixel_in_proj = z_c * proj_per_cam_px_ * inv_z;
    const double sigma = std::sqrt(blur * blur + 0.083 * pixel_in_proj * pixel_in_proj) + 1e-6;
    tile.sigma[i] = sigma;
    const double reach = radius_ + 3.0 * sigma;  // 0.5 erfc(3 / sqrt 2) = 0.1 %: nothing beyond
    tile.reach2[i] = reach * reach;
    const Eigen::Vector3d X = C_ + z_c * (R_ * d_c);
    const Eigen::Vector3d L = P_ - X;
    const double dist2 = L.squaredNorm();
    const double cos_in = std::abs(tris_.normal_w[t].dot(L)) / std::sqrt(dist2);
    const double falloff = (focus_mid_ * focus_mid_) / dist2;
    tile.weight[i] = static_cast<float>(tris_.albedo[t] * ps_.brightness * cos_in * falloff);
    tile.state[i] = lit(tile.pu[i], tile.pv[i], X_p.z()) ? TileLight::kLit : TileLight::kShadow;
  }

  // Spot centre and whether this spot may use each pixel's own depth lookup (shade_spot).
  // The projector's depth is looked up where the spot's distance from its centre, added back
  // to the centre, points: (u - cx) + cx. Almost always that is the pixel's own u, bit for
  // bit (the difference of two numbers within a factor 2 of each other is exact), and the
  // pixel's own lookup serves; where it is not, the point's own.
  bool lit_from(double u, double v, std::size_t i, const TileLight& tile) const {
    if (u == tile.pu[i] && v == tile.pv[i]) return tile.state[i] == TileLight::kLit;
    return lit(u, v, tile.zp[i]);
  }

  struct SpotFrame {
    double cx, cy, reach_max2;
    const Eigen::Vector3f* colour;
  };
  SpotFrame spot_frame(const SpotBox& box) const {
    const SpotHit& hit = hits_[box.spot];
    const Eigen::Vector2d centre = proj_.spot_pixel(hit.row, hit.col);
    return {centre.x(), centre.y(), box.reach_px * box.reach_px, &spot_rgb_[hit.symbol]};
  }

  // shade_spot, four pixels at a time; blocks of four aligned on the tile's rows, each
  // block's surfaces computed (all four) the first time a spot reaches it.
  __attribute__((target("avx2"))) void shade_spot_avx2(const SpotBox& box, int bv0, int bv1, int v0,
                                                      TileLight& tile) const {
    const SpotFrame f = spot_frame(box);
    const __m256d cx = _mm256_set1_pd(f.cx), cy = _mm256_set1_pd(f.cy), reach_max2 = _mm256_set1_pd(f.reach_max2);
    const __m256i lane = _mm256_set_epi64x(3, 2, 1, 0);
    const Eigen::Vector3f& c = *f.colour;
    const __m256 colour8 = _mm256_setr_ps(c[0], c[1], c[2], c[0], c[1], c[2], c[0], c[1]);
    const __m128 colour4 = _mm_setr_ps(c[2], c[0], c[1], c[2]);
    const int b0 = box.u0 & ~3;
    for (int v = bv0; v <= bv1; ++v) {
      const std::size_t row = static_cast<std::size_t>(v - v0) * tile.stride;
      for (int b = b0; b <= box.u1; b += 4) {
        const std::size_t i = row + b;
        std::uint32_t states;
        std::memcpy(&states, &tile.state[i], 4);
        if ((states & 0xFFu) == 0 || (states & 0xFF00u) == 0 || (states & 0xFF0000u) == 0 || (states & 0xFF000000u) == 0)
          surface_light4(v, b, i, tile);
        // the lanes inside the box
        const __m256i ub = _mm256_add_epi64(_mm256_set1_epi64x(b), lane);
        const __m256i inside = _mm256_andnot_si256(
            _mm256_or_si256(_mm256_cmpgt_epi64(_mm256_set1_epi64x(box.u0), ub), _mm256_cmpgt_epi64(ub, _mm256_set1_epi64x(box.u1))),
            _mm256_set1_epi64x(-1));
        const __m256d du = _mm256_sub_pd(_mm256_loadu_pd(&tile.pu[i]), cx);
        const __m256d dv = _mm256_sub_pd(_mm256_loadu_pd(&tile.pv[i]), cy);
        const __m256d rho2 = _mm256_add_pd(_mm256_mul_pd(du, du), _mm256_mul_pd(dv, dv));
        // shade_spot's `continue`s, negated as they are written (a NaN goes on, as there)
        const __m256d go = _mm256_and_pd(_mm256_cmp_pd(rho2, reach_max2, _CMP_NGT_UQ),
                                         _mm256_cmp_pd(rho2, _mm256_loadu_pd(&tile.reach2[i]), _CMP_NGT_UQ));
        int lanes = _mm256_movemask_pd(_mm256_and_pd(go, _mm256_castsi256_pd(inside)));
        if (!lanes) continue;
        // lit: the pixel's own lookup where the spot's lookup point is the pixel's (see lit_from)
        const __m256d same = _mm256_and_pd(_mm256_cmp_pd(_mm256_add_pd(du, cx), _mm256_loadu_pd(&tile.pu[i]), _CMP_EQ_OQ),
                                           _mm256_cmp_pd(_mm256_add_pd(dv, cy), _mm256_loadu_pd(&tile.pv[i]), _CMP_EQ_OQ));
        const int own = _mm256_movemask_pd(same);
        std::memcpy(&states, &tile.state[i], 4);
        const __m128i state = _mm_cvtsi32_si128(static_cast<int>(states));
        const int lit_lanes = _mm_movemask_epi8(_mm_cmpeq_epi8(state, _mm_set1_epi8(TileLight::kLit))) & 0xF;
        const int surface = ~_mm_movemask_epi8(_mm_cmpeq_epi8(state, _mm_set1_epi8(TileLight::kNoSurface))) & 0xF;
        int elsewhere = lanes & ~own & surface;  // rare: a spot whose lookup point is not the pixel's
        lanes &= own & lit_lanes;
        for (; elsewhere; elsewhere &= elsewhere - 1) {
          const int l = __builtin_ctz(static_cast<unsigned>(elsewhere));
          const std::size_t j = i + l;
          if (lit(tile.pu[j] - f.cx + f.cx, tile.pv[j] - f.cy + f.cy, tile.zp[j])) lanes |= 1 << l;
        }
        if (!lanes) continue;
        const __m128 e = _mm_mul_ps(edge4(_mm256_div_pd(_mm256_sub_pd(_mm256_sqrt_pd(rho2), _mm256_set1_pd(radius_)),
                                                        _mm256_loadu_pd(&tile.sigma[i]))),
                                    _mm_loadu_ps(&tile.weight[i]));
        // the four pixels' 12 radiance values in one go: a lane not lit adds +0 (radiance is
        // never -0: adding +0 changes no bit), the others e * colour, as add_light does
        const __m128 e_lit = _mm_and_ps(e, _mm_castsi128_ps(_mm_cmpgt_epi32(
                                               _mm_and_si128(_mm_set1_epi32(lanes), _mm_setr_epi32(1, 2, 4, 8)),
                                               _mm_setzero_si128())));
        const __m256 e8 = _mm256_permutevar8x32_ps(_mm256_castps128_ps256(e_lit), _mm256_setr_epi32(0, 0, 0, 1, 1, 1, 2, 2));
        const __m128 e4 = _mm_permutevar_ps(_mm_movehl_ps(e_lit, e_lit), _mm_setr_epi32(0, 1, 1, 1));
        float* out = &tile.radiance[3 * i];
        _mm256_storeu_ps(out, _mm256_add_ps(_mm256_loadu_ps(out), _mm256_mul_ps(e8, colour8)));
        _mm_storeu_ps(out + 8, _mm_add_ps(_mm_loadu_ps(out + 8), _mm_mul_ps(e4, colour4)));
      }
    }
  }

  static void add_light(TileLight& tile, std::size_t j, float e, const Eigen::Vector3f& colour) {
    float* out = &tile.radiance[3 * j];
    out[0] += e * colour[0];
    out[1] += e * colour[1];
    out[2] += e * colour[2];
  }

  // EdgeProfile's lookup of four values: the same bounds, truncation and float interpolation
  __attribute__((target("avx2"))) __m128 edge4(__m256d x) const {
    const __m256d f = _mm256_div_pd(_mm256_sub_pd(x, _mm256_set1_pd(EdgeProfile::kLo)), _mm256_set1_pd(EdgeProfile::kStep));
    const __m256d below = _mm256_cmp_pd(f, _mm256_setzero_pd(), _CMP_LE_OQ);
    const __m256d above = _mm256_cmp_pd(f, _mm256_set1_pd(EdgeProfile::kN - 1), _CMP_GE_OQ);
    // the table's index only where f lies strictly inside it (NaN too is outside: a lane that
    // is not lit may hold anything, and must not send the gather out of the table)
    const __m256d safe = _mm256_and_pd(f, _mm256_and_pd(_mm256_cmp_pd(f, _mm256_setzero_pd(), _CMP_GT_OQ),
                                                        _mm256_cmp_pd(f, _mm256_set1_pd(EdgeProfile::kN - 1), _CMP_LT_OQ)));
    const __m128i i = _mm256_cvttpd_epi32(safe);
    const __m128 t = _mm256_cvtpd_ps(_mm256_sub_pd(safe, _mm256_cvtepi32_pd(i)));
    // four scalar loads of each neighbouring pair (the gather instruction is slower here)
    alignas(16) int at[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(at), i);
    const float* table = edge_.table();
    const __m128 a = _mm_setr_ps(table[at[0]], table[at[1]], table[at[2]], table[at[3]]);
    const __m128 b = _mm_setr_ps(table[at[0] + 1], table[at[1] + 1], table[at[2] + 1], table[at[3] + 1]);
    const __m128 value = _mm_add_ps(a, _mm_mul_ps(t, _mm_sub_ps(b, a)));
    const __m128 below32 = _mm_castsi128_ps(lanes32(below)), above32 = _mm_castsi128_ps(lanes32(above));
    return _mm_blendv_ps(_mm_blendv_ps(value, _mm_setzero_ps(), above32), _mm_set1_ps(1.0f), below32);
  }

  // The triangle behind each of the pixels (v, u..u+N-1) and its ray (a lane past the image's
  // edge: none, and a zero ray); returns the lanes with a surface, bit l for lane l.
  template <int N>
  int lane_surfaces(int v, int u, int* tri, double* rx, double* ry, bool& one_triangle) const {
    int valid = 0;
    for (int l = 0; l < N; ++l) {
      tri[l] = -1;
      rx[l] = ry[l] = 0;
      if (u + l < k_.width) {
        const std::size_t px = static_cast<std::size_t>(v) * k_.width + u + l;
        const std::int32_t zi = cell_.pixel_to_zbuffer[px];
        tri[l] = zi >= 0 ? s_.camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
        rx[l] = rays_[2 * px];
        ry[l] = rays_[2 * px + 1];
      }
      valid |= (tri[l] >= 0) << l;
      one_triangle = one_triangle && tri[l] == tri[0];
    }
    return valid;
  }
  // The lanes' triangles, one row of `a` per quantity: the plane in the camera frame (normal,
  // offset), the normal in the world, the albedo (a lane without a triangle: a plane its ray
  // meets, albedo 0).
  template <int N>
  void lane_planes(const int* tri, double (*a)[N]) const {
    for (int l = 0; l < N; ++l) {
      const int t = tri[l];
      const Eigen::Vector3d nc = t >= 0 ? s_.normal_c[t] : Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d nw = t >= 0 ? tris_.normal_w[t] : Eigen::Vector3d::UnitZ();
      a[0][l] = nc.x(), a[1][l] = nc.y(), a[2][l] = nc.z(), a[3][l] = t >= 0 ? s_.offset_c[t] : 1.0;
      a[4][l] = nw.x(), a[5][l] = nw.y(), a[6][l] = nw.z(), a[7][l] = t >= 0 ? tris_.albedo[t] : 0.0;
    }
  }

  // surface_light of the four pixels (v, u..u+3), tile index i..i+3. Eigen evaluates
  // z (M d) + t as ((z M0) d0 + (z M1) d1) + (z M2) d2 + t in the first two rows and as
  // (z M0) d0 + ((z M1) d1 + (z M2) d2) + t in the third (its packet and scalar paths);
  // the dot products left to right. Written out in that order here.
  __attribute__((target("avx2"))) void surface_light4(int v, int u, std::size_t i, TileLight& tile) const {
    alignas(32) double rx[4], ry[4];
    int tri[4];
    bool one_triangle = true;
    const int valid = lane_surfaces<4>(v, u, tri, rx, ry, one_triangle);
    for (int l = 0; l < 4; ++l) tile.state[i + l] = TileLight::kNoSurface;
    if (!valid) return;
    // the triangles' planes, normals and albedo per lane (a lane without one: a plane it meets)
    __m256d n0, n1, n2, off, w0, w1, w2, alb;
    if (tri[0] >= 0 && one_triangle) {  // the common case
      const int t = tri[0];
      n0 = _mm256_set1_pd(s_.normal_c[t].x()), n1 = _mm256_set1_pd(s_.normal_c[t].y()), n2 = _mm256_set1_pd(s_.normal_c[t].z());
      off = _mm256_set1_pd(s_.offset_c[t]);
      w0 = _mm256_set1_pd(tris_.normal_w[t].x()), w1 = _mm256_set1_pd(tris_.normal_w[t].y()), w2 = _mm256_set1_pd(tris_.normal_w[t].z());
      alb = _mm256_set1_pd(tris_.albedo[t]);
    } else {
      alignas(32) double a[8][4];
      lane_planes<4>(tri, a);
      n0 = _mm256_load_pd(a[0]), n1 = _mm256_load_pd(a[1]), n2 = _mm256_load_pd(a[2]), off = _mm256_load_pd(a[3]);
      w0 = _mm256_load_pd(a[4]), w1 = _mm256_load_pd(a[5]), w2 = _mm256_load_pd(a[6]), alb = _mm256_load_pd(a[7]);
    }
    const __m256d dx = _mm256_load_pd(rx), dy = _mm256_load_pd(ry);
    // the ray meets the triangle's plane
    const __m256d denom = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(n0, dx), _mm256_mul_pd(n1, dy)),
                                        _mm256_mul_pd(n2, _mm256_set1_pd(1.0)));
    const __m256d abs_denom = _mm256_andnot_pd(_mm256_set1_pd(-0.0), denom);
    const __m256d z = _mm256_div_pd(off, denom);
    __m256d ok = _mm256_and_pd(_mm256_cmp_pd(abs_denom, _mm256_set1_pd(1e-12), _CMP_NLT_UQ),
                               _mm256_cmp_pd(z, _mm256_setzero_pd(), _CMP_NLE_UQ));
    const __m256d Xp = transform_row(p_R_c_, p_t_c_, 0, z, dx, dy);
    const __m256d Yp = transform_row(p_R_c_, p_t_c_, 1, z, dx, dy);
    const __m256d Zp = transform_row(p_R_c_, p_t_c_, 2, z, dx, dy);
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(Zp, _mm256_set1_pd(1e-3), _CMP_NLE_UQ));
    const __m256d inv_z = _mm256_div_pd(_mm256_set1_pd(1.0), Zp);
    const __m256d pu = _mm256_add_pd(_mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(kp_.fx), Xp), inv_z), _mm256_set1_pd(kp_.cx));
    const __m256d pv = _mm256_add_pd(_mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(kp_.fy), Yp), inv_z), _mm256_set1_pd(kp_.cy));
    // the projector's defocus there (Projector::defocus_sigma_px)
    const __m256d zero = _mm256_setzero_pd();
    const __m256d near_gap = _mm256_sub_pd(_mm256_set1_pd(ps_.focus_near_m), Zp);
    const __m256d far_gap = _mm256_sub_pd(Zp, _mm256_set1_pd(ps_.focus_far_m));
    __m256d outside = _mm256_blendv_pd(zero, near_gap, _mm256_cmp_pd(zero, near_gap, _CMP_LT_OQ));
    outside = _mm256_blendv_pd(outside, far_gap, _mm256_cmp_pd(outside, far_gap, _CMP_LT_OQ));
    const __m256d blur = _mm256_add_pd(_mm256_set1_pd(ps_.focused_blur_px), _mm256_mul_pd(_mm256_set1_pd(ps_.defocus_px_per_m), outside));
    const __m256d pixel_in_proj = _mm256_mul_pd(_mm256_mul_pd(z, _mm256_set1_pd(proj_per_cam_px_)), inv_z);
    const __m256d sigma = _mm256_add_pd(
        _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(blur, blur),
                                     _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(0.083), pixel_in_proj), pixel_in_proj))),
        _mm256_set1_pd(1e-6));
    const __m256d reach = _mm256_add_pd(_mm256_set1_pd(radius_), _mm256_mul_pd(_mm256_set1_pd(3.0), sigma));
    // the light the surface returns towards the camera
    const __m256d Lx = _mm256_sub_pd(_mm256_set1_pd(P_.x()), _mm256_add_pd(_mm256_set1_pd(C_.x()), transform_row(R_, Eigen::Vector3d::Zero(), 0, z, dx, dy, false)));
    const __m256d Ly = _mm256_sub_pd(_mm256_set1_pd(P_.y()), _mm256_add_pd(_mm256_set1_pd(C_.y()), transform_row(R_, Eigen::Vector3d::Zero(), 1, z, dx, dy, false)));
    const __m256d Lz = _mm256_sub_pd(_mm256_set1_pd(P_.z()), _mm256_add_pd(_mm256_set1_pd(C_.z()), transform_row(R_, Eigen::Vector3d::Zero(), 2, z, dx, dy, false)));
    const __m256d dist2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(Lx, Lx), _mm256_mul_pd(Ly, Ly)), _mm256_mul_pd(Lz, Lz));
    const __m256d nL = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(w0, Lx), _mm256_mul_pd(w1, Ly)),
                                     _mm256_mul_pd(w2, Lz));
    const __m256d cos_in = _mm256_div_pd(_mm256_andnot_pd(_mm256_set1_pd(-0.0), nL), _mm256_sqrt_pd(dist2));
    const __m256d falloff = _mm256_div_pd(_mm256_set1_pd(focus_mid_ * focus_mid_), dist2);
    const __m256d weight = _mm256_mul_pd(
        _mm256_mul_pd(_mm256_mul_pd(alb, _mm256_set1_pd(ps_.brightness)), cos_in), falloff);
    _mm256_storeu_pd(&tile.pu[i], pu);
    _mm256_storeu_pd(&tile.pv[i], pv);
    _mm256_storeu_pd(&tile.zp[i], Zp);
    _mm256_storeu_pd(&tile.sigma[i], sigma);
    _mm256_storeu_pd(&tile.reach2[i], _mm256_mul_pd(reach, reach));
    _mm_storeu_ps(&tile.weight[i], _mm256_cvtpd_ps(weight));
    const int good = valid & _mm256_movemask_pd(ok);
    const int lit_lanes = lit4(pu, pv, Zp);
    for (int l = 0; l < 4; ++l)
      if (good >> l & 1) tile.state[i + l] = (lit_lanes >> l & 1) ? TileLight::kLit : TileLight::kShadow;
  }

  // lit() of four points: DepthBuffer::nearest and depth_at, lane by lane the same
  // comparisons, casts and float division.
  __attribute__((target("avx2"))) int lit4(__m256d u, __m256d v, __m256d z_p) const {
    __m128 nearest = depth4(projector_depth_, u, v);
    if (arm_depth_) {
      // std::min(a, b) is (b < a) ? b : a
      const __m128 b = depth4(*arm_depth_, u, v);
      nearest = _mm_blendv_ps(nearest, b, _mm_cmplt_ps(b, nearest));
    }
    const __m256d limit = _mm256_add_pd(_mm256_mul_pd(_mm256_cvtps_pd(nearest), _mm256_set1_pd(1.0 + 2e-3)), _mm256_set1_pd(2e-3));
    return ~_mm256_movemask_pd(_mm256_cmp_pd(z_p, limit, _CMP_GT_OQ)) & 0xF;
  }
  __attribute__((target("avx2"))) static __m128i nearest4(__m256d x) {
    const __m256d inside = _mm256_and_pd(_mm256_cmp_pd(x, _mm256_set1_pd(-1e9), _CMP_GT_OQ),
                                         _mm256_cmp_pd(x, _mm256_set1_pd(1e9), _CMP_LT_OQ));
    const __m256d shifted = _mm256_add_pd(_mm256_add_pd(x, _mm256_set1_pd(0.5)), _mm256_set1_pd(DepthBuffer::kShift));
    // outside +-1e9 the shifted value is not converted at all (a zero stands in for it)
    const __m128i n = _mm_sub_epi32(_mm256_cvttpd_epi32(_mm256_and_pd(shifted, inside)),
                                    _mm_set1_epi32(static_cast<int>(DepthBuffer::kShift)));
    return _mm_blendv_epi8(_mm_set1_epi32(-(1 << 30)), n, lanes32(inside));
  }
  __attribute__((target("avx2"))) static __m128 depth4(const DepthBuffer& d, __m256d u, __m256d v) {
    const __m128i margin = _mm_set1_epi32(d.margin);
    const __m128i i = _mm_add_epi32(nearest4(u), margin), j = _mm_add_epi32(nearest4(v), margin);
    const __m128i out = _mm_or_si128(_mm_or_si128(_mm_cmplt_epi32(i, _mm_setzero_si128()), _mm_cmplt_epi32(j, _mm_setzero_si128())),
                                     _mm_or_si128(_mm_cmpgt_epi32(i, _mm_set1_epi32(d.width - 1)),
                                                  _mm_cmpgt_epi32(j, _mm_set1_epi32(d.height - 1))));
    const __m128i index = _mm_andnot_si128(out, _mm_add_epi32(_mm_mullo_epi32(j, _mm_set1_epi32(d.width)), i));
    // four scalar loads (index 0 stands in outside the buffer; its value is not used)
    alignas(16) int at[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(at), index);
    const float* inv_depth = d.inv_depth.data();
    const __m128 q = _mm_setr_ps(inv_depth[at[0]], inv_depth[at[1]], inv_depth[at[2]], inv_depth[at[3]]);
    const __m128 inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
    const __m128 depth = _mm_blendv_ps(inf, _mm_div_ps(_mm_set1_ps(1.0f), q), _mm_cmpgt_ps(q, _mm_setzero_ps()));
    return _mm_blendv_ps(depth, inf, _mm_castsi128_ps(out));
  }

  // Row `r` of z (M d) + t, d = (dx, dy, 1), in Eigen's order (see surface_light4); without
  // `add_t`, row r of z (M d) alone.
  __attribute__((target("avx2"))) static __m256d transform_row(const Eigen::Matrix3d& M, const Eigen::Vector3d& t, int r,
                                                                __m256d z, __m256d dx, __m256d dy, bool add_t = true) {
    const __m256d a0 = _mm256_mul_pd(_mm256_mul_pd(z, _mm256_set1_pd(M(r, 0))), dx);
    const __m256d a1 = _mm256_mul_pd(_mm256_mul_pd(z, _mm256_set1_pd(M(r, 1))), dy);
    const __m256d a2 = _mm256_mul_pd(_mm256_mul_pd(z, _mm256_set1_pd(M(r, 2))), _mm256_set1_pd(1.0));
    const __m256d sum = r < 2 ? _mm256_add_pd(_mm256_add_pd(a0, a1), a2) : _mm256_add_pd(a0, _mm256_add_pd(a1, a2));
    return add_t ? _mm256_add_pd(sum, _mm256_set1_pd(t[r])) : sum;
  }

  // The ambient light of one image row's pixels into tile row `row`, sixteen at a time, as the
  // scalar loop in shade computes it; returns where that loop goes on.
  __attribute__((target(SIM_AVX512_TARGET))) int ambient_avx512(std::size_t first, std::size_t row,
                                                                TileLight& tile) const {
    const __m512 ambient = _mm512_set1_ps(ambient_);
    const __m512i none = _mm512_set1_epi32(-1), zero = _mm512_setzero_si512();
    // 16 pixels' values spread over their 48 channels: channel c of pixel p is value p
    const __m512i spread[3] = {
        _mm512_setr_epi32(0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4, 5),
        _mm512_setr_epi32(5, 5, 6, 6, 6, 7, 7, 7, 8, 8, 8, 9, 9, 9, 10, 10),
        _mm512_setr_epi32(10, 11, 11, 11, 12, 12, 12, 13, 13, 13, 14, 14, 14, 15, 15, 15)};
    const std::int32_t* cell_of = cell_.pixel_to_zbuffer.data() + first;
    const std::int32_t* triangle = s_.camera_depth.triangle.data();
    const float* albedo = tris_.albedo.data();
    int u = 0;
    for (; u + 16 <= k_.width; u += 16) {
      // the z-buffer cells 64 pixels on, on their way into the cache (a gather does not call
      // the hardware's prefetcher: each new line waited for memory)
      const std::int32_t ahead = cell_of[std::min(u + 64, k_.width - 1)];
      if (ahead >= 0) _mm_prefetch(reinterpret_cast<const char*>(triangle + ahead), _MM_HINT_T0);
      const __m512i zi = _mm512_loadu_si512(cell_of + u);
      const __m512i t = _mm512_mask_i32gather_epi32(none, _mm512_cmpge_epi32_mask(zi, zero), zi, triangle, 4);
      const __mmask16 surface = _mm512_cmpge_epi32_mask(t, zero);
      const __m512 value = _mm512_maskz_mul_ps(surface, ambient, _mm512_mask_i32gather_ps(_mm512_setzero_ps(), surface, t, albedo, 4));
      float* out = &tile.radiance[3 * (row + u)];
      for (int k = 0; k < 3; ++k) _mm512_storeu_ps(out + 16 * k, _mm512_permutexvar_ps(spread[k], value));
    }
    return u;
  }

  // shade_spot_avx2 eight pixels at a time: blocks of eight aligned on the tile's rows, each
  // block's surfaces computed (all eight) the first time a spot reaches it.
  __attribute__((target(SIM_AVX512_TARGET))) void shade_spot_avx512(const SpotBox& box, int bv0, int bv1, int v0,
                                                                TileLight& tile) const {
    const SpotFrame f = spot_frame(box);
    const __m512d cx = _mm512_set1_pd(f.cx), cy = _mm512_set1_pd(f.cy), reach_max2 = _mm512_set1_pd(f.reach_max2);
    const __m512d radius = _mm512_set1_pd(radius_);
    const Eigen::Vector3f& c = *f.colour;
    // eight pixels' 24 radiance values: each pixel's light spread over its three channels
    const __m256 colour[3] = {_mm256_setr_ps(c[0], c[1], c[2], c[0], c[1], c[2], c[0], c[1]),
                              _mm256_setr_ps(c[2], c[0], c[1], c[2], c[0], c[1], c[2], c[0]),
                              _mm256_setr_ps(c[1], c[2], c[0], c[1], c[2], c[0], c[1], c[2])};
    const __m256i spread[3] = {_mm256_setr_epi32(0, 0, 0, 1, 1, 1, 2, 2), _mm256_setr_epi32(2, 3, 3, 3, 4, 4, 4, 5),
                               _mm256_setr_epi32(5, 5, 6, 6, 6, 7, 7, 7)};
    const int b0 = box.u0 & ~7;
    for (int v = bv0; v <= bv1; ++v) {
      const std::size_t row = static_cast<std::size_t>(v - v0) * tile.stride;
      for (int b = b0; b <= box.u1; b += 8) {
        const std::size_t i = row + b;
        std::uint64_t states;
        std::memcpy(&states, &tile.state[i], 8);
        // some byte is kUnknown (0)
        if ((states - 0x0101010101010101ull) & ~states & 0x8080808080808080ull) surface_light8(v, b, i, tile);
        // the lanes inside the box
        const int lo = std::max(0, box.u0 - b), hi = std::min(7, box.u1 - b);
        const __mmask8 inside = static_cast<__mmask8>((0xFFu << lo) & (0xFFu >> (7 - hi)));
        const __m512d pu = _mm512_loadu_pd(&tile.pu[i]), pv = _mm512_loadu_pd(&tile.pv[i]);
        const __m512d du = _mm512_sub_pd(pu, cx), dv = _mm512_sub_pd(pv, cy);
        const __m512d rho2 = _mm512_add_pd(_mm512_mul_pd(du, du), _mm512_mul_pd(dv, dv));
        // shade_spot's `continue`s, negated as they are written (a NaN goes on, as there)
        const __mmask8 go = _mm512_mask_cmp_pd_mask(inside, rho2, reach_max2, _CMP_NGT_UQ) &
                            _mm512_cmp_pd_mask(rho2, _mm512_loadu_pd(&tile.reach2[i]), _CMP_NGT_UQ);
        if (!go) continue;
        // lit: the pixel's own lookup where the spot's lookup point is the pixel's (see lit_from)
        const __mmask8 own = _mm512_cmp_pd_mask(_mm512_add_pd(du, cx), pu, _CMP_EQ_OQ) &
                             _mm512_cmp_pd_mask(_mm512_add_pd(dv, cy), pv, _CMP_EQ_OQ);
        std::memcpy(&states, &tile.state[i], 8);
        const __m128i state = _mm_cvtsi64_si128(static_cast<long long>(states));
        const int lit_lanes = _mm_movemask_epi8(_mm_cmpeq_epi8(state, _mm_set1_epi8(TileLight::kLit))) & 0xFF;
        const int surface = ~_mm_movemask_epi8(_mm_cmpeq_epi8(state, _mm_set1_epi8(TileLight::kNoSurface))) & 0xFF;
        int elsewhere = go & ~own & surface;  // rare: a spot whose lookup point is not the pixel's
        int lanes = go & own & lit_lanes;
        for (; elsewhere; elsewhere &= elsewhere - 1) {
          const int l = __builtin_ctz(static_cast<unsigned>(elsewhere));
          const std::size_t j = i + l;
          if (lit(tile.pu[j] - f.cx + f.cx, tile.pv[j] - f.cy + f.cy, tile.zp[j])) lanes |= 1 << l;
        }
        if (!lanes) continue;
        const __m256 e = _mm256_mul_ps(
            edge8(_mm512_div_pd(_mm512_sub_pd(_mm512_sqrt_pd(rho2), radius), _mm512_loadu_pd(&tile.sigma[i]))),
            _mm256_loadu_ps(&tile.weight[i]));
        // a lane not lit adds +0 (radiance is never -0: adding +0 changes no bit), the others
        // e * colour, as add_light does
        const __m256 e_lit = _mm256_maskz_mov_ps(static_cast<__mmask8>(lanes), e);
        float* out = &tile.radiance[3 * i];
        for (int k = 0; k < 3; ++k)
          _mm256_storeu_ps(out + 8 * k, _mm256_add_ps(_mm256_loadu_ps(out + 8 * k),
                                                      _mm256_mul_ps(_mm256_permutevar8x32_ps(e_lit, spread[k]), colour[k])));
      }
    }
  }

  // edge4 of eight values
  __attribute__((target(SIM_AVX512_TARGET))) __m256 edge8(__m512d x) const {
    const __m512d f = _mm512_div_pd(_mm512_sub_pd(x, _mm512_set1_pd(EdgeProfile::kLo)), _mm512_set1_pd(EdgeProfile::kStep));
    const __mmask8 below = _mm512_cmp_pd_mask(f, _mm512_setzero_pd(), _CMP_LE_OQ);
    const __mmask8 above = _mm512_cmp_pd_mask(f, _mm512_set1_pd(EdgeProfile::kN - 1), _CMP_GE_OQ);
    const __m512d safe = _mm512_maskz_mov_pd(_mm512_cmp_pd_mask(f, _mm512_setzero_pd(), _CMP_GT_OQ) &
                                                 _mm512_cmp_pd_mask(f, _mm512_set1_pd(EdgeProfile::kN - 1), _CMP_LT_OQ),
                                             f);
    const __m256i i = _mm512_cvttpd_epi32(safe);
    const __m256 t = _mm512_cvtpd_ps(_mm512_sub_pd(safe, _mm512_cvtepi32_pd(i)));
    alignas(32) int at[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(at), i);
    const float* table = edge_.table();
    const __m256 a = _mm256_setr_ps(table[at[0]], table[at[1]], table[at[2]], table[at[3]], table[at[4]], table[at[5]],
                                    table[at[6]], table[at[7]]);
    const __m256 b = _mm256_setr_ps(table[at[0] + 1], table[at[1] + 1], table[at[2] + 1], table[at[3] + 1],
                                    table[at[4] + 1], table[at[5] + 1], table[at[6] + 1], table[at[7] + 1]);
    const __m256 value = _mm256_add_ps(a, _mm256_mul_ps(t, _mm256_sub_ps(b, a)));
    return _mm256_mask_blend_ps(below, _mm256_mask_blend_ps(above, value, _mm256_setzero_ps()), _mm256_set1_ps(1.0f));
  }

  // surface_light4 of the eight pixels (v, u..u+7), tile index i..i+7, in the same order
  __attribute__((target(SIM_AVX512_TARGET))) void surface_light8(int v, int u, std::size_t i, TileLight& tile) const {
    alignas(64) double rx[8], ry[8];
    int tri[8];
    bool one_triangle = true;
    const int valid = lane_surfaces<8>(v, u, tri, rx, ry, one_triangle);
    std::memset(&tile.state[i], TileLight::kNoSurface, 8);
    if (!valid) return;
    __m512d n0, n1, n2, off, w0, w1, w2, alb;
    if (tri[0] >= 0 && one_triangle) {  // the common case
      const int t = tri[0];
      n0 = _mm512_set1_pd(s_.normal_c[t].x()), n1 = _mm512_set1_pd(s_.normal_c[t].y()), n2 = _mm512_set1_pd(s_.normal_c[t].z());
      off = _mm512_set1_pd(s_.offset_c[t]);
      w0 = _mm512_set1_pd(tris_.normal_w[t].x()), w1 = _mm512_set1_pd(tris_.normal_w[t].y()), w2 = _mm512_set1_pd(tris_.normal_w[t].z());
      alb = _mm512_set1_pd(tris_.albedo[t]);
    } else {
      alignas(64) double a[8][8];
      lane_planes<8>(tri, a);
      n0 = _mm512_load_pd(a[0]), n1 = _mm512_load_pd(a[1]), n2 = _mm512_load_pd(a[2]), off = _mm512_load_pd(a[3]);
      w0 = _mm512_load_pd(a[4]), w1 = _mm512_load_pd(a[5]), w2 = _mm512_load_pd(a[6]), alb = _mm512_load_pd(a[7]);
    }
    const __m512d dx = _mm512_load_pd(rx), dy = _mm512_load_pd(ry);
    const __m512d zero = _mm512_setzero_pd();
    const __m512d denom = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(n0, dx), _mm512_mul_pd(n1, dy)),
                                        _mm512_mul_pd(n2, _mm512_set1_pd(1.0)));
    const __m512d z = _mm512_div_pd(off, denom);
    __mmask8 ok = _mm512_cmp_pd_mask(_mm512_abs_pd(denom), _mm512_set1_pd(1e-12), _CMP_NLT_UQ) &
                  _mm512_cmp_pd_mask(z, zero, _CMP_NLE_UQ);
    const __m512d Xp = transform_row8(p_R_c_, p_t_c_, 0, z, dx, dy);
    const __m512d Yp = transform_row8(p_R_c_, p_t_c_, 1, z, dx, dy);
    const __m512d Zp = transform_row8(p_R_c_, p_t_c_, 2, z, dx, dy);
    ok &= _mm512_cmp_pd_mask(Zp, _mm512_set1_pd(1e-3), _CMP_NLE_UQ);
    const __m512d inv_z = _mm512_div_pd(_mm512_set1_pd(1.0), Zp);
    const __m512d pu = _mm512_add_pd(_mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(kp_.fx), Xp), inv_z), _mm512_set1_pd(kp_.cx));
    const __m512d pv = _mm512_add_pd(_mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(kp_.fy), Yp), inv_z), _mm512_set1_pd(kp_.cy));
    const __m512d near_gap = _mm512_sub_pd(_mm512_set1_pd(ps_.focus_near_m), Zp);
    const __m512d far_gap = _mm512_sub_pd(Zp, _mm512_set1_pd(ps_.focus_far_m));
    __m512d outside = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(zero, near_gap, _CMP_LT_OQ), zero, near_gap);
    outside = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(outside, far_gap, _CMP_LT_OQ), outside, far_gap);
    const __m512d blur = _mm512_add_pd(_mm512_set1_pd(ps_.focused_blur_px), _mm512_mul_pd(_mm512_set1_pd(ps_.defocus_px_per_m), outside));
    const __m512d pixel_in_proj = _mm512_mul_pd(_mm512_mul_pd(z, _mm512_set1_pd(proj_per_cam_px_)), inv_z);
    const __m512d sigma = _mm512_add_pd(
        _mm512_sqrt_pd(_mm512_add_pd(_mm512_mul_pd(blur, blur),
                                     _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(0.083), pixel_in_proj), pixel_in_proj))),
        _mm512_set1_pd(1e-6));
    const __m512d reach = _mm512_add_pd(_mm512_set1_pd(radius_), _mm512_mul_pd(_mm512_set1_pd(3.0), sigma));
    const Eigen::Vector3d origin = Eigen::Vector3d::Zero();
    const __m512d Lx = _mm512_sub_pd(_mm512_set1_pd(P_.x()), _mm512_add_pd(_mm512_set1_pd(C_.x()), transform_row8(R_, origin, 0, z, dx, dy, false)));
    const __m512d Ly = _mm512_sub_pd(_mm512_set1_pd(P_.y()), _mm512_add_pd(_mm512_set1_pd(C_.y()), transform_row8(R_, origin, 1, z, dx, dy, false)));
    const __m512d Lz = _mm512_sub_pd(_mm512_set1_pd(P_.z()), _mm512_add_pd(_mm512_set1_pd(C_.z()), transform_row8(R_, origin, 2, z, dx, dy, false)));
    const __m512d dist2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(Lx, Lx), _mm512_mul_pd(Ly, Ly)), _mm512_mul_pd(Lz, Lz));
    const __m512d nL = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(w0, Lx), _mm512_mul_pd(w1, Ly)), _mm512_mul_pd(w2, Lz));
    const __m512d cos_in = _mm512_div_pd(_mm512_abs_pd(nL), _mm512_sqrt_pd(dist2));
    const __m512d falloff = _mm512_div_pd(_mm512_set1_pd(focus_mid_ * focus_mid_), dist2);
    const __m512d weight = _mm512_mul_pd(_mm512_mul_pd(_mm512_mul_pd(alb, _mm512_set1_pd(ps_.brightness)), cos_in), falloff);
    _mm512_storeu_pd(&tile.pu[i], pu);
    _mm512_storeu_pd(&tile.pv[i], pv);
    _mm512_storeu_pd(&tile.zp[i], Zp);
    _mm512_storeu_pd(&tile.sigma[i], sigma);
    _mm512_storeu_pd(&tile.reach2[i], _mm512_mul_pd(reach, reach));
    _mm256_storeu_ps(&tile.weight[i], _mm512_cvtpd_ps(weight));
    const __mmask8 good = static_cast<__mmask8>(valid) & ok;
    const __mmask8 lit_lanes = static_cast<__mmask8>(lit8(pu, pv, Zp));
    const __m128i state = _mm_mask_blend_epi8(
        good, _mm_set1_epi8(TileLight::kNoSurface),
        _mm_mask_blend_epi8(lit_lanes, _mm_set1_epi8(TileLight::kShadow), _mm_set1_epi8(TileLight::kLit)));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(&tile.state[i]), state);
  }

  // lit4 of eight points
  __attribute__((target(SIM_AVX512_TARGET))) int lit8(__m512d u, __m512d v, __m512d z_p) const {
    __m256 nearest = depth8(projector_depth_, u, v);
    if (arm_depth_) {
      const __m256 b = depth8(*arm_depth_, u, v);
      nearest = _mm256_blendv_ps(nearest, b, _mm256_cmp_ps(b, nearest, _CMP_LT_OQ));
    }
    const __m512d limit = _mm512_add_pd(_mm512_mul_pd(_mm512_cvtps_pd(nearest), _mm512_set1_pd(1.0 + 2e-3)), _mm512_set1_pd(2e-3));
    return ~_mm512_cmp_pd_mask(z_p, limit, _CMP_GT_OQ) & 0xFF;
  }
  __attribute__((target(SIM_AVX512_TARGET))) static __m256i nearest8(__m512d x) {
    const __mmask8 inside = _mm512_cmp_pd_mask(x, _mm512_set1_pd(-1e9), _CMP_GT_OQ) &
                            _mm512_cmp_pd_mask(x, _mm512_set1_pd(1e9), _CMP_LT_OQ);
    const __m512d shifted = _mm512_add_pd(_mm512_add_pd(x, _mm512_set1_pd(0.5)), _mm512_set1_pd(DepthBuffer::kShift));
    const __m256i n = _mm256_sub_epi32(_mm512_cvttpd_epi32(_mm512_maskz_mov_pd(inside, shifted)),
                                       _mm256_set1_epi32(static_cast<int>(DepthBuffer::kShift)));
    return _mm256_mask_blend_epi32(inside, _mm256_set1_epi32(-(1 << 30)), n);
  }
  __attribute__((target(SIM_AVX512_TARGET))) static __m256 depth8(const DepthBuffer& d, __m512d u, __m512d v) {
    const __m256i margin = _mm256_set1_epi32(d.margin), zero = _mm256_setzero_si256();
    const __m256i i = _mm256_add_epi32(nearest8(u), margin), j = _mm256_add_epi32(nearest8(v), margin);
    const __m256i out = _mm256_or_si256(_mm256_or_si256(_mm256_cmpgt_epi32(zero, i), _mm256_cmpgt_epi32(zero, j)),
                                        _mm256_or_si256(_mm256_cmpgt_epi32(i, _mm256_set1_epi32(d.width - 1)),
                                                        _mm256_cmpgt_epi32(j, _mm256_set1_epi32(d.height - 1))));
    const __m256i index = _mm256_andnot_si256(out, _mm256_add_epi32(_mm256_mullo_epi32(j, _mm256_set1_epi32(d.width)), i));
    alignas(32) int at[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(at), index);
    const float* inv_depth = d.inv_depth.data();
    const __m256 q = _mm256_setr_ps(inv_depth[at[0]], inv_depth[at[1]], inv_depth[at[2]], inv_depth[at[3]],
                                    inv_depth[at[4]], inv_depth[at[5]], inv_depth[at[6]], inv_depth[at[7]]);
    const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
    const __m256 depth = _mm256_blendv_ps(inf, _mm256_div_ps(_mm256_set1_ps(1.0f), q), _mm256_cmp_ps(q, _mm256_setzero_ps(), _CMP_GT_OQ));
    return _mm256_blendv_ps(depth, inf, _mm256_castsi256_ps(out));
  }
  __attribute__((target(SIM_AVX512_TARGET))) static __m512d transform_row8(const Eigen::Matrix3d& M, const Eigen::Vector3d& t,
                                                                        int r, __m512d z, __m512d dx, __m512d dy,
                                                                        bool add_t = true) {
    const __m512d a0 = _mm512_mul_pd(_mm512_mul_pd(z, _mm512_set1_pd(M(r, 0))), dx);
    const __m512d a1 = _mm512_mul_pd(_mm512_mul_pd(z, _mm512_set1_pd(M(r, 1))), dy);
    const __m512d a2 = _mm512_mul_pd(_mm512_mul_pd(z, _mm512_set1_pd(M(r, 2))), _mm512_set1_pd(1.0));
    const __m512d sum = r < 2 ? _mm512_add_pd(_mm512_add_pd(a0, a1), a2) : _mm512_add_pd(a0, _mm512_add_pd(a1, a2));
    return add_t ? _mm512_add_pd(sum, _mm512_set1_pd(t[r])) : sum;
  }

  // lit when the projector's nearest surface along this direction is this one
  bool lit(double u, double v, double z_p) const {
    float nearest = projector_depth_.depth_at(u, v);
    if (arm_depth_) nearest = std::min(nearest, arm_depth_->depth_at(u, v));
    return !(z_p > nearest * (1.0 + 2e-3) + 2e-3);
  }

  const EdgeProfile& edge_ = edge_profile();
  const Cell& cell_;
  const Projector& proj_;
  const ProjectorSpec& ps_;
  const Intrinsics& kp_;
  const Intrinsics& k_;
  const SceneTriangles& tris_;
  const std::vector<SpotHit>& hits_;
  const DepthBuffer& projector_depth_;
  const DepthBuffer* arm_depth_;
  const RenderScratch& s_;
  const float ambient_;
  const std::array<Eigen::Vector3f, 10> spot_rgb_;
  const Eigen::Matrix3d R_;
  const Eigen::Vector3d C_, P_;
  const double radius_, focus_mid_;
  const float* rays_;
  const double proj_per_cam_px_;
  Eigen::Matrix3d p_R_c_;
  Eigen::Vector3d p_t_c_;
};

}  // namespace

cv::Mat render_image(const Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     RenderScratch* scratch, const CameraSpec* sensor, const LinkPoses* links) {
  const CameraSpec& cam = sensor ? *sensor : cell.scenario.camera;
  const Intrinsics& k = cell.scenario.camera.intrinsics;  // the lens is the cell's, whatever the sensor

  RenderScratch local;
  RenderScratch& s = scratch ? *scratch : local;
  s.arm.scalar = s.scalar;
  const FrameScene scene = pose_scene(cell, links, s.arm, true);
  const SceneTriangles& tris = *scene.triangles;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  rasterize(tris, c_T_w, k, cell.camera_margin_px, s.camera_depth, !s.scalar, s.avx512);
  render_parts::spot_boxes(cell, *scene.spot_hits, c_T_w, s.boxes);
  // triangle planes in the camera frame, once per frame
  const Eigen::Matrix3d R = world_T_camera.linear();
  const Eigen::Vector3d C = world_T_camera.translation();
  s.normal_c.resize(tris.normal_w.size());
  s.offset_c.resize(tris.normal_w.size());
  for (std::size_t i = 0; i < tris.normal_w.size(); ++i) {
    s.normal_c[i] = R.transpose() * tris.normal_w[i];
    s.offset_c[i] = tris.offset[i] - tris.normal_w[i].dot(C);
  }
  const FrameLight light(cell, scene, s, world_T_camera, cam);
  const VectorUnit unit = vector_unit(s.scalar, s.avx512);
  render_parts::Sensor sensor_model(cell, cam, noise_seed);
  sensor_model.scalar = s.scalar;
  sensor_model.avx512 = s.avx512;

  // Tiles of rows run in parallel; every pixel is written by the tile that owns its row, in
  // the same order (ambient, then the spots in box order), and the noise of a row depends
  // only on the seed and the row: the image does not depend on how the rows are split.
  cv::Mat image(k.height, k.width, CV_8UC3);
  const std::size_t row_len = static_cast<std::size_t>(k.width) * 3;
  const int tiles = (k.height + kTileRows - 1) / kTileRows;
  const auto render_tiles = [&](const cv::Range& band) {
    TileLight tile(kTileRows, k.width);
    for (int t = band.start; t < band.end; ++t) {
      const int v0 = t * kTileRows, v1 = std::min(k.height, v0 + kTileRows);
      // the rows' noise, runs at random places of an 8 MB pool, on its way into the cache
      // while the tile is shaded (the sensor's loads waited for memory: half its time)
      for (int v = v0; v < v1; ++v) {
        const char* noise = reinterpret_cast<const char*>(sensor_model.row_noise(v));
        for (std::size_t b = 0; b < row_len * sizeof(float); b += 64) _mm_prefetch(noise + b, _MM_HINT_T1);
      }
      light.shade(v0, v1, tile, unit);
      for (int v = v0; v < v1; ++v)
        sensor_model.expose_row(v, &tile.radiance[static_cast<std::size_t>(v - v0) * tile.stride * 3],
                                image.ptr<std::uint8_t>(v), row_len);
    }
  };
  if (s.threads == 1)
    render_tiles(cv::Range(0, tiles));
  else
    // one stripe per thread: each stripe allocates its tile buffers once (230 kB)
    cv::parallel_for_(cv::Range(0, tiles), render_tiles, std::max(1, cv::getNumThreads()));
  return image;
}

bool spot_resolved(double blur_px, const ProjectorSpec& spec) {
  // two neighbours as Gaussians of the disc's spread and the blur, one pitch apart: the light
  // midway is 2 exp(-p^2 / 8 s^2) of a peak; it falls below 40 % when s < p / 3.6
  const double r = spec.spot_radius_px;
  const double spread = std::sqrt(blur_px * blur_px + 0.25 * r * r);
  return spread < spec.spot_pitch_px / 3.6;
}

std::vector<SpotTruth> compute_truth(const Cell& cell, const Eigen::Isometry3d& world_T_camera, const LinkPoses* links) {
  ArmFrameBuffers buffers;
  const FrameScene scene = pose_scene(cell, links, buffers, false);
  const bool arm = links && !links->empty() && cell.arm_meshes.size() > 0;
  const int first_arm_object = static_cast<int>(cell.object_names.size());
  const pattern::MArray& pat = cell.projector->pattern();
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  const Eigen::Vector3d C = world_T_camera.translation();
  const Eigen::Isometry3d p_T_w = cell.projector->projector_T_world();
  std::vector<SpotTruth> truth(pat.cells.size());
  for (int r = 0; r < pat.rows; ++r)
    for (int c = 0; c < pat.cols; ++c) {
      SpotTruth& t = truth[static_cast<std::size_t>(r) * pat.cols + c];
      t.row = r;
      t.col = c;
    }
  for (const SpotHit& h : *scene.spot_hits) {
    if (!h.centre) continue;
    SpotTruth& t = truth[static_cast<std::size_t>(h.row) * pat.cols + h.col];
    t.on_arm = h.centre->object >= first_arm_object;
    t.object = h.centre->object;
    t.point_w = h.centre->point_w;
    const Eigen::Vector3d X_c = c_T_w * t.point_w;
    t.depth_m = X_c.z();
    for (const auto& rim : h.rim)
      if (rim) {
        const Eigen::Vector3d R_c = c_T_w * rim->point_w;
        if (R_c.z() > 1e-3) t.light_px.push_back(cell.camera->project(R_c));
      }
    if (X_c.z() <= 1e-3) continue;
    t.uv = cell.camera->project(X_c);
    t.light_px.push_back(t.uv);
    const bool inside = t.uv.x() >= -0.5 && t.uv.y() >= -0.5 && t.uv.x() < k.width - 0.5 && t.uv.y() < k.height - 0.5;
    const bool facing = h.centre->normal_w.dot(C - t.point_w) > 0;
    if (!inside || !facing) continue;
    // the segment from the camera to 1 mm short of the spot must be free
    const Eigen::Vector3d to = t.point_w + (C - t.point_w).normalized() * 1e-3;
    t.visible = !cell.world.ray_test(C, to).has_value();
    if (t.visible && arm && cell.arm_meshes.ray_test(*links, C, to)) {
      t.visible = false;
      t.hidden_by_arm = true;
    }
    if (!t.visible) continue;
    t.blur_px = cell.projector->defocus_sigma_px((p_T_w * t.point_w).z());
    t.resolved = spot_resolved(t.blur_px, cell.projector->spec());
    for (const auto& rim : h.rim)
      if (rim && rim->object == h.centre->object) {
        const Eigen::Vector3d R_c = c_T_w * rim->point_w;
        if (R_c.z() > 1e-3) t.footprint_px.push_back(cell.camera->project(R_c));
      }
  }
  return truth;
}

}  // namespace sim
