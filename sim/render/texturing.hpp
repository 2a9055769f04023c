// Textured surfaces for the shading kernel: the cell's textures in one pool of texels, and
// per frame each textured triangle's map from a pixel's ray to its texture coordinates.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "sim/render/rasterizer.hpp"
#include "sim/scene/world.hpp"

namespace sim {

// Every object texture's planes (Texture::rgb) one after another; first[o]: where object o's
// begin (-1: untextured). Throws std::invalid_argument when they hold more than kMaxSceneTexels.
inline constexpr std::size_t kMaxSceneTexels = std::size_t{3} << 24;  // 192 MB of floats
struct TexturePool {
  std::vector<float> texels;
  std::vector<std::int32_t> first;
};
TexturePool pool_textures(const World& world);

// One frame's textured triangles, in the layout of shading::Frame's texture fields.
struct TextureFrame {
  std::vector<float> map;           // kTextureFields x triangle_stride(2 n)
  std::vector<std::int32_t> texel;  // 3 x the same: first texel (-1: none), width, height
};
// For the camera at world_T_camera; false, and nothing written, when no triangle is textured
// (the kernel then reads nothing: an untextured scene's bytes are as before).
bool prepare_texture(const World& world, const TexturePool& pool, const SceneTriangles& tris,
                     const Eigen::Isometry3d& world_T_camera, TextureFrame& out);

}  // namespace sim
