// A z-buffer over the world's triangles seen through an ideal pinhole: for each pixel, the
// nearest triangle. The renderer uses it to find the surface behind each camera pixel and,
// from the projector, which surfaces the projector lights (its shadow map).
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "sim/scenario/scenario.hpp"
#include "sim/scene/world.hpp"

namespace sim {

// All triangles of the world in one flat array, with their planes, for fast per-pixel use.
struct SceneTriangles {
  std::vector<Eigen::Vector3d> a, b, c;  // vertices, world frame
  std::vector<Eigen::Vector3d> normal_w; // unit, counter-clockwise orientation
  std::vector<double> offset;            // plane: normal_w . x = offset
  std::vector<int> object;               // index into World::objects()
  std::vector<float> albedo;
};

SceneTriangles collect_triangles(const World& world);

struct DepthBuffer {
  int width = 0, height = 0;
  // pixel (i, j) of the buffer is pixel (i - margin, j - margin) of the pinhole image, so a
  // distorted lens that sees beyond the ideal frame still finds its surfaces
  int margin = 0;
  std::vector<float> inv_depth;       // 1/z in the viewer's frame (affine on screen); 0 where nothing
  std::vector<std::int32_t> triangle; // index into SceneTriangles; -1 where nothing

  // Nearest pixel. Runs per pixel: truncation of a shifted value is floor() for anything
  // above -kShift, where std::floor and std::lround are libm calls on baseline x86-64.
  // (Camera pixels look their cell up in Cell::pixel_to_zbuffer, computed once with it.)
  static constexpr double kShift = 1 << 20;
  static int nearest(double x) {
    // beyond +-1e9 (or NaN) no pixel is meant; the cast of such a value is undefined behaviour
    if (!(x > -1e9 && x < 1e9)) return -(1 << 30);
    return static_cast<int>(x + 0.5 + kShift) - static_cast<int>(kShift);
  }
  float depth_at(double u, double v) const {
    const int i = nearest(u) + margin;
    const int j = nearest(v) + margin;
    if (i < 0 || j < 0 || i >= width || j >= height) return std::numeric_limits<float>::infinity();
    const float q = inv_depth[static_cast<std::size_t>(j) * width + i];
    return q > 0 ? 1.0f / q : std::numeric_limits<float>::infinity();
  }
};

// Rasterises every triangle (both faces) seen from viewer_T_world through `k`.
// Triangles crossing the near plane are clipped. `vector`: four rows' spans at a time where
// the CPU has AVX2 (their depth tests sixteen pixels at a time where it has AVX-512 and
// `avx512` allows it); false: one at a time (the same buffer, bit for bit; tests hold the
// three to each other).
void rasterize(const SceneTriangles& tris, const Eigen::Isometry3d& viewer_T_world, const Intrinsics& k, int margin,
               DepthBuffer& out, bool vector = true, bool avx512 = true);
// Buffer pixels a rasterisation may write (inclusive).
struct RasterClip {
  int x0 = 0, y0 = 0, x1 = std::numeric_limits<int>::max(), y1 = std::numeric_limits<int>::max();
};
// Adds triangles [first, end) to a buffer rasterised from the same viewpoint (the moving
// arm over the static scene's buffer), only inside `clip`.
void rasterize_more(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                    const Intrinsics& k, DepthBuffer& out, const RasterClip& clip = RasterClip{}, bool vector = true,
                    bool avx512 = true);
// Appends a mesh placed at world_T_mesh, as object `object` with `albedo`.
void append_triangles(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& triangles,
                      const Eigen::Isometry3d& world_T_mesh, int object, float albedo, SceneTriangles& out);

}  // namespace sim
