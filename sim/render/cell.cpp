#include "sim/render/cell.hpp"

#include "sim/scene/mesh_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "servo/pattern/pattern_file.hpp"
#include "sim/render/shading.hpp"

namespace sim {

namespace {

// Light::beam_gap: each triangle's image box on the projector's plane against beam_pixels.
std::vector<float> beam_gaps(const SceneTriangles& tris, const Projector& proj, const RasterClip& w, int margin) {
  std::vector<float> gap(tris.a.size(), 0.0f);
  if (w.x0 > w.x1 || w.y0 > w.y1) return gap;
  const Eigen::AlignedBox2d window = beam_pixels(w, margin);
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  const Intrinsics& k = proj.spec().intrinsics;
  for (std::size_t i = 0; i < tris.a.size(); ++i) {
    Eigen::AlignedBox2d box;
    bool behind = false;
    for (const Eigen::Vector3d* v : {&tris.a[i], &tris.b[i], &tris.c[i]}) {
      const Eigen::Vector3d x = p_T_w * *v;
      if (!(x.z() > 1e-3)) behind = true;
      box.extend(pinhole_pixel(k, x));
    }
    if (behind) continue;
    const double away = gap_beyond(box, window);
    if (away > 0 && away < 1e9) gap[i] = static_cast<float>(away);
  }
  return gap;
}

// Light::never_shadowed. A plane P qualifies when, at every cell c of the beam window, P's 1/z
// over c's +-0.51 px box (the kernel looks up the cell nearest to a point's projector
// coordinates, computed in single precision) stays above 0, and the stored 1/z at c (the
// nearest surface, as the kernel reads it) no more than 0.1 % above its least (1/z is affine
// on the image, so least at a corner). Then any point X of P's plane that the kernel looks up
// has z_X q_c <= 1.001, where it darkens only above 1.002 + 0.002 q_c: skipping the lookup
// gives the same bytes, whatever the camera's pose. Only the planes that are the nearest
// surface somewhere in the window can qualify (a wall facing the projector, with nothing
// before it); each is checked row by row against the upper hull of the row's 1/z.
std::vector<std::uint8_t> never_shadowed_planes(const SceneTriangles& tris, const Projector& proj, const DepthBuffer& d,
                                                const RasterClip& w) {
  const std::size_t n = tris.a.size();
  std::vector<std::uint8_t> out(n, 0);
  if (tris.plane_of.size() != n || w.x0 > w.x1 || w.y0 > w.y1 || d.margin != 0 ||
      d.triangle.size() != d.inv_depth.size())
    return out;
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  const Intrinsics& k = proj.spec().intrinsics;
  constexpr double kBox = 0.51, kSlack = 1e-3;
  std::vector<std::uint8_t> candidate(n, 0);
  for (int y = w.y0; y <= w.y1; ++y)
    for (int x = w.x0; x <= w.x1; ++x) {
      const std::int32_t t = d.triangle[static_cast<std::size_t>(y) * d.width + x];
      if (t >= 0 && static_cast<std::size_t>(t) < n) candidate[static_cast<std::size_t>(tris.plane_of[t])] = 1;
    }
  // Per row of the window, the upper hull of (x, q_x / (1 + kSlack)): a plane's condition on a
  // row, a x + row >= q_x / (1 + kSlack) for every x, holds when it holds at the hull's vertex
  // that maximises q_x / (1 + kSlack) - a x (where the hull's edges' slopes pass a).
  const int rows = w.y1 - w.y0 + 1;
  std::vector<std::vector<int>> hull_x(static_cast<std::size_t>(rows));
  std::vector<std::vector<double>> hull_q(static_cast<std::size_t>(rows));
  for (int y = w.y0; y <= w.y1; ++y) {
    auto& hx = hull_x[static_cast<std::size_t>(y - w.y0)];
    auto& hq = hull_q[static_cast<std::size_t>(y - w.y0)];
    for (int x = w.x0; x <= w.x1; ++x) {
      const double q = d.inv_depth[static_cast<std::size_t>(y) * d.width + x] / (1 + kSlack);
      // drop the last vertex while it lies on or below the line from the one before to this
      while (hx.size() >= 2) {
        const std::size_t m = hx.size();
        const double cross = (hx[m - 1] - hx[m - 2]) * (q - hq[m - 2]) - (hq[m - 1] - hq[m - 2]) * (x - hx[m - 2]);
        if (cross < 0) break;
        hx.pop_back();
        hq.pop_back();
      }
      hx.push_back(x);
      hq.push_back(q);
    }
  }
  const auto passes = [&](std::size_t plane) {
    const Eigen::Vector3d n_p = p_T_w.linear() * tris.normal_w[plane];
    const double o_p = tris.offset[plane] + n_p.dot(p_T_w.translation());  // n_p . X_p = o_p
    if (!(std::abs(o_p) > 1e-9)) return false;
    // 1/z of the plane on the projector's image: a x + b y + c
    const double a = n_p.x() / (k.fx * o_p), b = n_p.y() / (k.fy * o_p);
    const double c = (n_p.z() - n_p.x() * k.cx / k.fx - n_p.y() * k.cy / k.fy) / o_p;
    const double reach = kBox * (std::abs(a) + std::abs(b));
    // above 0 over the window: at its corners (affine)
    for (const int y : {w.y0, w.y1})
      for (const int x : {w.x0, w.x1})
        if (!(a * x + b * y + c - reach > 0)) return false;
    for (int y = w.y0; y <= w.y1; ++y) {
      const auto& hx = hull_x[static_cast<std::size_t>(y - w.y0)];
      const auto& hq = hull_q[static_cast<std::size_t>(y - w.y0)];
      // the first vertex whose next edge's slope is at most a
      std::size_t lo = 0, hi = hx.size() - 1;
      while (lo < hi) {
        const std::size_t mid = (lo + hi) / 2;
        if (hq[mid + 1] - hq[mid] <= a * (hx[mid + 1] - hx[mid])) hi = mid;
        else lo = mid + 1;
      }
      if (!(a * hx[lo] + b * y + c - reach >= hq[lo])) return false;
    }
    return true;
  };
  std::vector<std::uint8_t> plane_ok(n, 0);
  for (std::size_t p = 0; p < n; ++p)
    if (candidate[p]) plane_ok[p] = passes(p);
  for (std::size_t i = 0; i < n; ++i) out[i] = plane_ok[static_cast<std::size_t>(tris.plane_of[i])];
  return out;
}

}  // namespace

namespace {

// The projector's beam window over its depth buffer (Light::beam) and what the renderer keeps
// of it: the depth there, the planes never in shadow, each triangle's gap to the window.
void fit_beam(const SceneTriangles& triangles, Light& light) {
  const Projector& proj = *light.projector;
  const DepthBuffer& d = light.projector_depth;
  const Eigen::Vector2d a = proj.spot_pixel(0, 0), b = proj.spot_pixel(proj.pattern().rows - 1, proj.pattern().cols - 1);
  const double spread = proj.spec().spot_radius_px + 3.0 * proj.defocus_sigma_px(light.farthest_spot_m + 0.5) + 4.0;
  RasterClip& w = light.beam;
  w.x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x(), b.x()) - spread)) + d.margin);
  w.y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y(), b.y()) - spread)) + d.margin);
  w.x1 = std::min(d.width - 1, static_cast<int>(std::ceil(std::max(a.x(), b.x()) + spread)) + d.margin);
  w.y1 = std::min(d.height - 1, static_cast<int>(std::ceil(std::max(a.y(), b.y()) + spread)) + d.margin);
  light.beam_depth = beam_window(d, w);
  light.never_shadowed = never_shadowed_planes(triangles, proj, d, w);
  light.beam_gap = beam_gaps(triangles, proj, w, d.margin);
}

// The projector standing at world_T_projector: its spots' hits and, with_depth, its view of the
// static scene (its depth buffer) and the beam window over it.
void light_the_scene(const Cell& cell, const Eigen::Isometry3d& world_T_projector, bool with_depth, Light& light) {
  ProjectorSpec spec = cell.projector->spec();
  spec.world_T_projector = world_T_projector;
  light.projector = std::make_shared<const Projector>(spec, cell.projector->pattern());
  light.spot_hits = light.projector->cast_spots(cell.world);
  light.farthest_spot_m = 0;
  for (const SpotHit& h : light.spot_hits)
    if (h.centre)
      light.farthest_spot_m = std::max(light.farthest_spot_m, (h.centre->point_w - world_T_projector.translation()).norm());
  light.with_depth = with_depth;
  if (!with_depth) return;
  rasterize(cell.triangles, light.projector->projector_T_world(), spec.intrinsics, 0, light.projector_depth);
  fit_beam(cell.triangles, light);
}

// The camera's rays: the margin its depth buffer needs so every distorted pixel's ray lands in
// it, each pixel's cell there (double precision, the previous renderer's), and the lens as the
// shading kernel reads it.
void lay_out_lens(Cell& cell) {
  // the margin the camera's depth buffer needs so every distorted pixel's ray lands in it
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const auto& rays = cell.camera->pixel_rays();
  double excess = 0;
  for (std::size_t i = 0; i < rays.size(); i += 2) {
    const double u = k.fx * rays[i] + k.cx, v = k.fy * rays[i + 1] + k.cy;
    excess = std::max({excess, -u, -v, u - (k.width - 1), v - (k.height - 1)});
  }
  cell.camera_margin_px = static_cast<int>(std::ceil(std::min(excess, 4.0 * k.width))) + 2;
  const int m = cell.camera_margin_px, zw = k.width + 2 * m, zh = k.height + 2 * m;
  cell.pixel_to_zbuffer.resize(rays.size() / 2);
  for (std::size_t i = 0; i < cell.pixel_to_zbuffer.size(); ++i) {
    const int zu = DepthBuffer::nearest(k.fx * rays[2 * i] + k.cx) + m;
    const int zv = DepthBuffer::nearest(k.fy * rays[2 * i + 1] + k.cy) + m;
    cell.pixel_to_zbuffer[i] = zu < 0 || zv < 0 || zu >= zw || zv >= zh ? -1 : zv * zw + zu;
  }

  Cell::Lens& lens = cell.lens;
  lens.stride = (k.width + 15) & ~15;
  const std::size_t padded = static_cast<std::size_t>(lens.stride) * k.height;
  lens.ray_x.assign(padded, std::numeric_limits<float>::quiet_NaN());
  lens.ray_y.assign(padded, std::numeric_limits<float>::quiet_NaN());
  // the ray to its z-buffer cell: a single-precision multiply and add, then floor
  const float zfx = static_cast<float>(k.fx), zcx = static_cast<float>(k.cx + m + 0.5);
  const float zfy = static_cast<float>(k.fy), zcy = static_cast<float>(k.cy + m + 0.5);
  lens.zrow_lo.assign(static_cast<std::size_t>(k.height), zh);
  lens.zrow_hi.assign(static_cast<std::size_t>(k.height), -1);
  lens.zcell.assign(padded, -1);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * k.width + u, at = static_cast<std::size_t>(v) * lens.stride + u;
      lens.ray_x[at] = rays[2 * px];
      lens.ray_y[at] = rays[2 * px + 1];
      const float x = lens.ray_x[at] * zfx + zcx, y = lens.ray_y[at] * zfy + zcy;
      if (!(x >= 0 && x < zw && y >= 0 && y < zh)) continue;
      const int row = static_cast<int>(std::floor(y));
      lens.zcell[at] = row * zw + static_cast<int>(std::floor(x));
      lens.zrow_lo[static_cast<std::size_t>(v)] = std::min(lens.zrow_lo[static_cast<std::size_t>(v)], row);
      lens.zrow_hi[static_cast<std::size_t>(v)] = std::max(lens.zrow_hi[static_cast<std::size_t>(v)], row);
    }
  // sixteen pixels of a row look up cells of one or two z-buffer rows: usually one run
  lens.zrun.assign(padded / 16, -1);
  for (std::size_t g = 0; g < lens.zrun.size(); ++g) {
    int lo = std::numeric_limits<int>::max(), hi = -1;
    for (std::size_t j = 16 * g; j < 16 * g + 16; ++j)
      if (lens.zcell[j] >= 0) lo = std::min(lo, lens.zcell[j]), hi = std::max(hi, lens.zcell[j]);
    if (hi >= 0 && hi - lo < 32) lens.zrun[g] = lo;
  }
}

// Each spot's symbol (unlit ones marked) and the noise pool the sensor reads.
void draw_symbols_and_noise(Cell& cell) {
  const pattern::MArray& pat = cell.projector->pattern();
  cell.spot_symbol.assign(pat.cells.size(), shading::kUnlitSymbol);
  for (int r = 0; r < pat.rows; ++r)
    for (int c = 0; c < pat.cols; ++c)
      if (cell.projector->is_lit(r, c)) cell.spot_symbol[static_cast<std::size_t>(r) * pat.cols + c] = pat.at(r, c);

  std::mt19937_64 rng(cell.scenario.seed);
  std::normal_distribution<float> gauss(0.f, 1.f);
  cell.noise_pool.resize(std::size_t{1} << 16);
  for (float& x : cell.noise_pool) x = gauss(rng);
}

}  // namespace

void prepare_rendering(Cell& cell) {
  light_the_scene(cell, cell.scenario.projector.world_T_projector, true, cell.light);
  cell.light.projector = cell.projector;  // the same projector (and pose): one object
  lay_out_lens(cell);
  draw_symbols_and_noise(cell);
}

const Light& light_at(const Cell& cell, const Eigen::Isometry3d& world_T_camera, Light& scratch, bool with_depth) {
  const std::optional<Eigen::Isometry3d>& mount = cell.scenario.projector.on_camera;
  if (!mount) return cell.light;
  // the same pose as the scratch's (to the bit): the light stands where it did
  if (scratch.projector && scratch.at && scratch.at->matrix() == world_T_camera.matrix() && (scratch.with_depth || !with_depth))
    return scratch;
  light_the_scene(cell, world_T_camera * *mount, with_depth, scratch);
  scratch.at = world_T_camera;
  return scratch;
}

}  // namespace sim
