// The cell's collision world: Bullet triangle-mesh objects, queried with rays.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <vector>

#include "sim/scene/triangle_mesh.hpp"

class btCollisionWorld;

namespace sim {

struct RayHit {
  Eigen::Vector3d point_w;    // world frame
  Eigen::Vector3d normal_w;   // unit, facing the ray's origin
  double fraction = 0;        // along from -> to
  int object = -1;            // index given by add_object
};

// Objects placed in the world, kept both as Bullet shapes (for rays) and as world-frame
// triangles (for the rasteriser). Static objects now; the robot's links later move.
class World {
 public:
  World();
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // Returns the object's index. Throws std::invalid_argument for an empty mesh.
  // `albedo`: per channel (R, G, B), 0..1
  int add_object(const TriangleMesh& mesh, const Eigen::Isometry3d& world_T_object, const Eigen::Vector3d& albedo);

  // Closest hit on the segment from -> to, if any.
  std::optional<RayHit> ray_test(const Eigen::Vector3d& from_w, const Eigen::Vector3d& to_w) const;

  struct Object {
    std::vector<Eigen::Vector3d> vertices_w;
    std::vector<std::array<int, 3>> triangles;
    double albedo = 0.8;  // the brightest channel's: the light it returns
    // each channel's share of it (albedo_c / albedo), 1 for a grey surface: the renderer
    // multiplies a pixel's light by it, per channel
    Eigen::Vector3d tint = Eigen::Vector3d::Ones();
    // the mesh's diffuse texture (TriangleMesh), multiplying the tint where it covers a triangle
    std::shared_ptr<const Texture> texture;
    std::vector<std::array<Eigen::Vector2d, 3>> corner_uv;
    std::vector<std::uint8_t> textured;
  };
  const std::vector<Object>& objects() const { return objects_; }

 private:
  struct Bullet;
  std::unique_ptr<Bullet> bullet_;
  std::vector<Object> objects_;
};

// Meshes that move, each with a pose per frame (the arm's links). A ray is cast in each
// mesh's own frame against its Bullet BVH, so casting changes no shared state: threads may
// cast at once, and the poses are an argument, not a state.
class MovingMeshes {
 public:
  MovingMeshes();
  ~MovingMeshes();
  MovingMeshes(const MovingMeshes&) = delete;
  MovingMeshes& operator=(const MovingMeshes&) = delete;

  // `link`: which entry of the poses places it. Returns the mesh's index.
  int add(const TriangleMesh& mesh, int link, double albedo);
  std::size_t size() const { return meshes_.size(); }
  const TriangleMesh& mesh(std::size_t i) const { return meshes_[i]; }
  int link(std::size_t i) const { return links_[i]; }
  float albedo(std::size_t i) const { return albedo_[i]; }

  // Closest hit on the segment; RayHit::object is the mesh's index.
  std::optional<RayHit> ray_test(const std::vector<Eigen::Isometry3d>& world_T_link, const Eigen::Vector3d& from_w,
                                 const Eigen::Vector3d& to_w) const;

 private:
  struct Bullet;
  std::unique_ptr<Bullet> bullet_;
  std::vector<TriangleMesh> meshes_;
  std::vector<int> links_;
  std::vector<float> albedo_;
  std::vector<Eigen::AlignedBox3d> boxes_;
};

}  // namespace sim
