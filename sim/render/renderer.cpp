#include "sim/render/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/core/utility.hpp>

#include "servo/pattern/palette.hpp"

namespace sim {
namespace {

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// 0.5 erfc(x / sqrt 2): the fraction of a Gaussian-blurred edge's light at signed distance x
// (in sigmas) outside it. Tabulated: std::erfc costs ~30 ns and runs once per lit pixel.
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

 private:
  static constexpr int kN = 2049;
  static constexpr double kLo = -6.0, kStep = 12.0 / (kN - 1);
  std::array<float, kN> table_{};
};

const EdgeProfile& edge_profile() {
  static const EdgeProfile profile;  // immutable table, built once
  return profile;
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
  rasterize_more(triangles, first, p_T_w, kp, d, clip);
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

cv::Mat render_image(const Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     RenderScratch* scratch, const CameraSpec* sensor, const LinkPoses* links) {
  const CameraSpec& cam = sensor ? *sensor : cell.scenario.camera;
  const Intrinsics& k = cell.scenario.camera.intrinsics;  // the lens is the cell's, whatever the sensor
  const Projector& proj = *cell.projector;
  const ProjectorSpec& ps = proj.spec();
  const Intrinsics& kp = ps.intrinsics;
  const EdgeProfile& edge = edge_profile();

  RenderScratch local;
  RenderScratch& s = scratch ? *scratch : local;
  const FrameScene scene = pose_scene(cell, links, s.arm, true);
  const SceneTriangles& tris = *scene.triangles;
  const std::vector<SpotHit>& hits = *scene.spot_hits;
  const DepthBuffer& projector_depth = *scene.projector_depth;
  const DepthBuffer* arm_depth = scene.arm_projector_depth;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  rasterize(tris, c_T_w, k, cell.camera_margin_px, s.camera_depth);
  spot_boxes(cell, hits, c_T_w, s.boxes);

  // spot colours after the sensor's channel crosstalk, per pattern symbol
  std::array<Eigen::Vector3f, 10> spot_rgb;
  for (int i = 0; i < 10; ++i) {
    const pattern::Rgb c = pattern::symbol_colour(i);
    const Eigen::Vector3f raw(c.r / 255.f, c.g / 255.f, c.b / 255.f);
    const float x = static_cast<float>(cam.crosstalk);
    spot_rgb[i] = (1 - 2 * x) * raw + x * Eigen::Vector3f(raw.y() + raw.z(), raw.x() + raw.z(), raw.x() + raw.y());
  }

  const Eigen::Matrix3d R = world_T_camera.linear();
  const Eigen::Vector3d C = world_T_camera.translation();
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  const Eigen::Vector3d P = ps.world_T_projector.translation();
  const double radius = ps.spot_radius_px;
  const double focus_mid = 0.5 * (ps.focus_near_m + ps.focus_far_m);
  const float* rays = cell.camera->pixel_rays().data();
  // triangle planes in the camera frame, and the camera -> projector motion, once per frame
  s.normal_c.resize(tris.normal_w.size());
  s.offset_c.resize(tris.normal_w.size());
  for (std::size_t i = 0; i < tris.normal_w.size(); ++i) {
    s.normal_c[i] = R.transpose() * tris.normal_w[i];
    s.offset_c[i] = tris.offset[i] - tris.normal_w[i].dot(C);
  }
  const Eigen::Isometry3d p_T_c = p_T_w * world_T_camera;
  const Eigen::Matrix3d p_R_c = p_T_c.linear();
  const Eigen::Vector3d p_t_c = p_T_c.translation();
  const std::size_t npx = static_cast<std::size_t>(k.width) * k.height;
  const double proj_per_cam_px = kp.fx / k.fx;  // a camera pixel at depth z seen from the projector at z_p
  s.radiance.resize(npx * 3);  // every value is written by the ambient pass below

  // Row bands run in parallel; every pixel is written by the band that owns its row, and
  // the noise of a row depends only on the seed and the row, so the image does not depend
  // on how the rows are split.
  cv::parallel_for_(cv::Range(0, k.height), [&](const cv::Range& band) {
    // ambient light on whatever surface each pixel sees
    for (int v = band.start; v < band.end; ++v) {
      float* out = &s.radiance[static_cast<std::size_t>(v) * k.width * 3];
      const std::int32_t* zi = &cell.pixel_to_zbuffer[static_cast<std::size_t>(v) * k.width];
      for (int u = 0; u < k.width; ++u) {
        const std::int32_t t = zi[u] >= 0 ? s.camera_depth.triangle[static_cast<std::size_t>(zi[u])] : -1;
        out[3 * u] = out[3 * u + 1] = out[3 * u + 2] = t >= 0 ? static_cast<float>(cam.ambient) * tris.albedo[t] : 0.f;
      }
    }
    // each spot's light, inside its box
    for (const SpotBox& box : s.boxes) {
      const int v0 = std::max(box.v0, band.start), v1 = std::min(box.v1, band.end - 1);
      if (v0 > v1) continue;
      const SpotHit& hit = hits[box.spot];
      const Eigen::Vector2d centre = proj.spot_pixel(hit.row, hit.col);
      const Eigen::Vector3f& colour = spot_rgb[hit.symbol];
      const double reach_max2 = box.reach_px * box.reach_px;
      for (int v = v0; v <= v1; ++v)
        for (int u = box.u0; u <= box.u1; ++u) {
          const std::size_t px = static_cast<std::size_t>(v) * k.width + u;
          const std::int32_t zi = cell.pixel_to_zbuffer[px];
          const std::int32_t t = zi >= 0 ? s.camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
          if (t < 0) continue;
          const Eigen::Vector3d d_c(rays[2 * px], rays[2 * px + 1], 1.0);
          // exact intersection of this pixel's ray with the triangle's plane (camera frame)
          const double denom = s.normal_c[t].dot(d_c);
          if (std::abs(denom) < 1e-12) continue;
          const double z_c = s.offset_c[t] / denom;
          if (z_c <= 0) continue;
          const Eigen::Vector3d X_p = z_c * (p_R_c * d_c) + p_t_c;
          if (X_p.z() <= 1e-3) continue;
          const double inv_z = 1.0 / X_p.z();
          const double du = kp.fx * X_p.x() * inv_z + kp.cx - centre.x();
          const double dv = kp.fy * X_p.y() * inv_z + kp.cy - centre.y();
          const double rho2 = du * du + dv * dv;
          if (rho2 > reach_max2) continue;  // most of the box: between spots
          const double blur = proj.defocus_sigma_px(X_p.z());
          const double pixel_in_proj = z_c * proj_per_cam_px * inv_z;
          const double sigma = std::sqrt(blur * blur + 0.083 * pixel_in_proj * pixel_in_proj) + 1e-6;
          const double reach = radius + 3.0 * sigma;  // 0.5 erfc(3 / sqrt 2) = 0.1 %: nothing beyond
          if (rho2 > reach * reach) continue;
          // lit when the projector's nearest surface along this direction is this one
          float nearest = projector_depth.depth_at(du + centre.x(), dv + centre.y());
          if (arm_depth) nearest = std::min(nearest, arm_depth->depth_at(du + centre.x(), dv + centre.y()));
          if (X_p.z() > nearest * (1.0 + 2e-3) + 2e-3) continue;
          const Eigen::Vector3d X = C + z_c * (R * d_c);
          const Eigen::Vector3d L = P - X;
          const double dist2 = L.squaredNorm();
          const double cos_in = std::abs(tris.normal_w[t].dot(L)) / std::sqrt(dist2);
          const double falloff = (focus_mid * focus_mid) / dist2;
          const float e = edge((std::sqrt(rho2) - radius) / sigma) *
                          static_cast<float>(tris.albedo[t] * ps.brightness * cos_in * falloff);
          float* out = &s.radiance[3 * px];
          out[0] += e * colour[0];
          out[1] += e * colour[1];
          out[2] += e * colour[2];
        }
    }
  });

  // the sensor: exposure, read + shot noise, 8-bit quantisation
  const float gain = static_cast<float>(255.0 * cam.exposure);
  const bool noisy = cam.noise_sigma > 0 || cam.shot_noise > 0;
  const float read_var = static_cast<float>(cam.noise_sigma * cam.noise_sigma);
  const float shot = static_cast<float>(cam.shot_noise);
  const float* pool = cell.noise_pool.data();
  const std::size_t row_len = static_cast<std::size_t>(k.width) * 3;
  const std::size_t pool_span = cell.noise_pool.size() > row_len ? cell.noise_pool.size() - row_len : 1;
  cv::Mat image(k.height, k.width, CV_8UC3);
  cv::parallel_for_(cv::Range(0, k.height), [&](const cv::Range& band) {
    for (int v = band.start; v < band.end; ++v) {
      // a contiguous run of the pool at a seeded offset: the loop below vectorises
      std::uint64_t state = noise_seed ^ (0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(v + 1));
      const float* __restrict noise = pool + splitmix64(state) % pool_span;
      const float* __restrict in = &s.radiance[static_cast<std::size_t>(v) * row_len];
      std::uint8_t* __restrict row = image.ptr<std::uint8_t>(v);
      const std::size_t n = row_len;  // a local count: the loop vectorises only when it cannot alias
      const float g = gain, rv = read_var, sh = shot;
      if (noisy) {
        for (std::size_t i = 0; i < n; ++i) {
          const float value = g * in[i];
          const float noisy_value = value + std::sqrt(rv + sh * std::max(value, 0.f)) * noise[i];
          row[i] = static_cast<std::uint8_t>(std::min(std::max(noisy_value + 0.5f, 0.f), 255.f));
        }
      } else {
        for (std::size_t i = 0; i < n; ++i)
          row[i] = static_cast<std::uint8_t>(std::min(std::max(g * in[i] + 0.5f, 0.f), 255.f));
      }
    }
  });
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
