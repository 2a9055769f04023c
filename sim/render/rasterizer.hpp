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
  // +1: a face of a closed mesh whose normals point out of it, -1: into it; 0: of an open
  // mesh. A closed mesh's faces turned away from a viewer outside it are hidden by its own
  // faces turned towards it: rasterize() leaves them out where asked.
  std::vector<std::int8_t> outward;
  // the first of a run of triangles of one mesh, each sharing an edge with the one before and
  // lying in its plane (a quad's two halves, a flat wall's tiles): the same surface to shade
  std::vector<std::int32_t> plane_of;
  // the vertices (world frame) and each triangle's three: a = vertex_w[corner[i][0]], b, c the
  // next two (a vertex that triangles share is projected once a frame)
  std::vector<Eigen::Vector3d> vertex_w;
  std::vector<std::array<std::int32_t, 3>> corner;
  // where triangle i and the next one are a flat quad's halves (one plane, two vertices in
  // common): the next one's vertex that is not i's (0-2) and i's edge they share (from its
  // vertex e to e + 1); -1 otherwise
  std::vector<std::int8_t> quad_extra, quad_edge;
  // Textured triangles (World::Object::texture): 1 where triangle i is, and the affine map from
  // a world point x to its texture coordinates, (u, v) = uv_map[i] (x, 1). Sized up to the last
  // textured mesh's triangles (empty when none is): a triangle beyond is untextured.
  std::vector<std::uint8_t> textured;
  std::vector<Eigen::Matrix<double, 2, 4>> uv_map;
};

// Where a point `p` of a viewer's frame lands on its image through the ideal pinhole `k` (pixels).
inline Eigen::Vector2d pinhole_pixel(const Intrinsics& k, const Eigen::Vector3d& p) {
  return {k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy};
}

// Whether triangle i is a face of a closed mesh turned away from a viewer at `viewer` (world):
// hidden by the mesh's own faces turned towards it, left out where culling is asked.
inline bool faces_away(const SceneTriangles& tris, std::size_t i, const Eigen::Vector3d& viewer) {
  return tris.outward[i] != 0 && tris.outward[i] * tris.normal_w[i].dot(viewer - tris.a[i]) < 0;
}

// +1 when the mesh is closed (every edge shared by exactly two faces, in opposite directions)
// with normals pointing out of it, -1 closed with normals pointing in, 0 open.
int closed_orientation(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& triangles);

SceneTriangles collect_triangles(const World& world);

struct DepthBuffer {
  int width = 0, height = 0;
  // pixel (i, j) of the buffer is pixel (i - margin, j - margin) of the pinhole image, so a
  // distorted lens that sees beyond the ideal frame still finds its surfaces
  int margin = 0;
  // the rows held: [row0, row0 + rows) (a band of the image, see fill_triangles); a whole
  // buffer has row0 = 0 and rows = height
  int row0 = 0, rows = 0;
  std::vector<float> inv_depth;       // 1/z in the viewer's frame (affine on screen); 0 where nothing
  std::vector<std::int32_t> triangle; // index into SceneTriangles; -1 where nothing

  // Nearest pixel. Runs per pixel: truncation of a shifted value is floor() for anything
  // above -kShift, where std::floor and std::lround are libm calls on baseline x86-64.
  // (Camera pixels look their cell up in Cell::Lens::zcell, computed once per lens.)
  static constexpr double kShift = 1 << 20;
  static int nearest(double x) {
    // beyond +-1e9 (or NaN) no pixel is meant; the cast of such a value is undefined behaviour
    if (!(x > -1e9 && x < 1e9)) return -(1 << 30);
    return static_cast<int>(x + 0.5 + kShift) - static_cast<int>(kShift);
  }
  float depth_at(double u, double v) const {
    const int i = nearest(u) + margin;
    const int j = nearest(v) + margin - row0;
    if (i < 0 || j < 0 || i >= width || j >= rows) return std::numeric_limits<float>::infinity();
    const float q = inv_depth[static_cast<std::size_t>(j) * width + i];
    return q > 0 ? 1.0f / q : std::numeric_limits<float>::infinity();
  }
};

// Rasterises every triangle (both faces) seen from viewer_T_world through `k`.
// Triangles crossing the near plane are clipped. `vector`: four rows' spans at a time where
// the CPU has AVX2 (their depth tests sixteen pixels at a time where it has AVX-512 and
// `avx512` allows it); false: one at a time (the same buffer, bit for bit; tests hold the
// three to each other).
// `cull`: faces of closed meshes turned away from the viewer are left out (the same buffer,
// the viewer being outside every closed mesh, but for exact ties at silhouettes).
// project_triangles' `by_plane`: each triangle fills its SceneTriangles::plane_of id, and two
// consecutive triangles of one plane that share an edge and make a convex quad on screen are
// filled as that quad (half the spans for a tessellated surface's strips).
void rasterize(const SceneTriangles& tris, const Eigen::Isometry3d& viewer_T_world, const Intrinsics& k, int margin,
               DepthBuffer& out, bool vector = true, bool avx512 = true, bool cull = false);
// Buffer pixels a rasterisation may write (inclusive).
struct RasterClip {
  int x0 = 0, y0 = 0, x1 = std::numeric_limits<int>::max(), y1 = std::numeric_limits<int>::max();
};

// w(x, y) = a x + b y + c over a buffer's pixels: barycentric weights and 1/z are affine there
struct Affine {
  double a, b, c;
  double at(double x, double y) const { return a * x + b * y + c; }
};

// A triangle on a viewer's image plane (pixels, without the margin), ready to fill; or a flat
// convex quad, two triangles of one plane sharing an edge (n = 4). Its edges and 1/z are
// solved once (project_triangles), however many bands of a buffer it is then filled into.
struct ScreenTriangle {
  double u[4], v[4], inv_z[4];
  int n;            // vertices: 3 or 4
  std::int32_t id;  // index into SceneTriangles (by_plane: its plane_of)
  int y0, y1;       // the buffer rows it may cover
  int x0, x1;       // the buffer columns it may cover; x0 > x1: nothing (no area)
  Affine edge[4];   // inside: every edge's w >= 0 (n of them), buffer coordinates
  Affine iz;        // 1/z, from the plane of its first three vertices
};
// Triangles [first, end) seen from viewer_T_world through `k`, clipped against the near plane
// (a triangle crossing it becomes one or two); `cull` as in rasterize. Appended to `out`.
// `moved`: triangle i (i < moved->size()) flagged there fills its id plus `moved_by` (the
// renderer's triangles outside the beam this frame, whose numbers it keeps apart).
void project_triangles(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                       const Intrinsics& k, int margin, bool cull, std::vector<ScreenTriangle>& out,
                       bool by_plane = false, const std::vector<std::uint8_t>* moved = nullptr,
                       std::int32_t moved_by = 0);
// Fills `out` (its rows [row0, row0 + rows) only, and `clip`) with the triangles, in order. A
// buffer filled band by band holds, bit for bit, what one fill of the whole holds.
void fill_triangles(const std::vector<ScreenTriangle>& tris, DepthBuffer& out, const RasterClip& clip,
                    bool vector = true, bool avx512 = true);
// The same for the triangles tris[i], i in `which` (ascending: the order of the fill).
void fill_triangles(const std::vector<ScreenTriangle>& tris, const std::vector<std::int32_t>& which, DepthBuffer& out,
                    const RasterClip& clip, bool vector = true, bool avx512 = true);
// ScreenTriangle's edges, 1/z and box for its vertices u, v, inv_z and n, in a buffer with
// `margin` (project_triangles calls it; a caller building its own calls it too).
void solve_edges(ScreenTriangle& t, int margin);
// Sizes `out` as the viewer's buffer (k's image with `margin` around it) holding rows
// [row0, row0 + rows) (clamped to it), cleared: nothing anywhere.
void clear_band(const Intrinsics& k, int margin, int row0, int rows, DepthBuffer& out);
// Adds triangles [first, end) to a buffer rasterised from the same viewpoint (the moving
// arm over the static scene's buffer), only inside `clip`.
void rasterize_more(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                    const Intrinsics& k, DepthBuffer& out, const RasterClip& clip = RasterClip{}, bool vector = true,
                    bool avx512 = true, bool cull = false);
// The cells of `d` inside `window` (inclusive), row by row: 1/z, 0 where nothing.
std::vector<float> beam_window(const DepthBuffer& d, const RasterClip& window);
// Appends a mesh placed at world_T_mesh, as object `object` with `albedo`; `corner_uv` and
// `textured` (TriangleMesh's), when given, map its textured triangles.
void append_triangles(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& triangles,
                      const Eigen::Isometry3d& world_T_mesh, int object, float albedo, SceneTriangles& out,
                      int outward = 0, const std::vector<std::array<Eigen::Vector2d, 3>>* corner_uv = nullptr,
                      const std::vector<std::uint8_t>* textured = nullptr);

// The affine map from a point of triangle (a, b, c) to the texture coordinates that its
// corners' `uv` interpolate: (u, v) = M (x, 1), exact on the triangle's plane.
Eigen::Matrix<double, 2, 4> texture_map(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                        const std::array<Eigen::Vector2d, 3>& uv);

}  // namespace sim
