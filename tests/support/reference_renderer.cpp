#include "support/reference_renderer.hpp"

#include <cmath>

#include "sim/render/render_parts.hpp"

namespace reference {

cv::Mat render_image(const sim::Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     const sim::CameraSpec* sensor, const sim::LinkPoses* links) {
  using namespace sim;
  const CameraSpec& cam = sensor ? *sensor : cell.scenario.camera;
  const Intrinsics& k = cell.scenario.camera.intrinsics;
  const Projector& proj = *cell.projector;
  const ProjectorSpec& ps = proj.spec();
  const Intrinsics& kp = ps.intrinsics;

  RenderScratch s;
  s.scalar = s.arm.scalar = true;
  const FrameScene scene = pose_scene(cell, links, s.arm, true);
  const SceneTriangles& tris = *scene.triangles;
  const std::vector<SpotHit>& hits = *scene.spot_hits;
  const DepthBuffer& projector_depth = *scene.projector_depth;
  const DepthBuffer* arm_depth = scene.arm_projector_depth;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  rasterize(tris, c_T_w, k, cell.camera_margin_px, s.camera_depth, false);
  render_parts::spot_boxes(cell, hits, c_T_w, s.boxes);
  const std::array<Eigen::Vector3f, 10> spot_rgb = render_parts::spot_colours(cam);

  const Eigen::Matrix3d R = world_T_camera.linear();
  const Eigen::Vector3d C = world_T_camera.translation();
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  const Eigen::Vector3d P = ps.world_T_projector.translation();
  const double radius = ps.spot_radius_px;
  const double focus_mid = 0.5 * (ps.focus_near_m + ps.focus_far_m);
  const float* rays = cell.camera->pixel_rays().data();
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
  const double proj_per_cam_px = kp.fx / k.fx;
  std::vector<float> radiance(npx * 3);  // linear RGB, 1 = full scale at exposure 1

  // ambient light on whatever surface each pixel sees
  for (std::size_t px = 0; px < npx; ++px) {
    const std::int32_t zi = cell.pixel_to_zbuffer[px];
    const std::int32_t t = zi >= 0 ? s.camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
    float* out = &radiance[3 * px];
    out[0] = out[1] = out[2] = t >= 0 ? static_cast<float>(cam.ambient) * tris.albedo[t] : 0.f;
  }
  // each spot's light, every pixel of its box computed from the pixel's ray
  for (const SpotBox& box : s.boxes) {
    const SpotHit& hit = hits[box.spot];
    const Eigen::Vector2d centre = proj.spot_pixel(hit.row, hit.col);
    const Eigen::Vector3f& colour = spot_rgb[hit.symbol];
    const double reach_max2 = box.reach_px * box.reach_px;
    for (int v = box.v0; v <= box.v1; ++v)
      for (int u = box.u0; u <= box.u1; ++u) {
        const std::size_t px = static_cast<std::size_t>(v) * k.width + u;
        const std::int32_t zi = cell.pixel_to_zbuffer[px];
        const std::int32_t t = zi >= 0 ? s.camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
        if (t < 0) continue;
        const Eigen::Vector3d d_c(rays[2 * px], rays[2 * px + 1], 1.0);
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
        if (rho2 > reach_max2) continue;
        const double blur = proj.defocus_sigma_px(X_p.z());
        const double pixel_in_proj = z_c * proj_per_cam_px * inv_z;
        const double sigma = std::sqrt(blur * blur + 0.083 * pixel_in_proj * pixel_in_proj) + 1e-6;
        const double reach = radius + 3.0 * sigma;
        if (rho2 > reach * reach) continue;
        float nearest = projector_depth.depth_at(du + centre.x(), dv + centre.y());
        if (arm_depth) nearest = std::min(nearest, arm_depth->depth_at(du + centre.x(), dv + centre.y()));
        if (X_p.z() > nearest * (1.0 + 2e-3) + 2e-3) continue;
        const Eigen::Vector3d X = C + z_c * (R * d_c);
        const Eigen::Vector3d L = P - X;
        const double dist2 = L.squaredNorm();
        const double cos_in = std::abs(tris.normal_w[t].dot(L)) / std::sqrt(dist2);
        const double falloff = (focus_mid * focus_mid) / dist2;
        const float e = render_parts::edge_fraction((std::sqrt(rho2) - radius) / sigma) *
                        static_cast<float>(tris.albedo[t] * ps.brightness * cos_in * falloff);
        float* out = &radiance[3 * px];
        out[0] += e * colour[0];
        out[1] += e * colour[1];
        out[2] += e * colour[2];
      }
  }

  // the sensor, written out here (the renderer's runs in the widest vector unit the CPU has)
  const render_parts::Sensor sensor_model(cell, cam, noise_seed);
  cv::Mat image(k.height, k.width, CV_8UC3);
  const std::size_t row_len = static_cast<std::size_t>(k.width) * 3;
  for (int v = 0; v < k.height; ++v) {
    const float* noise = sensor_model.row_noise(v);
    const float* in = &radiance[static_cast<std::size_t>(v) * row_len];
    std::uint8_t* row = image.ptr<std::uint8_t>(v);
    for (std::size_t i = 0; i < row_len; ++i) {
      const float value = sensor_model.gain * in[i];
      if (sensor_model.noisy) {
        const float noisy_value =
            value + std::sqrt(sensor_model.read_var + sensor_model.shot * std::max(value, 0.f)) * noise[i];
        row[i] = static_cast<std::uint8_t>(std::min(std::max(noisy_value + 0.5f, 0.f), 255.f));
      } else {
        row[i] = static_cast<std::uint8_t>(std::min(std::max(value + 0.5f, 0.f), 255.f));
      }
    }
  }
  return image;
}

}  // namespace reference
