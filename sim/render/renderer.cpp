#include "sim/render/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <opencv2/core/utility.hpp>

#include "servo/pattern/palette.hpp"
#include "sim/render/shading.hpp"
#include "sim/render/vector_unit.hpp"

namespace sim {
namespace {

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace
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
  t.outward.resize(first);
  t.plane_of.resize(first);
  t.corner.resize(first);
  t.quad_extra.resize(first);
  t.quad_edge.resize(first);
  t.vertex_w.resize(cell.triangles.vertex_w.size());
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
Eigen::AlignedBox2d arm_box_in_projector(const Cell& cell, const Light& light, const LinkPoses& links, bool& behind) {
  const MovingMeshes& arm = cell.arm_meshes;
  const Projector& proj = *light.projector;
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
      box.extend(pinhole_pixel(kp, x));
    }
  }
  return box;
}

// The projector's depth with the arm: only the region the arm's box covers is redrawn over
// the static depth, and only where spots can shine.
const DepthBuffer& arm_projector_depth(const Light& light, const SceneTriangles& triangles, std::size_t first,
                                       const Eigen::AlignedBox2d& box, bool behind, ArmFrameBuffers& buf) {
  const Projector& proj = *light.projector;
  const Intrinsics& kp = proj.spec().intrinsics;
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  DepthBuffer& d = buf.arm_projector_depth;
  const DepthBuffer& full = light.projector_depth;
  const std::size_t n = static_cast<std::size_t>(full.width) * full.height;
  if (d.width != full.width || d.height != full.height || d.margin != full.margin || d.inv_depth.size() != n) {
    d.width = full.width;
    d.height = d.rows = full.height;
    d.row0 = 0;
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
  // only where spots can shine is the projector's depth ever read (Light::beam)
  RasterClip clip = light.beam;
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

FrameScene pose_scene(const Cell& cell, const Light& light, const LinkPoses* links, ArmFrameBuffers& buf,
                      bool with_triangles, bool with_hits) {
  FrameScene scene{&cell.triangles, &light.spot_hits, &light.projector_depth, nullptr, false};
  if (!links || links->empty() || cell.arm_meshes.size() == 0) return scene;
  if (with_triangles) scene.triangles = &posed_triangles(cell, *links, buf);
  // is any of the arm in the projector's beam? its box on the projector's image plane
  const Projector& proj = *light.projector;
  const Intrinsics& kp = proj.spec().intrinsics;
  bool behind = false;
  const Eigen::AlignedBox2d box = arm_box_in_projector(cell, light, *links, behind);
  const double reach = proj.spec().spot_radius_px + 2;
  const Eigen::AlignedBox2d image(Eigen::Vector2d(-reach, -reach), Eigen::Vector2d(kp.width + reach, kp.height + reach));
  if (!behind && (box.isEmpty() || !box.intersects(image))) return scene;
  scene.arm_in_beam = true;
  if (with_hits) {
    buf.spot_hits = light.spot_hits;
    const int object_offset = static_cast<int>(cell.object_names.size());
    for (SpotHit& h : buf.spot_hits) {
      const Eigen::Vector2d c = proj.spot_pixel(h.row, h.col);
      if (!behind && (c.x() < box.min().x() - reach || c.x() > box.max().x() + reach || c.y() < box.min().y() - reach ||
                      c.y() > box.max().y() + reach))
        continue;
      proj.recast(h, cell.arm_meshes, *links, object_offset);
    }
    scene.spot_hits = &buf.spot_hits;
  }
  if (with_triangles)
    scene.arm_projector_depth = &arm_projector_depth(light, *scene.triangles, cell.triangles.a.size(), box, behind, buf);
  return scene;
}

std::uint64_t frame_seed(std::uint64_t scenario_seed, std::uint64_t frame) {
  std::uint64_t s = scenario_seed ^ (0xD1B54A32D192ED03ull * (frame + 1));
  return splitmix64(s);
}

std::uint64_t white_frame_seed(std::uint64_t pattern_seed) { return frame_seed(pattern_seed, 0x5768697465ull); }

namespace {

// 0.5 erfc(x / sqrt 2), the fraction of a Gaussian-blurred edge's light at signed distance x (in
// sigmas) outside it, as cubic Hermite segments (values and slopes exact at their ends: within
// 2e-5 of it) over [-kEdgeReach, kEdgeReach)
struct EdgeProfile {
  std::array<float, shading::kEdgeSegments> c[4];
  EdgeProfile() {
    const double h = 2.0 * shading::kEdgeReach / shading::kEdgeSegments;
    const auto value = [](double x) { return 0.5 * std::erfc(x / std::sqrt(2.0)); };
    const auto slope = [](double x) { return -std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI); };
    for (int k = 0; k < shading::kEdgeSegments; ++k) {
      const double x0 = -shading::kEdgeReach + k * h, x1 = x0 + h;
      const double p0 = value(x0), p1 = value(x1), m0 = slope(x0) * h, m1 = slope(x1) * h;
      c[0][k] = static_cast<float>(p0);
      c[1][k] = static_cast<float>(m0);
      c[2][k] = static_cast<float>(3 * (p1 - p0) - 2 * m0 - m1);
      c[3][k] = static_cast<float>(2 * (p0 - p1) + m0 + m1);
    }
  }
};
const EdgeProfile& edge_profile() {
  static const EdgeProfile profile;  // immutable, built once
  return profile;
}

// Image rows shaded together (see render_image): on one thread 120 (a VGA band's z-buffer,
// 0.75 MB, stays in the core's second cache while its rows are shaded, and fewer bands cut
// fewer polygons' rows into partial blocks: 4-5 % of a frame against 48), on several 48 (more
// bands to share out)
constexpr int kBandRowsOneThread = 120, kBandRowsShared = 48;

shading::DepthView beam_view(const Light& light, const std::vector<float>& window) {
  const RasterClip& w = light.beam;
  if (w.x0 > w.x1 || w.y0 > w.y1) return {window.data(), 0, 0, 0, 0};
  const int margin = light.projector_depth.margin;
  return {window.data(), w.x1 - w.x0 + 1, w.y1 - w.y0 + 1, margin - w.x0, margin - w.y0};
}

// Each triangle's numbers of shading.hpp, for this camera pose (double precision, then float);
// then, from n on, the planes' numbers for their triangles outside the beam (outside_beam):
// their ambient alone (G = 0: no point, no spot).
void prepare_triangles(const Light& light, const SceneTriangles& tris, const Eigen::Isometry3d& world_T_camera,
                       const CameraSpec& cam, bool skip_unshadowed, std::vector<float>& out) {
  const ProjectorSpec& ps = light.projector->spec();
  const Eigen::Matrix3d R = world_T_camera.linear();
  const Eigen::Vector3d C = world_T_camera.translation();
  const Eigen::Vector3d P = ps.world_T_projector.translation();
  const double focus_mid = 0.5 * (ps.focus_near_m + ps.focus_far_m);
  const std::size_t n = tris.normal_w.size();
  const std::size_t stride = shading::triangle_stride(2 * n);
  out.assign(stride * shading::kTriangleFields, 0.0f);
  // the z-buffer names each pixel's plane (its first triangle, SceneTriangles::plane_of): only
  // those are ever read
  const bool by_plane = tris.plane_of.size() == n;
  for (std::size_t i = 0; i < n; ++i) {
    if (by_plane && tris.plane_of[i] != static_cast<std::int32_t>(i)) continue;
    const auto rec = [&](int field) -> float& { return out[field * stride + i]; };
    rec(shading::kAmbient) = static_cast<float>(cam.ambient) * tris.albedo[i];
    out[shading::kAmbient * stride + n + i] = rec(shading::kAmbient);
    const Eigen::Vector3d n_c = R.transpose() * tris.normal_w[i];
    const double o_c = tris.offset[i] - tris.normal_w[i].dot(C);  // plane n_c . X = o_c, camera frame
    // a plane through the camera's centre is seen edge-on: its ambient, no spot (G = 0)
    if (!(std::abs(o_c) > 1e-9)) continue;
    const Eigen::Vector3d g = n_c / o_c;
    for (int k = 0; k < 3; ++k) rec(shading::kG0 + k) = static_cast<float>(g[k]);
    // |n.L| is the projector's distance from the plane: the same for every point of it
    const double facing = std::abs(tris.normal_w[i].dot(P) - tris.offset[i]);
    rec(shading::kReturn) = static_cast<float>(tris.albedo[i] * ps.brightness * facing * focus_mid * focus_mid);
    // the static scene's planes (the arm's come after them) never in its shadow: -K
    if (skip_unshadowed && i < light.never_shadowed.size() && light.never_shadowed[i]) rec(shading::kReturn) *= -1;
  }
}

// Each triangle's tint (World::Object::tint: its channels' share of its albedo), in the layout
// of the triangles' fields, at i and at its copy n + i; false, and nothing written, when every
// surface is grey (the kernel then multiplies nothing: a grey scene's bytes are as before).
bool prepare_tint(const Cell& cell, const SceneTriangles& tris, std::vector<float>& out) {
  const auto& objects = cell.world.objects();
  const bool tinted = std::any_of(objects.begin(), objects.end(),
                                  [](const World::Object& o) { return o.tint != Eigen::Vector3d::Ones(); });
  if (!tinted) return false;
  const std::size_t n = tris.normal_w.size();
  const std::size_t stride = shading::triangle_stride(2 * n);
  out.assign(stride * 3, 1.0f);  // the arm's links, after the objects: grey
  // the z-buffer names a plane's first triangle (SceneTriangles::plane_of): only those are read
  const bool by_plane = tris.plane_of.size() == n;
  for (std::size_t i = 0; i < n; ++i) {
    if (by_plane && tris.plane_of[i] != static_cast<std::int32_t>(i)) continue;
    const auto o = static_cast<std::size_t>(tris.object[i]);
    if (o >= objects.size()) continue;
    for (int c = 0; c < 3; ++c) out[c * stride + i] = out[c * stride + n + i] = static_cast<float>(objects[o].tint[c]);
  }
  return true;
}

// The frame's coloured and textured surfaces (Frame::tint, texture_map, texel, texels).
void surface_colours(const Cell& cell, const SceneTriangles& tris, const Eigen::Isometry3d& world_T_camera,
                     RenderScratch& s, shading::Frame& f) {
  f.tint = prepare_tint(cell, tris, s.tint) ? s.tint.data() : nullptr;
  if (prepare_texture(cell.world, cell.textures, tris, world_T_camera, s.texture)) {
    f.texture_map = s.texture.map.data();
    f.texel = s.texture.texel.data();
    f.texels = cell.textures.texels.data();
  }
}

}  // namespace

// A pixel the z-buffer gives to a triangle looks along a ray within half a pixel of the
// triangle's image (its z-buffer cell's centre lies in that image; the lens table rounds the ray
// to the nearest cell). So the rays through the triangle's image box widened by a pixel meet
// its plane in a region holding every point such a pixel shades: the box's four corner rays
// meet the plane in front of the camera (then the whole box's rays do, and the region is the
// convex quadrilateral of the four points), and each of the four lies in front of the
// projector (then the whole region does, and its image is the convex hull of theirs). When
// that image lies a projector pixel or more beyond beam_pixels, no rounding in the kernel
// (about 1e-3 of a pixel) brings any of those points into the window. Rays meeting the plane
// at a grazing angle (cosine under 0.01) are not trusted: there the kernel's 1/z loses digits.
void outside_beam(const Cell& cell, const Light& light, const Eigen::Isometry3d& world_T_camera,
                  std::vector<std::uint8_t>& out) {
  const SceneTriangles& tris = cell.triangles;
  const std::size_t n = std::min(tris.a.size(), light.beam_gap.size());
  out.assign(n, 0);
  const RasterClip& w = light.beam;
  if (w.x0 > w.x1 || w.y0 > w.y1) return;
  const Eigen::AlignedBox2d window = beam_pixels(w, light.projector_depth.margin);
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const Intrinsics& kp = light.projector->spec().intrinsics;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  const Eigen::Isometry3d p_T_c = light.projector->projector_T_world() * world_T_camera;
  const Eigen::Vector3d C = world_T_camera.translation();
  constexpr double kNearest = 0.01, kGrazing = 0.01, kClear = 1.0;  // metres, cosine, projector pixels
  // Below, reciprocals and squares stand for divisions and roots: this is a decision with a
  // pixel to spare, and they move it by 1e-16 of a pixel.
  // each vertex once: its image, or NaN where before kNearest
  const bool indexed = tris.corner.size() == tris.a.size();
  thread_local std::vector<Eigen::Vector2d> vertex_image;
  const auto image_of = [&](const Eigen::Vector3d& v) {
    const Eigen::Vector3d x = c_T_w * v;
    return x.z() >= kNearest ? pinhole_pixel(k, x) : Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  };
  if (indexed) {
    vertex_image.resize(tris.vertex_w.size());
    for (std::size_t v = 0; v < tris.vertex_w.size(); ++v) vertex_image[v] = image_of(tris.vertex_w[v]);
  }
  const double inv_fx = 1.0 / k.fx, inv_fy = 1.0 / k.fy;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(light.beam_gap[i] > kClear)) continue;  // its own image reaches the window: so does the region
    // a face of a closed mesh turned away from the camera is never drawn (project_triangles)
    if (tris.outward.size() == tris.a.size() && faces_away(tris, i, C)) continue;
    Eigen::AlignedBox2d image;
    bool near = false;
    for (int q = 0; q < 3; ++q) {
      const Eigen::Vector2d x = indexed ? vertex_image[static_cast<std::size_t>(tris.corner[i][q])]
                                        : image_of(q == 0 ? tris.a[i] : q == 1 ? tris.b[i] : tris.c[i]);
      if (std::isnan(x.x())) near = true;
      image.extend(x);
    }
    if (near) continue;  // clipped by the rasteriser: not worth the care
    const Eigen::Vector3d n_c = c_T_w.linear() * tris.normal_w[i];
    const double o_c = tris.offset[i] - tris.normal_w[i].dot(C);  // n_c . X = o_c
    Eigen::AlignedBox2d seen;
    bool sure = true;
    for (int corner = 0; corner < 4 && sure; ++corner) {
      const double u = corner & 1 ? image.max().x() + 1 : image.min().x() - 1;
      const double v = corner & 2 ? image.max().y() + 1 : image.min().y() - 1;
      const Eigen::Vector3d ray((u - k.cx) * inv_fx, (v - k.cy) * inv_fy, 1.0);
      const double facing = n_c.dot(ray), t = o_c / facing;
      const Eigen::Vector3d x = p_T_c * (t * ray);
      sure = facing * facing >= kGrazing * kGrazing * ray.squaredNorm() && t > 0 && x.z() > 1e-3;
      const double inv_z = 1.0 / x.z();
      seen.extend(Eigen::Vector2d(kp.fx * x.x() * inv_z + kp.cx, kp.fy * x.y() * inv_z + kp.cy));
    }
    out[i] = sure && gap_beyond(seen, window) > kClear;
  }
}

// The kernel of the widest vector unit the scratch allows and the CPU has.
auto shading_kernel(const RenderScratch& s) {
  const VectorUnit unit = vector_unit(s.scalar, s.avx512);
  return unit == VectorUnit::kAvx512 ? shading::shade_rows_avx512
         : unit == VectorUnit::kAvx2 ? shading::shade_rows_avx2
                                     : shading::shade_rows_scalar;
}

// The frame's projector (defocus, spot grid, colours seen through the sensor's crosstalk, the
// camera-to-projector pose) and sensor numbers (gain, noise). `colour` holds the colour
// tables the frame points to.
void projector_and_sensor(const Cell& cell, const Light& light, const CameraSpec& cam,
                          const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                          std::array<float, shading::kSymbolLut> (&colour)[3], shading::Frame& f) {
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const Projector& proj = *light.projector;
  const ProjectorSpec& ps = proj.spec();
  f.focused_blur = static_cast<float>(ps.focused_blur_px);
  f.defocus_per_m = static_cast<float>(ps.defocus_px_per_m);
  f.focus_near = static_cast<float>(ps.focus_near_m);
  f.focus_far = static_cast<float>(ps.focus_far_m);
  f.pixel_scale = static_cast<float>(ps.intrinsics.fx / k.fx);
  f.radius = static_cast<float>(ps.spot_radius_px);
  const pattern::MArray& pat = proj.pattern();
  const Eigen::Vector2d origin = proj.spot_pixel(0, 0);
  f.grid_x0 = static_cast<float>(origin.x());
  f.grid_y0 = static_cast<float>(origin.y());
  f.pitch = static_cast<float>(ps.spot_pitch_px);
  f.inv_pitch = static_cast<float>(1.0 / ps.spot_pitch_px);
  f.rows = pat.rows;
  f.cols = pat.cols;
  f.spot_symbol = cell.spot_symbol.data();
  for (int i = 0; i < 10; ++i) {
    const pattern::Rgb c = pattern::symbol_colour(i);
    const Eigen::Vector3f raw(c.r / 255.f, c.g / 255.f, c.b / 255.f);
    const float x = static_cast<float>(cam.crosstalk);
    // the sensor's channel crosstalk
    const Eigen::Vector3f seen = (1 - 2 * x) * raw + x * Eigen::Vector3f(raw.y() + raw.z(), raw.x() + raw.z(), raw.x() + raw.y());
    for (int ch = 0; ch < 3; ++ch) colour[ch][static_cast<std::size_t>(i)] = seen[ch];
  }
  f.colour_r = colour[0].data();
  f.colour_g = colour[1].data();
  f.colour_b = colour[2].data();
  for (int j = 0; j < 4; ++j) f.edge[j] = edge_profile().c[j].data();
  // the camera-to-projector pose, the projector's intrinsics folded in: u_p = h_0 / h_2, ...
  const Eigen::Isometry3d p_T_c = proj.projector_T_world() * world_T_camera;
  Eigen::Matrix<double, 3, 4> m;
  m << p_T_c.linear(), p_T_c.translation();
  const Intrinsics& kp = ps.intrinsics;
  const Eigen::Matrix<double, 3, 4> km =
      (Eigen::Matrix3d() << kp.fx, 0, kp.cx, 0, kp.fy, kp.cy, 0, 0, 1).finished() * m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) f.m[r][c] = static_cast<float>(km(r, c));
  const Eigen::Vector3d q = world_T_camera.inverse() * ps.world_T_projector.translation();
  f.qx = static_cast<float>(q.x());
  f.qy = static_cast<float>(q.y());
  f.qz = static_cast<float>(q.z());
  f.gain = static_cast<float>(255.0 * cam.exposure);
  f.read_var = static_cast<float>(cam.noise_sigma * cam.noise_sigma);
  f.shot = static_cast<float>(cam.shot_noise);
  f.noisy = cam.noise_sigma > 0 || cam.shot_noise > 0;
  f.noise_pool = cell.noise_pool.data();
  f.noise_span = static_cast<std::uint32_t>(cell.noise_pool.size() - shading::kNoiseChunk + 1);
  f.noise_seed = noise_seed;
}

// Each band's z-buffer rows (the rows its image rows look up) and, in s.band_screen, the
// polygons that meet them in order: a band's fill then visits its own, not every polygon of the
// frame.
std::vector<std::pair<int, int>> polygons_by_band(const Cell::Lens& lens, int height, int band_height, int bands,
                                                  RenderScratch& s) {
  std::vector<std::pair<int, int>> band_rows(static_cast<std::size_t>(bands));
  s.band_screen.resize(static_cast<std::size_t>(bands));
  for (int b = 0; b < bands; ++b) {
    const int v0 = b * band_height, v1 = std::min(height, v0 + band_height);
    band_rows[static_cast<std::size_t>(b)] = {*std::min_element(lens.zrow_lo.begin() + v0, lens.zrow_lo.begin() + v1),
                                              *std::max_element(lens.zrow_hi.begin() + v0, lens.zrow_hi.begin() + v1)};
    s.band_screen[static_cast<std::size_t>(b)].clear();
  }
  // bands whose rows rise with the band (any lens that keeps the image's rows in order): from
  // the first band reaching a polygon's top row to the last its bottom row reaches; else all
  bool rising = true;
  for (int b = 1; b < bands; ++b)
    rising = rising && band_rows[static_cast<std::size_t>(b)].first >= band_rows[static_cast<std::size_t>(b - 1)].first &&
             band_rows[static_cast<std::size_t>(b)].second >= band_rows[static_cast<std::size_t>(b - 1)].second;
  for (std::size_t i = 0; i < s.screen.size(); ++i) {
    const ScreenTriangle& t = s.screen[i];
    int b = 0;
    if (rising)
      b = static_cast<int>(std::partition_point(band_rows.begin(), band_rows.end(),
                                                [&](const std::pair<int, int>& r) { return r.second < t.y0; }) -
                           band_rows.begin());
    for (; b < bands; ++b) {
      const auto [z0, z1] = band_rows[static_cast<std::size_t>(b)];
      if (rising && z0 > t.y1) break;
      if (t.y1 >= z0 && t.y0 <= z1) s.band_screen[static_cast<std::size_t>(b)].push_back(static_cast<std::int32_t>(i));
    }
  }
  return band_rows;
}

namespace {

// The frame's lens (its rays and z-buffer cells), its triangles' numbers, and the projector's
// depth over the beam window (the arm's too, when it is in the beam).
void lens_and_light(const Cell& cell, const Light& light, const FrameScene& scene, RenderScratch& s, shading::Frame& f) {
  const Cell::Lens& lens = cell.lens;
  f.width = cell.scenario.camera.intrinsics.width;
  f.height = cell.scenario.camera.intrinsics.height;
  f.stride = lens.stride;
  f.zcell = lens.zcell.data();
  f.zrun = lens.zrun.data();
  f.ray_x = lens.ray_x.data();
  f.ray_y = lens.ray_y.data();
  f.triangles = s.triangles.data();
  f.projector_depth = beam_view(light, light.beam_depth);
  if (scene.arm_projector_depth) {
    // the arm's depth over the same window: one cell index serves both
    s.arm_beam_depth = beam_window(*scene.arm_projector_depth, light.beam);
    f.arm_depth = beam_view(light, s.arm_beam_depth);
  }
}

}  // namespace

cv::Mat render_image(const Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     RenderScratch* scratch, const CameraSpec* sensor, const LinkPoses* links, Cast cast) {
  const CameraSpec& cam = sensor ? *sensor : cell.scenario.camera;
  const Intrinsics& k = cell.scenario.camera.intrinsics;  // the lens is the cell's, whatever the sensor

  RenderScratch local;
  RenderScratch& s = scratch ? *scratch : local;
  s.arm.scalar = s.scalar;
  const Light& light = light_at(cell, world_T_camera, s.light, true);
  const FrameScene scene = pose_scene(cell, light, links, s.arm, true, false);
  const SceneTriangles& tris = *scene.triangles;
  s.screen.clear();
  // the z-buffer names each pixel's plane (SceneTriangles::plane_of): a row of pixels crosses
  // fewer of them than of triangles, and the kernel handles each distinct one in turn; a
  // triangle outside the beam names its plane's copy after the n triangles, which holds the
  // ambient light alone
  const auto n_tris = static_cast<std::int32_t>(tris.normal_w.size());
  if (s.skip_outside_beam) outside_beam(cell, light, world_T_camera, s.outside);
  project_triangles(tris, 0, world_T_camera.inverse(), k, cell.camera_margin_px, true, s.screen, true,
                    s.skip_outside_beam ? &s.outside : nullptr, n_tris);
  prepare_triangles(light, tris, world_T_camera, cam, s.skip_unshadowed, s.triangles);

  const Cell::Lens& lens = cell.lens;
  shading::Frame f;
  lens_and_light(cell, light, scene, s, f);
  surface_colours(cell, tris, world_T_camera, s, f);
  f.triangle_count = 2 * tris.normal_w.size();
  f.outside_from = n_tris;
  std::array<float, shading::kSymbolLut> colour[3]{};
  projector_and_sensor(cell, light, cam, world_T_camera, noise_seed, colour, f);
  f.white = cast == Cast::kWhite;

  const auto shade = shading_kernel(s);
  // Band by band: the z-buffer rows a band of image rows looks up are filled, then shaded
  // while they are in the cache (a whole frame's z-buffer is 2.6 MB; a band's 0.2-0.75 MB). A band
  // of the z-buffer holds what the whole one would, and a row's bytes depend only on the frame
  // and the row (its noise on the seed and the row): the image does not depend on the bands or
  // on how they are shared out over threads.
  cv::Mat image(k.height, k.width, CV_8UC3);
  const int workers = s.threads == 1 ? 1 : std::max(1, cv::getNumThreads());
  const int band_height = workers == 1 ? kBandRowsOneThread : kBandRowsShared;
  const int bands = (k.height + band_height - 1) / band_height;
  const std::vector<std::pair<int, int>> band_rows = polygons_by_band(lens, k.height, band_height, bands, s);
  const auto shade_bands = [&](const cv::Range& range) {
    // each thread's own band buffers, kept from frame to frame (no allocation per frame)
    thread_local DepthBuffer depth;
    thread_local std::vector<float> rows;
    rows.resize(static_cast<std::size_t>(shading::kRowArrays) * f.stride);
    for (int b = range.start; b < range.end; ++b) {
      const int v0 = b * band_height, v1 = std::min(k.height, v0 + band_height);
      const auto [z0, z1] = band_rows[static_cast<std::size_t>(b)];
      shading::Frame band = f;
      if (z0 <= z1) {
        clear_band(k, cell.camera_margin_px, z0, z1 - z0 + 1, depth);
        fill_triangles(s.screen, s.band_screen[static_cast<std::size_t>(b)], depth,
                       RasterClip{0, z0, std::numeric_limits<int>::max(), z1}, !s.scalar, s.avx512);
        band.cell_triangle = depth.triangle.data();
        band.cells = depth.triangle.size();
        band.cell_base = static_cast<std::int64_t>(depth.row0) * depth.width;
      }
      shade(band, v0, v1, image.data, image.step, rows.data());
    }
  };
  if (s.threads == 1)
    shade_bands(cv::Range(0, bands));
  else
    cv::parallel_for_(cv::Range(0, bands), shade_bands, workers);
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
  Light own;
  const Light& light = light_at(cell, world_T_camera, own, false);
  const FrameScene scene = pose_scene(cell, light, links, buffers, false, true);
  const bool arm = links && !links->empty() && cell.arm_meshes.size() > 0;
  const int first_arm_object = static_cast<int>(cell.object_names.size());
  const pattern::MArray& pat = cell.projector->pattern();
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  const Eigen::Vector3d C = world_T_camera.translation();
  const Eigen::Isometry3d p_T_w = light.projector->projector_T_world();
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
    t.blur_px = light.projector->defocus_sigma_px((p_T_w * t.point_w).z());
    t.resolved = spot_resolved(t.blur_px, light.projector->spec());
    for (const auto& rim : h.rim)
      if (rim && rim->object == h.centre->object) {
        const Eigen::Vector3d R_c = c_T_w * rim->point_w;
        if (R_c.z() > 1e-3) t.footprint_px.push_back(cell.camera->project(R_c));
      }
  }
  return truth;
}

}  // namespace sim
