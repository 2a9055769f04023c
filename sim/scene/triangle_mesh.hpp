// Triangle meshes read from disk with assimp: the shapes of the scene's objects.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <vector>

#include "sim/scene/texture.hpp"

namespace sim {

// A missing, unreadable or unusable mesh file. what() is one line: "<file>: <what is wrong>".
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;        // metres, in the mesh's own frame
  std::vector<std::array<int, 3>> triangles;    // vertex indices, counter-clockwise from outside
  // Where the file's material names a diffuse image (an OBJ's `map_Kd`, a PNG beside it):
  // that image, each triangle's texture coordinates (u, v) per corner, and per triangle 1
  // where the texture covers it. Empty and null for an untextured mesh. A textured mesh's
  // vertices are joined by position alone: its geometry is the one it has without the texture.
  std::shared_ptr<const Texture> texture;
  std::vector<std::array<Eigen::Vector2d, 3>> corner_uv;
  std::vector<std::uint8_t> textured;
};

// Reads every mesh of the file (node transforms applied), triangulated, with identical
// vertices joined. Throws MeshError when the file is missing, assimp cannot parse it, it
// holds no triangles, or a coordinate is not finite. An OBJ's material library and texture
// are read only from the mesh's own folder, by plain file name (see mesh_check.hpp).
TriangleMesh load_mesh(const std::filesystem::path& path);
// The same, refused before assimp reads it when the file holds more than `max_triangles`
// (a caller's running budget: a URDF's many meshes are counted as they load).
TriangleMesh load_mesh(const std::filesystem::path& path, std::size_t max_triangles, const std::string& budget_name);

struct MeshStats {
  std::size_t triangle_count = 0;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
  double area_m2 = 0.0;
  // closed: every edge is shared by exactly two triangles; oriented: and in opposite directions
  bool closed = false;
  bool consistently_oriented = false;
};

MeshStats mesh_stats(const TriangleMesh& mesh);

}  // namespace sim
