// Structural check of a mesh file before any mesh library touches it. assimp 5.2 aborts
// (an assertion, SIGABRT) on a PLY whose body is shorter than its header says and loops on a
// header with no end_header; a file that decodes to millions of triangles would take
// gigabytes. So every file is walked here first, with bounded counts, and refused in one line.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>

namespace sim {

// Limits for one mesh file (docs/topics.md, Safety).
inline constexpr std::uintmax_t kMaxMeshFileBytes = 64u << 20;
inline constexpr std::size_t kMaxMeshVertices = 1'000'000;
inline constexpr std::size_t kMaxMeshTriangles = 2'000'000;
inline constexpr std::size_t kMaxFaceCorners = 64;
inline constexpr std::size_t kMaxSceneTriangles = 4'000'000;  // all objects of a scenario

struct MeshFileCounts {
  std::size_t vertices = 0;
  std::size_t triangles = 0;  // after fan triangulation of every face
};

// Walks an OBJ, PLY (ASCII or binary, either byte order) or STL (ASCII or binary) file
// completely: sizes, counts, numbers and indices. Throws MeshError ("<file>: <what>").
MeshFileCounts check_mesh_file(const std::filesystem::path& path);
// The same in two steps, so that the bytes walked are the bytes assimp reads: the file as a
// regular file of at most kMaxMeshFileBytes (MeshError otherwise), then its structure.
std::string read_mesh_file(const std::filesystem::path& path);
MeshFileCounts check_mesh_data(const std::filesystem::path& path, const std::string& data);

// An OBJ's material library (`mtllib NAME`) and a material's texture (`map_Kd NAME`) are read
// only from the mesh's own folder and named by a plain file name: no folder, no leading dot,
// at most kMaxSideFileName bytes of letters, digits, '_', '-' and '.'; with the extension
// `extension` (".mtl", ".png"). Returns the path beside `mesh`; throws MeshError naming both.
inline constexpr std::size_t kMaxSideFileName = 128;
inline constexpr std::uintmax_t kMaxMaterialFileBytes = 1u << 20;
std::filesystem::path side_file(const std::filesystem::path& mesh, const std::string& name, const std::string& extension);
// A material library's text, walked before assimp reads it: printable lines of known
// statements (newmtl, Ka, Kd, Ks, Ke, Ns, Ni, d, Tr, Tf, illum, map_Kd with one plain name).
void check_material_data(const std::filesystem::path& path, const std::string& data);

}  // namespace sim
