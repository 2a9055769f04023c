#include "sim/render/texturing.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "sim/render/shading.hpp"

namespace sim {

TexturePool pool_textures(const World& world) {
  TexturePool pool;
  const auto& objects = world.objects();
  pool.first.assign(objects.size(), -1);
  for (std::size_t o = 0; o < objects.size(); ++o) {
    if (!objects[o].texture) continue;
    const std::vector<float>& rgb = objects[o].texture->rgb;
    if (pool.texels.size() + rgb.size() > kMaxSceneTexels)
      throw std::invalid_argument(objects[o].texture->file + ": the scene's textures hold more than " +
                                  std::to_string(kMaxSceneTexels / 3) + " pixels (the limit)");
    pool.first[o] = static_cast<std::int32_t>(pool.texels.size());
    pool.texels.insert(pool.texels.end(), rgb.begin(), rgb.end());
  }
  return pool;
}

bool prepare_texture(const World& world, const TexturePool& pool, const SceneTriangles& tris,
                     const Eigen::Isometry3d& world_T_camera, TextureFrame& out) {
  if (pool.texels.empty() || tris.textured.empty()) return false;
  const std::size_t n = tris.normal_w.size();
  const std::size_t stride = shading::triangle_stride(2 * n);
  out.map.assign(stride * shading::kTextureFields, 0.0f);
  out.texel.assign(stride * 3, -1);
  const Eigen::Matrix3d R = world_T_camera.linear();
  const Eigen::Vector3d C = world_T_camera.translation();
  const auto& objects = world.objects();
  // the z-buffer names a plane's first triangle (SceneTriangles::plane_of): only those are read;
  // a textured triangle is its plane's first unless its neighbour has the same map
  const bool by_plane = tris.plane_of.size() == n;
  for (std::size_t i = 0; i < tris.textured.size() && i < n; ++i) {
    if (!tris.textured[i] || (by_plane && tris.plane_of[i] != static_cast<std::int32_t>(i))) continue;
    const auto o = static_cast<std::size_t>(tris.object[i]);
    if (o >= objects.size() || pool.first[o] < 0) continue;
    const Eigen::Vector3d n_c = R.transpose() * tris.normal_w[i];
    const double o_c = tris.offset[i] - tris.normal_w[i].dot(C);
    if (!(std::abs(o_c) > 1e-9)) continue;  // seen edge-on: no point of it is drawn
    // 1/z = G . r for the pixel's ray r = (x, y, 1); the point z r; (u, v) = M (R z r + C, 1)
    const Eigen::Vector3d g = n_c / o_c;
    const Eigen::Matrix<double, 2, 4>& m = tris.uv_map[i];
    const Eigen::Matrix<double, 2, 3> a = m.leftCols<3>() * R;
    const Eigen::Vector2d k = m.leftCols<3>() * C + m.col(3);
    const float fields[shading::kTextureFields] = {
        static_cast<float>(g.x()),     static_cast<float>(g.y()),     static_cast<float>(g.z()),
        static_cast<float>(a(0, 0)),   static_cast<float>(a(0, 1)),   static_cast<float>(a(0, 2)),
        static_cast<float>(k.x()),     static_cast<float>(a(1, 0)),   static_cast<float>(a(1, 1)),
        static_cast<float>(a(1, 2)),   static_cast<float>(k.y())};
    const Texture& t = *objects[o].texture;
    for (std::size_t copy : {i, n + i}) {  // the plane's triangle and its copy outside the beam
      for (int f = 0; f < shading::kTextureFields; ++f) out.map[static_cast<std::size_t>(f) * stride + copy] = fields[f];
      out.texel[copy] = pool.first[o];
      out.texel[stride + copy] = t.width;
      out.texel[2 * stride + copy] = t.height;
    }
  }
  return true;
}

}  // namespace sim
