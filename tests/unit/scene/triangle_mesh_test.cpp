#include "sim/scene/triangle_mesh.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sys/stat.h>

namespace sim {
namespace {

const std::string kMeshes = std::string(CELL_SOURCE_DIR) + "/meshes/";

std::string error_of(const std::filesystem::path& p) {
  try {
    load_mesh(p);
  } catch (const MeshError& e) {
    return e.what();
  }
  return "";
}


std::filesystem::path write_bytes(const std::string& name, const std::string& bytes) {
  const auto p = std::filesystem::temp_directory_path() / name;
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

void expect_refused(const std::string& name, const std::string& bytes, const std::string& what) {
  const auto p = write_bytes(name, bytes);
  const std::string e = error_of(p);
  EXPECT_NE(e.find(p.string()), std::string::npos) << e;
  EXPECT_NE(e.find(what), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  std::filesystem::remove(p);
}

std::string binary_ply_header(int vertices, int faces) {
  return "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(vertices) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(faces) +
         "\nproperty list uchar int vertex_indices\nend_header\n";
}

// Issue 9, item 2: a PLY whose body is shorter than its header says made assimp abort the
// whole process (SIGABRT). Every mesh is now walked before assimp sees it.
TEST(Meshes, ShortBinaryPlyIsRefusedNotAborted) {
  std::string body(3 * 12, '\0');  // 3 vertices, then the face is missing
  expect_refused("_short.ply", binary_ply_header(3, 1) + body, "body ends early");
  expect_refused("_short2.ply", binary_ply_header(3, 1) + std::string(10, '\0'), "body ends early");
}

TEST(Meshes, MalformedFilesAreRefusedBeforeImport) {
  std::string face;
  face.push_back(3);
  for (int i : {0, 1, 7}) face.append(reinterpret_cast<const char*>(&i), 4);
  expect_refused("_badindex.ply", binary_ply_header(3, 1) + std::string(36, '\0') + face, "refers to vertex 7");
  expect_refused("_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n", "ends early");
  // found by the fuzzer: assimp loops for ever on a header line "end_headernan"
  expect_refused("_endhdr.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_headernan\n0 0 0\n1 0 0\n"
                 "0 1 0\n3 0 1 2\n", "no end_header line");
  // found by the fuzzer: a form feed inside an ASCII PLY line made assimp abort
  expect_refused("_ff.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0\f 0\n"
                 "0 1 0\n3 0 1 2\n", "byte \\x0c");
  expect_refused("_cr.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 \r0\n1 0 0\n"
                 "0 1 0\n3 0 1 2\n", "byte \\x0d");
  expect_refused("_bomb.ply", binary_ply_header(2000000000, 1), "limit");
  expect_refused("_bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "refers to no vertex");
  expect_refused("_nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not a finite number");
  expect_refused("_odd.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nxyz 1\nf 1 2 3\n", "unknown OBJ statement");
  expect_refused("_bin.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nxyz\xff 1\nf 1 2 3\n", "line 4: byte \\xff");
  std::string stl(80, ' ');
  const std::uint32_t n = 5;
  stl.append(reinterpret_cast<const char*>(&n), 4);
  expect_refused("_short.stl", stl + std::string(50, '\0'), "expected 334");
}

TEST(Meshes, ValidBinaryPlyStillLoads) {
  std::string body;
  for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) body.append(reinterpret_cast<const char*>(&v), 4);
  body.push_back(3);
  for (int i : {0, 1, 2}) body.append(reinterpret_cast<const char*>(&i), 4);
  const auto p = write_bytes("_ok.ply", binary_ply_header(3, 1) + body);
  EXPECT_EQ(load_mesh(p).triangles.size(), 1u);
  std::filesystem::remove(p);
}

TEST(Meshes, PlaneIsA2_4MetreWall) {
  const MeshStats s = mesh_stats(load_mesh(kMeshes + "plane.obj"));
  EXPECT_EQ(s.triangle_count, 2u * 12 * 12);
  EXPECT_NEAR(s.bbox_max.x() - s.bbox_min.x(), 2.4, 1e-6);
  EXPECT_NEAR(s.bbox_max.y() - s.bbox_min.y(), 2.4, 1e-6);
  EXPECT_NEAR(s.bbox_max.z() - s.bbox_min.z(), 0.0, 1e-9);
  EXPECT_NEAR(s.area_m2, 2.4 * 2.4, 1e-6);
  EXPECT_FALSE(s.closed);  // a wall is a sheet
}

TEST(Meshes, EllipticCylinderIsClosedWithItsStatedAxes) {
  const MeshStats s = mesh_stats(load_mesh(kMeshes + "elliptic_cylinder.obj"));
  EXPECT_TRUE(s.closed);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_NEAR(s.bbox_max.x(), 0.20, 1e-6);
  EXPECT_NEAR(s.bbox_min.x(), -0.20, 1e-6);
  EXPECT_NEAR(s.bbox_max.y(), 0.10, 1e-4);
  EXPECT_NEAR(s.bbox_max.z() - s.bbox_min.z(), 0.60, 1e-6);
  EXPECT_GT(s.triangle_count, 1000u);
}

TEST(Meshes, HamIsClosedAsymmetricWithANarrowShank) {
  const TriangleMesh m = load_mesh(kMeshes + "ham.obj");
  const MeshStats s = mesh_stats(m);
  EXPECT_TRUE(s.closed);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_NEAR(s.bbox_max.z() - s.bbox_min.z(), 0.45, 1e-6);
  // not an ellipsoid: flatter below (-Y) than above, and the shank is much thinner than the bulb
  EXPECT_GT(s.bbox_max.y(), -s.bbox_min.y() * 1.3);
  double bulb = 0, shank = 0;
  for (const auto& v : m.vertices) {
    if (std::abs(v.z() - 0.14) < 0.01) bulb = std::max(bulb, std::abs(v.y()));
    if (std::abs(v.z() - 0.38) < 0.01) shank = std::max(shank, std::abs(v.y()));
  }
  EXPECT_GT(bulb, 2.0 * shank);
}

// The held-out shapes of the decoder's evaluation (docs/decoding.md) are solids as stated: closed,
// their faces outward (a positive volume by the divergence theorem), the sizes their comments
// give, and printed with the plain shape's geometry.
double signed_volume(const TriangleMesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6.0;
  return v;
}

TEST(Meshes, TheHeldOutShapesAreClosedSolidsOfTheirStatedSize) {
  struct Shape {
    const char* name;
    Eigen::Vector3d min, max;
    double volume_m3;  // from the stated dimensions
  };
  constexpr double kPi = 3.14159265358979323846;
  const double r = 0.13, w = 0.012;
  const std::vector<Shape> shapes{
      {"pyramid", {-0.12, -0.12, 0}, {0.12, 0.12, 0.18}, 0.24 * 0.24 * 0.18 / 3},
      {"bowl", {-r, -r, -r}, {r, r, 0}, 2.0 / 3 * kPi * (r * r * r - (r - w) * (r - w) * (r - w))},
      {"arch", {-0.15, -0.08, 0}, {0.15, 0.08, 0.18}, 2 * 0.06 * 0.16 * 0.13 + 0.30 * 0.16 * 0.05},
      {"dumbbell", {-0.08, -0.08, -0.21}, {0.08, 0.08, 0.21}, 0},
      {"bottle", {-0.07, -0.07, 0}, {0.07, 0.07, 0.27}, 0},
  };
  for (const Shape& shape : shapes) {
    SCOPED_TRACE(shape.name);
    const TriangleMesh m = load_mesh(kMeshes + "heldout/" + shape.name + ".obj");
    const MeshStats s = mesh_stats(m);
    EXPECT_TRUE(s.closed);
    EXPECT_TRUE(s.consistently_oriented);
    EXPECT_GT(signed_volume(m), 0.0);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(s.bbox_min[k], shape.min[k], 2e-3);
      EXPECT_NEAR(s.bbox_max[k], shape.max[k], 2e-3);
    }
    // facets inside a curved surface lose a little volume: within 3 %
    if (shape.volume_m3 > 0) {
      EXPECT_NEAR(signed_volume(m), shape.volume_m3, 0.03 * shape.volume_m3);
    }
    const TriangleMesh printed = load_mesh(kMeshes + "heldout/printed/" + shape.name + ".obj");
    EXPECT_TRUE(printed.texture);
    EXPECT_EQ(printed.triangles.size(), m.triangles.size());
    EXPECT_NEAR(signed_volume(printed), signed_volume(m), 1e-9);
  }
}

TEST(Meshes, MissingFileIsOneLineNamingIt) {
  const std::string e = error_of("/nonexistent/wall.obj");
  EXPECT_EQ(e, "/nonexistent/wall.obj: mesh file not found");
}

TEST(Meshes, CorruptFileIsOneLineNamingIt) {
  const auto path = std::filesystem::temp_directory_path() / "triangle_mesh_test_corrupt.obj";
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nf 1 2 9\n";  // face refers to a vertex that does not exist
  const std::string e = error_of(path);
  EXPECT_EQ(e.rfind(path.string() + ": ", 0), 0u) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;

  const auto junk = std::filesystem::temp_directory_path() / "triangle_mesh_test_junk.ply";
  std::ofstream(junk, std::ios::binary) << "ply\nformat binary_little_endian 1.0\nelement vertex 999\n\x01\x02";
  const std::string j = error_of(junk);
  EXPECT_EQ(j.rfind(junk.string() + ": ", 0), 0u) << j;
}

TEST(Meshes, NonFiniteVertexIsRejected) {
  const auto path = std::filesystem::temp_directory_path() / "triangle_mesh_test_nan.obj";
  std::ofstream(path) << "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string e = error_of(path);
  EXPECT_EQ(e.rfind(path.string() + ": ", 0), 0u) << e;
}

// Issue 41: a printed mesh (texture coordinates, a material library naming a PNG beside it)
// loads its texture, every triangle's corners' coordinates, and the geometry of the same shape
// unprinted: its vertices joined by position (closed, as the plain box is).
TEST(Meshes, APrintedMeshCarriesItsTextureAndTheGeometryOfThePlainOne) {
  const TriangleMesh printed = load_mesh(kMeshes + "compact/printed/box.obj");
  const TriangleMesh plain = load_mesh(kMeshes + "compact/box.obj");
  ASSERT_TRUE(printed.texture);
  EXPECT_EQ(printed.texture->width, 256);
  EXPECT_EQ(printed.texture->height, 256);
  EXPECT_EQ(printed.corner_uv.size(), printed.triangles.size());
  EXPECT_EQ(printed.textured, std::vector<std::uint8_t>(printed.triangles.size(), 1));
  EXPECT_EQ(printed.vertices.size(), plain.vertices.size());
  EXPECT_EQ(printed.triangles.size(), plain.triangles.size());
  EXPECT_TRUE(mesh_stats(printed).consistently_oriented);
  float texel[3];
  texel_at(*printed.texture, 0.5, 0.99, texel);  // the label's top: its cream ground
  EXPECT_NEAR(texel[0], 242 / 255.0, 1e-6);
  EXPECT_NEAR(texel[2], 190 / 255.0, 1e-6);
  EXPECT_FALSE(load_mesh(kMeshes + "compact/box.obj").texture);
}

// A folder of its own for one printed mesh: the OBJ names `mtl`, which names `png`.
struct PrintedFolder {
  explicit PrintedFolder(const std::string& name) : dir(std::filesystem::temp_directory_path() / name) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~PrintedFolder() { std::filesystem::remove_all(dir); }
  std::filesystem::path obj(const std::string& mtllib) const {
    const auto p = dir / "m.obj";
    std::ofstream(p) << "mtllib " << mtllib << "\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n";
    return p;
  }
  void file(const std::string& name, const std::string& bytes) const { std::ofstream(dir / name, std::ios::binary) << bytes; }
  std::filesystem::path dir;
};

// What the OBJ and its material name is read from the mesh's folder alone, by plain name:
// assimp's own file system would open any path (a FIFO: a load that never ends). Every refusal
// is one line naming the file; a missing library or texture is an error, not an unprinted mesh.
TEST(Meshes, AMaterialOrTextureIsAPlainFileBesideTheMesh) {
  PrintedFolder f("_printed_paths");
  const std::string png = [] {
    std::ifstream in(kMeshes + "compact/printed/label.png", std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  for (const std::string bad : {"/etc/passwd.mtl", "../x.mtl", "sub/x.mtl", ".hidden.mtl", "x.txt"}) {
    const std::string e = error_of(f.obj(bad));
    EXPECT_NE(e.find("m.obj"), std::string::npos) << bad << ": " << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  }
  EXPECT_NE(error_of(f.obj("gone.mtl")).find("gone.mtl"), std::string::npos);
  ASSERT_EQ(mkfifo((f.dir / "fifo.mtl").c_str(), 0600), 0);
  EXPECT_NE(error_of(f.obj("fifo.mtl")).find("regular"), std::string::npos) << error_of(f.obj("fifo.mtl"));
  const auto with_texture = [&](const std::string& map) {
    f.file("a.mtl", "newmtl a\nKd 1 1 1\nmap_Kd " + map + "\n");
    return error_of(f.obj("a.mtl"));
  };
  EXPECT_NE(with_texture("/tmp/x.png").find("plain file name"), std::string::npos);
  EXPECT_NE(with_texture("-s 2 2 x.png").find("no options"), std::string::npos);
  EXPECT_NE(with_texture("absent.png").find("absent.png"), std::string::npos);
  f.file("notpng.png", "GIF89a, not a PNG at all, but long enough to read a header");
  EXPECT_NE(with_texture("notpng.png").find("not a PNG"), std::string::npos);
  std::string huge = png;
  huge[16] = 0, huge[17] = 0, huge[18] = 0x13, huge[19] = 0x88;  // a header claiming 5000 pixels across
  f.file("huge.png", huge);
  EXPECT_NE(with_texture("huge.png").find("5000 x 256"), std::string::npos) << with_texture("huge.png");
  std::string cut = png.substr(0, png.size() / 2);
  f.file("cut.png", cut);
  EXPECT_NE(with_texture("cut.png").find("cut.png"), std::string::npos);
  f.file("a.mtl", "newmtl a\nmap_Bump x.png\n");
  EXPECT_NE(error_of(f.obj("a.mtl")).find("unknown material statement 'map_Bump'"), std::string::npos);
  f.file("label.png", png);
  EXPECT_EQ(with_texture("label.png"), "");
  EXPECT_TRUE(load_mesh(f.dir / "m.obj").texture);
}

}  // namespace
}  // namespace sim
