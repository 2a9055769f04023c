#include "sim/scene/mesh_check.hpp"

#include "common/regular_file.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "sim/scene/triangle_mesh.hpp"

namespace sim {
namespace {

[[noreturn]] void fail(const std::filesystem::path& p, const std::string& what) {
  throw MeshError(p.string() + ": " + what);
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Printable excerpt of untrusted bytes for a message.
std::string shown(const std::string& s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  return s.size() > 40 ? out + "..." : out;
}

bool parse_double(const std::string& tok, double& v) {
  // plain decimal only: strtod also reads hex floats and "infinity", which assimp does not
  if (tok.empty() || tok.size() > 64 || tok.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
  char* end = nullptr;
  v = std::strtod(tok.c_str(), &end);
  return end == tok.c_str() + tok.size() && std::isfinite(v);
}

bool parse_long(const std::string& tok, long long& v) {
  if (tok.empty() || tok.size() > 20) return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtoll(tok.c_str(), &end, 10);
  return errno == 0 && end == tok.c_str() + tok.size();
}

// Text formats hold printable ASCII, spaces, tabs and line ends only: assimp splits on fewer
// whitespace characters than C++ streams do (a form feed inside a line made it abort).
void check_text(const std::filesystem::path& p, const std::string& data, std::size_t from, std::size_t to) {
  std::size_t line = 1;
  for (std::size_t i = 0; i < std::min(to, data.size()); ++i) {
    const auto b = static_cast<unsigned char>(data[i]);
    if (b == '\n') ++line;
    if (i < from) continue;
    const bool line_end = b == '\n' || (b == '\r' && i + 1 < data.size() && data[i + 1] == '\n');
    if ((b < 0x20 && b != '\t' && !line_end) || b >= 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", b);
      fail(p, "line " + std::to_string(line) + ": byte " + hex + " in a text mesh file");
    }
  }
}

void add_triangles(const std::filesystem::path& p, MeshFileCounts& c, std::size_t corners) {
  c.triangles += corners - 2;
  if (c.triangles > kMaxMeshTriangles)
    fail(p, "more than " + std::to_string(kMaxMeshTriangles) + " triangles (the limit per mesh)");
}

// One statement of a line-based text format (OBJ, MTL): its key, where it is ("line N: ") and
// its values up to a '#' comment; false for a blank or comment line. More than `max_values`
// values is refused.
struct Statement {
  std::string key, at;
  std::vector<std::string> values;
};
bool read_statement(const std::filesystem::path& p, std::string line, std::size_t n, std::size_t max_values,
                    Statement& out) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::istringstream ls(line);
  out.values.clear();
  if (!(ls >> out.key) || out.key[0] == '#') return false;
  out.at = "line " + std::to_string(n) + ": ";
  for (std::string t; ls >> t;) {
    if (t[0] == '#') break;
    out.values.push_back(t);
    if (out.values.size() > max_values) fail(p, out.at + "too many values on one line");
  }
  return true;
}

// ---------------------------------------------------------------- OBJ
MeshFileCounts check_obj(const std::filesystem::path& p, const std::string& data) {
  check_text(p, data, 0, data.size());
  // first pass: how many of each kind of vertex the indices may refer to
  std::size_t nv = 0, nt = 0, nn = 0;
  {
    std::istringstream in(data);
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("v ", 0) == 0 || line.rfind("v\t", 0) == 0) ++nv;
      else if (line.rfind("vt", 0) == 0) ++nt;
      else if (line.rfind("vn", 0) == 0) ++nn;
    }
  }
  if (nv > kMaxMeshVertices) fail(p, std::to_string(nv) + " vertices, more than the limit of " + std::to_string(kMaxMeshVertices));
  MeshFileCounts c;
  c.vertices = nv;
  std::istringstream in(data);
  std::string line;
  std::size_t n = 0;
  const auto index_ok = [](const std::string& t, std::size_t count, bool allow_empty) {
    if (t.empty()) return allow_empty;
    long long i = 0;
    if (!parse_long(t, i) || i == 0) return false;
    return i > 0 ? static_cast<std::size_t>(i) <= count : static_cast<std::size_t>(-i) <= count;
  };
  Statement st;
  while (std::getline(in, line)) {
    if (!read_statement(p, line, ++n, kMaxFaceCorners + 4, st)) continue;
    const std::string& key = st.key;
    const std::string& at = st.at;
    const std::vector<std::string>& toks = st.values;
    if (key == "v" || key == "vn" || key == "vt") {
      const std::size_t need = key == "vt" ? 1 : 3;
      if (toks.size() < need || toks.size() > 4) fail(p, at + "'" + key + "' needs " + std::to_string(need) + " to 4 numbers");
      for (const auto& t : toks) {
        double v;
        if (!parse_double(t, v)) fail(p, at + "'" + shown(t) + "' is not a finite number");
      }
    } else if (key == "f") {
      if (toks.size() < 3) fail(p, at + "a face needs at least 3 corners");
      if (toks.size() > kMaxFaceCorners) fail(p, at + "a face with more than " + std::to_string(kMaxFaceCorners) + " corners");
      for (const auto& t : toks) {
        const std::size_t a = t.find('/');
        const std::size_t b = a == std::string::npos ? std::string::npos : t.find('/', a + 1);
        const std::string vi = t.substr(0, a);
        const std::string ti = a == std::string::npos ? "" : t.substr(a + 1, b == std::string::npos ? std::string::npos : b - a - 1);
        const std::string ni = b == std::string::npos ? "" : t.substr(b + 1);
        if (!index_ok(vi, nv, false) || !index_ok(ti, nt, true) || !index_ok(ni, nn, true))
          fail(p, at + "face corner '" + shown(t) + "' refers to no vertex (" + std::to_string(nv) + " vertices)");
      }
      add_triangles(p, c, toks.size());
    } else if (key == "mtllib") {
      // read by the loader from the mesh's folder alone (MeshFolderIO), so named plainly
      if (toks.size() != 1) fail(p, at + "'mtllib' takes one plain file name");
      side_file(p, toks[0], ".mtl");
    } else if (key == "o" || key == "g" || key == "s" || key == "usemtl") {
      // names, smoothing groups, materials: nothing to check (lines and points, 'l' and 'p',
      // are refused: assimp 5.2's triangulation asserts on them and aborts the process)
    } else {
      fail(p, at + "unknown OBJ statement '" + shown(key) + "'");
    }
  }
  if (c.triangles == 0) fail(p, "mesh has no faces");
  return c;
}

// ---------------------------------------------------------------- PLY
struct PlyProperty {
  std::string name;
  int size = 0;        // bytes of the value (or of each list item)
  bool is_float = false;
  bool list = false;
  int count_size = 0;  // bytes of a list's length
};
struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> props;
};

int ply_type_size(const std::string& t, bool& is_float) {
  is_float = t == "float" || t == "float32" || t == "double" || t == "float64";
  if (t == "char" || t == "int8" || t == "uchar" || t == "uint8") return 1;
  if (t == "short" || t == "int16" || t == "ushort" || t == "uint16") return 2;
  if (t == "int" || t == "int32" || t == "uint" || t == "uint32" || t == "float" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

struct PlyHeader {
  std::string format;           // ascii | binary_little_endian | binary_big_endian
  std::size_t body = 0;         // offset of the first byte after end_header
  std::vector<PlyElement> elements;
};

PlyHeader read_ply_header(const std::filesystem::path& p, const std::string& data) {
  if (data.rfind("ply", 0) != 0) fail(p, "not a PLY file (no 'ply' magic)");
  // end_header alone on its line: assimp reads "end_headerX" as no end and loops for ever
  std::size_t end_header = std::string::npos, body = 0;
  for (const char* marker : {"\nend_header\n", "\nend_header\r\n"}) {
    const std::size_t at = data.find(marker);
    if (at != std::string::npos && at < end_header) {
      end_header = at + 1;
      body = at + std::strlen(marker);
    }
  }
  if (end_header == std::string::npos || end_header > 64 * 1024)
    fail(p, "PLY header has no end_header line in its first 64 kB (truncated or corrupt file)");
  check_text(p, data, 0, body);
  std::istringstream in(data.substr(0, end_header));
  std::string line, format;
  std::vector<PlyElement> elements;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key.empty() || key == "ply" || key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      std::string version;
      ls >> format >> version;
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
        fail(p, "unknown PLY format '" + shown(format) + "'");
    } else if (key == "element") {
      PlyElement e;
      std::string count;
      ls >> e.name >> count;
      long long n = 0;
      if (!parse_long(count, n) || n < 0) fail(p, "PLY element '" + shown(e.name) + "' has count '" + shown(count) + "'");
      const std::size_t limit = e.name == "face" ? kMaxMeshTriangles : kMaxMeshVertices;
      if (static_cast<unsigned long long>(n) > limit)
        fail(p, "PLY element '" + shown(e.name) + "' has " + std::to_string(n) + " entries, more than the limit of " +
                    std::to_string(limit));
      e.count = static_cast<std::size_t>(n);
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) fail(p, "PLY property before any element");
      PlyProperty prop;
      std::string type;
      ls >> type;
      if (type == "list") {
        std::string count_type, item_type;
        ls >> count_type >> item_type >> prop.name;
        bool f = false;
        prop.list = true;
        prop.count_size = ply_type_size(count_type, f);
        if (prop.count_size == 0 || f) fail(p, "PLY list length type '" + shown(count_type) + "'");
        prop.size = ply_type_size(item_type, prop.is_float);
        if (prop.size == 0) fail(p, "unknown PLY type '" + shown(item_type) + "'");
      } else {
        ls >> prop.name;
        prop.size = ply_type_size(type, prop.is_float);
        if (prop.size == 0) fail(p, "unknown PLY type '" + shown(type) + "'");
      }
      elements.back().props.push_back(prop);
    } else {
      fail(p, "unknown PLY header line '" + shown(line) + "'");
    }
  }
  if (format.empty()) fail(p, "PLY header has no format line");
  return {format, body, elements};
}

// one element per line, exactly its values: assimp reads ASCII PLY line by line and asserts
// (aborting the process) on an element split over two lines
void check_ply_ascii(const std::filesystem::path& p, const std::string& data, const PlyHeader& h, MeshFileCounts& c) {
  const std::size_t body = h.body;
  const std::vector<PlyElement>& elements = h.elements;
  check_text(p, data, body, data.size());
  std::istringstream lines(data.substr(body));
  for (const auto& e : elements)
    for (std::size_t i = 0; i < e.count; ++i) {
      std::string text;
      if (!std::getline(lines, text))
        fail(p, "PLY body ends early: element '" + shown(e.name) + "' " + std::to_string(i) + " of " +
                    std::to_string(e.count) + " is missing");
      std::istringstream b(text);
      std::string tok;
      const auto next = [&]() {
        if (!(b >> tok))
          fail(p, "PLY element '" + shown(e.name) + "' " + std::to_string(i) + " has too few values on its line");
        double v;
        if (!parse_double(tok, v)) fail(p, "PLY value '" + shown(tok) + "' is not a finite number");
        return v;
      };
      for (const auto& prop : e.props) {
        if (!prop.list) {
          next();
          continue;
        }
        const double n = next();
        if (n < 0 || n > kMaxFaceCorners || n != std::floor(n)) fail(p, "PLY list of length '" + shown(tok) + "'");
        for (int k = 0; k < static_cast<int>(n); ++k) {
          const double idx = next();
          if (e.name == "face" && (idx < 0 || idx >= static_cast<double>(c.vertices) || idx != std::floor(idx)))
            fail(p, "PLY face " + std::to_string(i) + " refers to vertex " + shown(tok) + " of " + std::to_string(c.vertices));
        }
        if (e.name == "face") {
          if (n < 3) fail(p, "PLY face " + std::to_string(i) + " has fewer than 3 corners");
          add_triangles(p, c, static_cast<std::size_t>(n));
        }
      }
      if (b >> tok) fail(p, "PLY element '" + shown(e.name) + "' " + std::to_string(i) + " has extra values on its line");
    }
}

void check_ply_binary(const std::filesystem::path& p, const std::string& data, const PlyHeader& h, MeshFileCounts& c) {
  const std::string& format = h.format;
  const std::size_t body = h.body;
  const std::vector<PlyElement>& elements = h.elements;
  const bool swap = format == "binary_big_endian";
  std::size_t at = body;
  const auto read_uint = [&](int size, bool is_float, const std::string& what) -> double {
    if (data.size() - at < static_cast<std::size_t>(size))
      fail(p, "PLY body ends early (" + std::to_string(data.size()) + " bytes) while reading " + what);
    unsigned char b[8];
    std::memcpy(b, data.data() + at, static_cast<std::size_t>(size));
    at += static_cast<std::size_t>(size);
    if (swap) std::reverse(b, b + size);
    if (is_float) {
      if (size == 4) {
        float f;
        std::memcpy(&f, b, 4);
        return f;
      }
      double d;
      std::memcpy(&d, b, 8);
      return d;
    }
    std::uint64_t v = 0;
    std::memcpy(&v, b, static_cast<std::size_t>(size));
    return static_cast<double>(v);
  };
  for (const auto& e : elements)
    for (std::size_t i = 0; i < e.count; ++i)
      for (const auto& prop : e.props) {
        const std::string what = "element '" + shown(e.name) + "' " + std::to_string(i) + " of " + std::to_string(e.count);
        if (!prop.list) {
          const double v = read_uint(prop.size, prop.is_float, what);
          if (prop.is_float && !std::isfinite(v)) fail(p, "PLY value of " + what + " is not a finite number");
          continue;
        }
        const double n = read_uint(prop.count_size, false, what);
        if (n > kMaxFaceCorners) fail(p, "PLY list of " + what + " has length " + std::to_string(static_cast<long long>(n)));
        for (int k = 0; k < static_cast<int>(n); ++k) {
          const double idx = read_uint(prop.size, prop.is_float, what);
          if (e.name == "face" && (prop.is_float || idx >= static_cast<double>(c.vertices)))
            fail(p, "PLY " + what + " refers to vertex " + std::to_string(static_cast<long long>(idx)) + " of " +
                        std::to_string(c.vertices));
        }
        if (e.name == "face") {
          if (n < 3) fail(p, "PLY " + what + " has fewer than 3 corners");
          add_triangles(p, c, static_cast<std::size_t>(n));
        }
      }
}

MeshFileCounts check_ply(const std::filesystem::path& p, const std::string& data) {
  const PlyHeader h = read_ply_header(p, data);
  MeshFileCounts c;
  for (const auto& e : h.elements)
    if (e.name == "vertex") c.vertices = e.count;
  if (h.format == "ascii") check_ply_ascii(p, data, h, c);
  else check_ply_binary(p, data, h, c);
  if (c.triangles == 0) fail(p, "mesh has no faces");
  return c;
}

// ---------------------------------------------------------------- STL
MeshFileCounts check_stl(const std::filesystem::path& p, const std::string& data) {
  MeshFileCounts c;
  const bool ascii = data.rfind("solid", 0) == 0 && data.find("facet") != std::string::npos;
  if (!ascii) {
    if (data.size() < 84) fail(p, "binary STL shorter than its 84-byte header");
    std::uint32_t n = 0;
    std::memcpy(&n, data.data() + 80, 4);
    if (n > kMaxMeshTriangles) fail(p, "binary STL says " + std::to_string(n) + " triangles, more than the limit");
    if (data.size() != 84 + 50ull * n)
      fail(p, "binary STL of " + std::to_string(data.size()) + " bytes for " + std::to_string(n) + " triangles (expected " +
                  std::to_string(84 + 50ull * n) + ")");
    for (std::uint32_t t = 0; t < n; ++t)
      for (int k = 0; k < 12; ++k) {
        float f;
        std::memcpy(&f, data.data() + 84 + 50ull * t + 4 * k, 4);
        if (!std::isfinite(f)) fail(p, "binary STL triangle " + std::to_string(t) + " has a non-finite number");
      }
    c.triangles = n;
    c.vertices = 3ull * n;
  } else {
    check_text(p, data, 0, data.size());
    std::istringstream in(data);
    std::string tok;
    std::size_t vertices = 0;
    while (in >> tok) {
      if (tok != "vertex") continue;
      for (int k = 0; k < 3; ++k) {
        double v;
        if (!(in >> tok) || !parse_double(tok, v)) fail(p, "ASCII STL vertex " + std::to_string(vertices) + " is not 3 numbers");
      }
      if (++vertices > 3 * kMaxMeshTriangles) fail(p, "ASCII STL with more triangles than the limit");
    }
    if (vertices % 3 != 0) fail(p, "ASCII STL with " + std::to_string(vertices) + " vertices, not whole triangles");
    c.vertices = vertices;
    c.triangles = vertices / 3;
  }
  if (c.triangles == 0) fail(p, "mesh has no faces");
  return c;
}

}  // namespace

std::string read_mesh_file(const std::filesystem::path& path) {
  try {
    return common::read_regular_file(path, kMaxMeshFileBytes, "mesh file");
  } catch (const common::FileError& e) {
    throw MeshError(e.what());
  }
}

MeshFileCounts check_mesh_data(const std::filesystem::path& path, const std::string& data) {
  const std::string ext = lower(path.extension().string());
  if (ext == ".obj") return check_obj(path, data);
  if (ext == ".ply") return check_ply(path, data);
  if (ext == ".stl") return check_stl(path, data);
  fail(path, "unsupported mesh format '" + shown(ext) + "' (use .obj, .ply or .stl)");
}

std::filesystem::path side_file(const std::filesystem::path& mesh, const std::string& name, const std::string& extension) {
  const bool plain = !name.empty() && name.size() <= kMaxSideFileName && name[0] != '.' &&
                     name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.") ==
                         std::string::npos;
  if (!plain)
    fail(mesh, "'" + shown(name) + "': a material or texture must be a plain file name beside the mesh (letters, digits, _ - .)");
  if (lower(std::filesystem::path(name).extension().string()) != extension)
    fail(mesh, "'" + shown(name) + "': expected a " + extension + " file");
  return mesh.parent_path() / name;
}

void check_material_data(const std::filesystem::path& path, const std::string& data) {
  check_text(path, data, 0, data.size());
  std::istringstream in(data);
  std::string line;
  Statement st;
  for (std::size_t n = 1; std::getline(in, line); ++n) {
    if (!read_statement(path, line, n, 4, st)) continue;
    const std::string& key = st.key;
    const std::string& at = st.at;
    const std::vector<std::string>& toks = st.values;
    if (key == "newmtl") {
      if (toks.size() != 1 || toks[0].size() > kMaxSideFileName) fail(path, at + "'newmtl' takes one name");
    } else if (key == "map_Kd") {
      if (toks.size() != 1) fail(path, at + "'map_Kd' takes one plain file name (no options)");
      side_file(path, toks[0], ".png");
    } else if (key == "Ka" || key == "Kd" || key == "Ks" || key == "Ke" || key == "Tf" || key == "Ns" || key == "Ni" ||
               key == "d" || key == "Tr" || key == "illum") {
      if (toks.empty() || toks.size() > 3) fail(path, at + "'" + key + "' takes 1 to 3 numbers");
      for (const auto& t : toks) {
        double v;
        if (!parse_double(t, v)) fail(path, at + "'" + shown(t) + "' is not a finite number");
      }
    } else {
      fail(path, at + "unknown material statement '" + shown(key) + "'");
    }
  }
}

MeshFileCounts check_mesh_file(const std::filesystem::path& path) { return check_mesh_data(path, read_mesh_file(path)); }

}  // namespace sim
