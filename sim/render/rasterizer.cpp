#include "sim/render/rasterizer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sim {
namespace {

constexpr double kNear = 0.01;  // metres

struct ScreenVertex {
  double u, v, inv_z;
};

void fill_triangle(const ScreenVertex& p0, const ScreenVertex& p1, const ScreenVertex& p2, std::int32_t id,
                   DepthBuffer& out, const RasterClip& clip) {
  const double area = (p1.u - p0.u) * (p2.v - p0.v) - (p1.v - p0.v) * (p2.u - p0.u);
  if (std::abs(area) < 1e-12) return;
  const double m = out.margin;
  const int x0 = std::max(clip.x0, static_cast<int>(std::ceil(std::min({p0.u, p1.u, p2.u}) + m)));
  const int x1 = std::min({out.width - 1, clip.x1, static_cast<int>(std::floor(std::max({p0.u, p1.u, p2.u}) + m))});
  const int y0 = std::max(clip.y0, static_cast<int>(std::ceil(std::min({p0.v, p1.v, p2.v}) + m)));
  const int y1 = std::min({out.height - 1, clip.y1, static_cast<int>(std::floor(std::max({p0.v, p1.v, p2.v}) + m))});
  if (x0 > x1 || y0 > y1) return;
  // barycentric weights and 1/z are affine in screen space: w(x, y) = a x + b y + c
  const double inv_area = 1.0 / area;
  struct Affine {
    double a, b, c;
    double at(double x, double y) const { return a * x + b * y + c; }
  };
  const auto edge = [&](const ScreenVertex& s, const ScreenVertex& e) {
    // ((e.u - s.u) (y - s.v) - (e.v - s.v) (x - s.u)) / area, in buffer coordinates
    const double a = -(e.v - s.v) * inv_area, b = (e.u - s.u) * inv_area;
    return Affine{a, b, -(a * (s.u + m) + b * (s.v + m))};
  };
  const Affine w0 = edge(p1, p2), w1 = edge(p2, p0), w2 = edge(p0, p1);
  const Affine iz{w0.a * p0.inv_z + w1.a * p1.inv_z + w2.a * p2.inv_z,
                  w0.b * p0.inv_z + w1.b * p1.inv_z + w2.b * p2.inv_z,
                  w0.c * p0.inv_z + w1.c * p1.inv_z + w2.c * p2.inv_z};
  const Affine* edges[3] = {&w0, &w1, &w2};
  for (int y = y0; y <= y1; ++y) {
    // the span of this row inside all three edges, solved per edge (a x + b y + c >= 0), so
    // the loop below visits only covered pixels (thin triangles leave most of their box empty)
    double lo = x0, hi = x1;
    for (const Affine* e : edges) {
      const double c = e->b * y + e->c;
      if (e->a > 1e-15) lo = std::max(lo, -(c + 1e-9) / e->a);
      else if (e->a < -1e-15) hi = std::min(hi, -(c + 1e-9) / e->a);
      else if (c < -1e-9) hi = lo - 1;  // parallel to this edge and outside it
    }
    const int xa = std::max(x0, static_cast<int>(std::ceil(lo))), xb = std::min(x1, static_cast<int>(std::floor(hi)));
    if (xa > xb) continue;
    float q = static_cast<float>(iz.at(xa, y));
    const float dq = static_cast<float>(iz.a);
    float* inv_depth = &out.inv_depth[static_cast<std::size_t>(y) * out.width];
    std::int32_t* tri = &out.triangle[static_cast<std::size_t>(y) * out.width];
    for (int x = xa; x <= xb; ++x, q += dq) {
      if (q > inv_depth[x]) {  // nearer
        inv_depth[x] = q;
        tri[x] = id;
      }
    }
  }
}

}  // namespace

void append_triangles(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& triangles,
                      const Eigen::Isometry3d& world_T_mesh, int object, float albedo, SceneTriangles& t) {
  for (const auto& tri : triangles) {
    const Eigen::Vector3d a = world_T_mesh * vertices[tri[0]];
    const Eigen::Vector3d b = world_T_mesh * vertices[tri[1]];
    const Eigen::Vector3d c = world_T_mesh * vertices[tri[2]];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-15) continue;  // degenerate: no surface
    t.a.push_back(a);
    t.b.push_back(b);
    t.c.push_back(c);
    t.normal_w.push_back(n.normalized());
    t.offset.push_back(t.normal_w.back().dot(a));
    t.object.push_back(object);
    t.albedo.push_back(albedo);
  }
}

SceneTriangles collect_triangles(const World& world) {
  SceneTriangles t;
  const auto& objects = world.objects();
  for (std::size_t o = 0; o < objects.size(); ++o)
    append_triangles(objects[o].vertices_w, objects[o].triangles, Eigen::Isometry3d::Identity(), static_cast<int>(o),
                     static_cast<float>(objects[o].albedo), t);
  return t;
}

void rasterize(const SceneTriangles& tris, const Eigen::Isometry3d& viewer_T_world, const Intrinsics& k, int margin,
               DepthBuffer& out) {
  out.margin = margin;
  out.width = k.width + 2 * margin;
  out.height = k.height + 2 * margin;
  const std::size_t n = static_cast<std::size_t>(out.width) * out.height;
  out.inv_depth.assign(n, 0.0f);
  out.triangle.assign(n, -1);
  rasterize_more(tris, 0, viewer_T_world, k, out, RasterClip{});
}

void rasterize_more(const SceneTriangles& tris, std::size_t first, const Eigen::Isometry3d& viewer_T_world,
                    const Intrinsics& k, DepthBuffer& out, const RasterClip& clip) {

  const auto to_screen = [&](const Eigen::Vector3d& p) {
    return ScreenVertex{k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy, 1.0 / p.z()};
  };
  for (std::size_t i = first; i < tris.a.size(); ++i) {
    const Eigen::Vector3d v[3] = {viewer_T_world * tris.a[i], viewer_T_world * tris.b[i], viewer_T_world * tris.c[i]};
    const int behind = (v[0].z() < kNear) + (v[1].z() < kNear) + (v[2].z() < kNear);
    if (behind == 3) continue;
    const auto id = static_cast<std::int32_t>(i);
    if (behind == 0) {
      fill_triangle(to_screen(v[0]), to_screen(v[1]), to_screen(v[2]), id, out, clip);
      continue;
    }
    // clip against the near plane (Sutherland-Hodgman): a triangle or a quad remains
    Eigen::Vector3d poly[4];
    int count = 0;
    for (int e = 0; e < 3; ++e) {
      const Eigen::Vector3d& p = v[e];
      const Eigen::Vector3d& q = v[(e + 1) % 3];
      const bool pin = p.z() >= kNear, qin = q.z() >= kNear;
      if (pin) poly[count++] = p;
      if (pin != qin) poly[count++] = p + (q - p) * ((kNear - p.z()) / (q.z() - p.z()));
    }
    for (int f = 1; f + 1 < count; ++f)
      fill_triangle(to_screen(poly[0]), to_screen(poly[f]), to_screen(poly[f + 1]), id, out, clip);
  }
}

}  // namespace sim
