#include "sim/scene/triangle_mesh.hpp"

#include "sim/scene/mesh_check.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <fstream>
#include <map>
#include <string>

namespace sim {
namespace {

void collect(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, TriangleMesh& out,
             const std::string& file) {
  const aiMatrix4x4 world = parent * node->mTransformation;
  for (unsigned m = 0; m < node->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[node->mMeshes[m]];
    const int base = static_cast<int>(out.vertices.size());
    for (unsigned i = 0; i < mesh->mNumVertices; ++i) {
      const aiVector3D p = world * mesh->mVertices[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw MeshError(file + ": vertex " + std::to_string(i) + " of mesh '" + mesh->mName.C_Str() +
                        "' is not a finite number");
      out.vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines left by triangulation carry no surface
      out.triangles.push_back({base + static_cast<int>(face.mIndices[0]), base + static_cast<int>(face.mIndices[1]),
                               base + static_cast<int>(face.mIndices[2])});
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) collect(scene, node->mChildren[c], world, out, file);
}


}  // namespace

TriangleMesh load_mesh(const std::filesystem::path& path) { return load_mesh(path, kMaxMeshTriangles, ""); }

TriangleMesh load_mesh(const std::filesystem::path& path, std::size_t max_triangles, const std::string& budget_name) {
  const std::string file = path.string();
  // assimp only ever sees bytes whose structure was walked here, read once from a regular file
  const std::string data = read_mesh_file(path);
  const MeshFileCounts counts = check_mesh_data(path, data);
  if (counts.triangles > max_triangles)
    throw MeshError(file + ": " + std::to_string(counts.triangles) + " triangles, more than the " +
                    std::to_string(max_triangles) + " left " + budget_name);
  std::string hint = path.extension().string().substr(1);  // a known extension: checked above
  for (char& ch : hint) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFileFromMemory(
      data.data(), data.size(),
      aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure | aiProcess_SortByPType,
      hint.c_str());
  if (scene == nullptr || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0 || scene->mRootNode == nullptr) {
    std::string why = importer.GetErrorString();
    if (why.empty()) why = "incomplete scene";
    for (char& ch : why)
      if (ch == '\n' || ch == '\r') ch = ' ';
    throw MeshError(file + ": cannot read mesh: " + why);
  }
  TriangleMesh mesh;
  collect(scene, scene->mRootNode, aiMatrix4x4(), mesh, file);
  if (mesh.triangles.empty()) throw MeshError(file + ": mesh has no triangles");
  return mesh;
}

MeshStats mesh_stats(const TriangleMesh& mesh) {
  MeshStats s;
  s.triangle_count = mesh.triangles.size();
  if (mesh.vertices.empty()) return s;
  s.bbox_min = s.bbox_max = mesh.vertices.front();
  for (const auto& v : mesh.vertices) {
    s.bbox_min = s.bbox_min.cwiseMin(v);
    s.bbox_max = s.bbox_max.cwiseMax(v);
  }
  // directed edge -> uses; a closed, consistently oriented surface uses each directed edge
  // once and its reverse once
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[t[0]];
    const Eigen::Vector3d& b = mesh.vertices[t[1]];
    const Eigen::Vector3d& c = mesh.vertices[t[2]];
    s.area_m2 += 0.5 * (b - a).cross(c - a).norm();
    for (int i = 0; i < 3; ++i) ++directed[{t[i], t[(i + 1) % 3]}];
  }
  bool closed = true;
  bool oriented = true;
  for (const auto& [edge, uses] : directed) {
    const auto rev = directed.find({edge.second, edge.first});
    const int back = rev == directed.end() ? 0 : rev->second;
    if (uses + back != 2) closed = false;
    if (uses != 1 || back != 1) oriented = false;
  }
  s.closed = closed;
  s.consistently_oriented = closed && oriented;
  return s;
}

}  // namespace sim
