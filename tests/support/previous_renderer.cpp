#include "support/previous_renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <random>

#include "servo/pattern/palette.hpp"

namespace previous {
namespace {

using namespace sim;

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// 0.5 erfc(x / sqrt 2), tabulated
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
  static constexpr int kN = 2049;
  static constexpr double kLo = -6.0, kStep = 12.0 / (kN - 1);

 private:
  std::array<float, kN> table_{};
};

float edge_fraction(double x) {
  static const EdgeProfile profile;
  return profile(x);
}

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

// the 8 MB pool of unit Gaussian samples the renderer then drew its noise from
const std::vector<float>& noise_pool(std::uint64_t seed) {
  static std::mutex mutex;
  static std::map<std::uint64_t, std::vector<float>> pools;
  const std::lock_guard<std::mutex> lock(mutex);
  std::vector<float>& pool = pools[seed];
  if (pool.empty()) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<float> gauss(0.f, 1.f);
    pool.resize(std::size_t{1} << 21);
    for (float& x : pool) x = gauss(rng);
  }
  return pool;
}

struct Sensor {
  Sensor(const Cell& cell, const CameraSpec& cam, std::uint64_t noise_seed)
      : gain(static_cast<float>(255.0 * cam.exposure)),
        read_var(static_cast<float>(cam.noise_sigma * cam.noise_sigma)),
        shot(static_cast<float>(cam.shot_noise)),
        noisy(cam.noise_sigma > 0 || cam.shot_noise > 0),
        pool(noise_pool(cell.scenario.seed).data()),
        seed(noise_seed) {
    const std::size_t row_len = static_cast<std::size_t>(cell.scenario.camera.intrinsics.width) * 3;
    const std::size_t size = std::size_t{1} << 21;
    pool_span = size > row_len ? size - row_len : 1;
  }
  const float* row_noise(int v) const {
    std::uint64_t state = seed ^ (0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(v + 1));
    return pool + splitmix64(state) % pool_span;
  }
  float gain, read_var, shot;
  bool noisy;
  const float* pool;
  std::size_t pool_span = 1;
  std::uint64_t seed;
};

// The image region (inclusive pixel bounds) one spot can light on one object.
struct SpotBox {
  int spot = 0;
  double reach_px = 0;
  int u0 = 0, v0 = 0, u1 = -1, v1 = -1;
};

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

}  // namespace

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
  std::vector<SpotBox> boxes;
  const FrameScene scene = pose_scene(cell, cell.light, links, s.arm, true, true);
  const SceneTriangles& tris = *scene.triangles;
  const std::vector<SpotHit>& hits = *scene.spot_hits;
  const DepthBuffer& projector_depth = *scene.projector_depth;
  const DepthBuffer* arm_depth = scene.arm_projector_depth;
  const Eigen::Isometry3d c_T_w = world_T_camera.inverse();
  DepthBuffer camera_depth;
  rasterize(tris, c_T_w, k, cell.camera_margin_px, camera_depth, false);
  spot_boxes(cell, hits, c_T_w, boxes);
  const std::array<Eigen::Vector3f, 10> spot_rgb = spot_colours(cam);

  const Eigen::Matrix3d R = world_T_camera.linear();
  const Eigen::Vector3d C = world_T_camera.translation();
  const Eigen::Isometry3d p_T_w = proj.projector_T_world();
  const Eigen::Vector3d P = ps.world_T_projector.translation();
  const double radius = ps.spot_radius_px;
  const double focus_mid = 0.5 * (ps.focus_near_m + ps.focus_far_m);
  const float* rays = cell.camera->pixel_rays().data();
  std::vector<Eigen::Vector3d> normal_c(tris.normal_w.size());
  std::vector<double> offset_c(tris.normal_w.size());
  for (std::size_t i = 0; i < tris.normal_w.size(); ++i) {
    normal_c[i] = R.transpose() * tris.normal_w[i];
    offset_c[i] = tris.offset[i] - tris.normal_w[i].dot(C);
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
    const std::int32_t t = zi >= 0 ? camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
    float* out = &radiance[3 * px];
    out[0] = out[1] = out[2] = t >= 0 ? static_cast<float>(cam.ambient) * tris.albedo[t] : 0.f;
  }
  // each spot's light, every pixel of its box computed from the pixel's ray
  for (const SpotBox& box : boxes) {
    const SpotHit& hit = hits[box.spot];
    const Eigen::Vector2d centre = proj.spot_pixel(hit.row, hit.col);
    const Eigen::Vector3f& colour = spot_rgb[hit.symbol];
    const double reach_max2 = box.reach_px * box.reach_px;
    for (int v = box.v0; v <= box.v1; ++v)
      for (int u = box.u0; u <= box.u1; ++u) {
        const std::size_t px = static_cast<std::size_t>(v) * k.width + u;
        const std::int32_t zi = cell.pixel_to_zbuffer[px];
        const std::int32_t t = zi >= 0 ? camera_depth.triangle[static_cast<std::size_t>(zi)] : -1;
        if (t < 0) continue;
        const Eigen::Vector3d d_c(rays[2 * px], rays[2 * px + 1], 1.0);
        const double denom = normal_c[t].dot(d_c);
        if (std::abs(denom) < 1e-12) continue;
        const double z_c = offset_c[t] / denom;
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
        const float e = edge_fraction((std::sqrt(rho2) - radius) / sigma) *
                        static_cast<float>(tris.albedo[t] * ps.brightness * cos_in * falloff);
        float* out = &radiance[3 * px];
        out[0] += e * colour[0];
        out[1] += e * colour[1];
        out[2] += e * colour[2];
      }
  }

  // the sensor
  const Sensor sensor_model(cell, cam, noise_seed);
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

}  // namespace previous
