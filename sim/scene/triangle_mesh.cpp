#include "sim/scene/triangle_mesh.hpp"

#include "sim/scene/mesh_check.hpp"

#include <assimp/MemoryIOWrapper.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/IOSystem.hpp>
#include <assimp/Importer.hpp>
#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <fstream>
#include <cstring>
#include <map>
#include <string>

#include "common/regular_file.hpp"

namespace sim {
namespace {

// The files assimp asks for while it reads a mesh from memory (an OBJ's material library).
// Its own would open any path the file names, a FIFO among them (the read would never end):
// here only a plain .mtl name beside the mesh is served, a regular file of bounded size whose
// statements were walked first (check_material_data); every other name reads as missing.
class MeshFolderIO : public Assimp::IOSystem {
 public:
  explicit MeshFolderIO(std::filesystem::path mesh) : mesh_(std::move(mesh)) {}
  bool Exists(const char* name) const override { return served(name); }
  char getOsSeparator() const override { return '/'; }
  Assimp::IOStream* Open(const char* name, const char* mode) override {
    if (mode == nullptr || std::strchr(mode, 'w') != nullptr || std::strchr(mode, 'a') != nullptr) return nullptr;
    if (!served(name)) return nullptr;
    const std::filesystem::path path = side_file(mesh_, name, ".mtl");
    std::string data;
    try {
      data = common::read_regular_file(path, kMaxMaterialFileBytes, "material library");
    } catch (const common::FileError& e) {
      throw MeshError(e.what());
    }
    check_material_data(path, data);
    auto* bytes = new std::uint8_t[data.size() + 1];
    std::memcpy(bytes, data.data(), data.size());
    return new Assimp::MemoryIOStream(bytes, data.size(), /*own*/ true);
  }
  void Close(Assimp::IOStream* stream) override { delete stream; }

 private:
  // a plain .mtl name (assimp asks with the names the file gives); anything else is missing
  bool served(const char* name) const {
    if (name == nullptr) return false;
    try {
      side_file(mesh_, name, ".mtl");
      return true;
    } catch (const MeshError&) {
      return false;
    }
  }
  std::filesystem::path mesh_;
};

// What collect() finds beside the geometry: the diffuse texture's name and which triangles
// it covers, with their corners' texture coordinates.
struct Texturing {
  std::string name;  // the one texture the file's materials name (empty: none)
  std::vector<std::array<Eigen::Vector2d, 3>> corner_uv;
  std::vector<std::uint8_t> textured;
};

// The diffuse texture `mesh`'s material names, if the mesh has coordinates for it (else "").
std::string diffuse_texture(const aiScene* scene, const aiMesh* mesh, const std::string& file) {
  if (!mesh->HasTextureCoords(0) || mesh->mMaterialIndex >= scene->mNumMaterials) return "";
  const aiMaterial* material = scene->mMaterials[mesh->mMaterialIndex];
  if (material->GetTextureCount(aiTextureType_DIFFUSE) == 0) return "";
  aiString name;
  if (material->GetTexture(aiTextureType_DIFFUSE, 0, &name) != AI_SUCCESS) return "";
  const std::string n = name.C_Str();
  side_file(file, n, ".png");  // the name as the library gave it, refused unless plain
  return n;
}

void collect(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, TriangleMesh& out,
             Texturing& tex, const std::string& file, int depth) {
  // a node tree deeper than any real file: refused before the recursion could exhaust the stack
  if (depth > 256) throw MeshError(file + ": node hierarchy deeper than 256");
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
    const std::string texture = diffuse_texture(scene, mesh, file);
    if (!texture.empty() && !tex.name.empty() && texture != tex.name)
      throw MeshError(file + ": materials name two textures ('" + tex.name + "', '" + texture +
                      "'): one image per mesh file");
    if (!texture.empty()) tex.name = texture;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines left by triangulation carry no surface
      out.triangles.push_back({base + static_cast<int>(face.mIndices[0]), base + static_cast<int>(face.mIndices[1]),
                               base + static_cast<int>(face.mIndices[2])});
      std::array<Eigen::Vector2d, 3> uv{};
      for (int k = 0; k < 3 && !texture.empty(); ++k) {
        const aiVector3D& t = mesh->mTextureCoords[0][face.mIndices[k]];
        if (!std::isfinite(t.x) || !std::isfinite(t.y))
          throw MeshError(file + ": a texture coordinate of mesh '" + mesh->mName.C_Str() + "' is not a finite number");
        uv[k] = Eigen::Vector2d(t.x, t.y);
      }
      tex.corner_uv.push_back(uv);
      tex.textured.push_back(texture.empty() ? 0 : 1);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) collect(scene, node->mChildren[c], world, out, tex, file, depth + 1);
}

// A textured mesh's vertices joined by position alone (assimp keeps a vertex apart for each
// texture coordinate it has, which would open the mesh along every seam).
void join_by_position(TriangleMesh& mesh) {
  std::map<std::array<double, 3>, int> first;
  std::vector<Eigen::Vector3d> joined;
  std::vector<int> index(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d& v = mesh.vertices[i];
    const auto [at, added] = first.emplace(std::array<double, 3>{v.x(), v.y(), v.z()}, static_cast<int>(joined.size()));
    if (added) joined.push_back(v);
    index[i] = at->second;
  }
  for (auto& t : mesh.triangles)
    for (int& k : t) k = index[static_cast<std::size_t>(k)];
  mesh.vertices = std::move(joined);
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
  importer.SetIOHandler(new MeshFolderIO(path));  // the importer owns it
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
  Texturing tex;
  collect(scene, scene->mRootNode, aiMatrix4x4(), mesh, tex, file, 0);
  if (mesh.triangles.empty()) throw MeshError(file + ": mesh has no triangles");
  if (!tex.name.empty()) {
    mesh.texture = std::make_shared<const Texture>(load_texture(side_file(path, tex.name, ".png")));
    mesh.corner_uv = std::move(tex.corner_uv);
    mesh.textured = std::move(tex.textured);
    join_by_position(mesh);
  }
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
