#include "sim/arm/robot_model.hpp"

#include <console_bridge/console.h>
#include <tinyxml2.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cstdlib>
#include <map>

#include <cmath>
#include <fstream>
#include <mutex>
#include <sstream>

#include "common/regular_file.hpp"
#include "common/strict_yaml.hpp"

namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// urdfdom reports through console_bridge on stderr; the first error becomes our one line.
class CapturedLog : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR && first_error.empty()) first_error = text;
  }
  std::string first_error;
};

std::mutex& console_mutex() {
  static std::mutex m;  // console_bridge's handler is process-wide
  return m;
}

[[noreturn]] void fail(const std::filesystem::path& f, const std::string& what) {
  throw RobotModelError(f.string() + ": " + what);
}

Eigen::Isometry3d to_iso(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  Eigen::Quaterniond q(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z);
  if (!std::isfinite(q.norm())) {
    t.matrix().setConstant(std::nan(""));  // refused by finite_pose, never taken for the identity
    return t;
  }
  if (!(q.norm() > 0.5)) q = Eigen::Quaterniond::Identity();
  t.linear() = q.normalized().toRotationMatrix();
  return t;
}

bool finite_pose(const Eigen::Isometry3d& t) {
  return t.matrix().allFinite() && t.translation().cwiseAbs().maxCoeff() <= 100.0;
}

// Closed primitive meshes for URDF <box>, <cylinder> (along z) and <sphere>.
TriangleMesh box_mesh(const Eigen::Vector3d& size) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back((i & 1 ? 0.5 : -0.5) * size.x(), (i & 2 ? 0.5 : -0.5) * size.y(), (i & 4 ? 0.5 : -0.5) * size.z());
  m.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                 {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return m;
}

TriangleMesh cylinder_mesh(double r, double length, int around = 32) {
  TriangleMesh m;
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < around; ++i) {
      const double a = 2 * kPi * i / around;
      m.vertices.emplace_back(r * std::cos(a), r * std::sin(a), (k ? 0.5 : -0.5) * length);
    }
  const int b = static_cast<int>(m.vertices.size());
  m.vertices.emplace_back(0, 0, -0.5 * length);
  m.vertices.emplace_back(0, 0, 0.5 * length);
  for (int i = 0; i < around; ++i) {
    const int j = (i + 1) % around;
    m.triangles.push_back({i, j, around + j});
    m.triangles.push_back({i, around + j, around + i});
    m.triangles.push_back({b, j, i});
    m.triangles.push_back({b + 1, around + i, around + j});
  }
  return m;
}

TriangleMesh sphere_mesh(double r, int rings = 12, int around = 24) {
  TriangleMesh m;
  m.vertices.emplace_back(0, 0, -r);
  for (int k = 1; k < rings; ++k) {
    const double th = kPi * k / rings - kPi / 2;
    for (int i = 0; i < around; ++i) {
      const double a = 2 * kPi * i / around;
      m.vertices.emplace_back(r * std::cos(th) * std::cos(a), r * std::cos(th) * std::sin(a), r * std::sin(th));
    }
  }
  m.vertices.emplace_back(0, 0, r);
  const int top = static_cast<int>(m.vertices.size()) - 1;
  const auto id = [&](int k, int i) { return 1 + (k - 1) * around + (i % around); };
  for (int i = 0; i < around; ++i) m.triangles.push_back({0, id(1, i + 1), id(1, i)});
  for (int k = 1; k + 1 < rings; ++k)
    for (int i = 0; i < around; ++i) {
      m.triangles.push_back({id(k, i), id(k, i + 1), id(k + 1, i + 1)});
      m.triangles.push_back({id(k, i), id(k + 1, i + 1), id(k + 1, i)});
    }
  for (int i = 0; i < around; ++i) m.triangles.push_back({top, id(rings - 1, i), id(rings - 1, i + 1)});
  return m;
}

// One URDF geometry as a mesh in the link frame.
TriangleMesh geometry_mesh(const std::filesystem::path& urdf_file, const urdf::GeometrySharedPtr& g,
                           const urdf::Pose& origin, const std::string& where, std::size_t triangles_left) {
  if (!g) fail(urdf_file, where + ": no geometry");
  TriangleMesh m;
  Eigen::Vector3d scale(1, 1, 1);
  const auto positive = [&](double v, const char* what) {
    if (!(v > 1e-6 && v < 100)) fail(urdf_file, where + ": " + what + " must be in (1e-6, 100) m");
    return v;
  };
  switch (g->type) {
    case urdf::Geometry::BOX: {
      const auto& b = static_cast<const urdf::Box&>(*g);
      m = box_mesh({positive(b.dim.x, "box size"), positive(b.dim.y, "box size"), positive(b.dim.z, "box size")});
      break;
    }
    case urdf::Geometry::CYLINDER: {
      const auto& c = static_cast<const urdf::Cylinder&>(*g);
      m = cylinder_mesh(positive(c.radius, "cylinder radius"), positive(c.length, "cylinder length"));
      break;
    }
    case urdf::Geometry::SPHERE:
      m = sphere_mesh(positive(static_cast<const urdf::Sphere&>(*g).radius, "sphere radius"));
      break;
    case urdf::Geometry::MESH: {
      const auto& me = static_cast<const urdf::Mesh&>(*g);
      const std::string& name = me.filename;
      if (name.rfind("package://", 0) == 0 || name.find("://") != std::string::npos)
        fail(urdf_file, where + ": mesh '" + common::printable(name) +
                            "': URIs are not resolved here; give a path relative to the URDF file");
      std::filesystem::path p(name);
      if (p.is_relative()) p = urdf_file.parent_path() / p;
      // walked by check_mesh_file and counted before assimp: a URDF of many huge meshes is
      // refused at the first one past the arm's limit, not after loading them all (issue 18)
      m = load_mesh(p, triangles_left, "of the robot's limit of " + std::to_string(kMaxArmTriangles) + " (" + where + ")");
      scale = Eigen::Vector3d(me.scale.x, me.scale.y, me.scale.z);
      if (!scale.allFinite() || scale.cwiseAbs().minCoeff() < 1e-6 || scale.cwiseAbs().maxCoeff() > 1e3)
        fail(urdf_file, where + ": mesh scale must be finite, between 1e-6 and 1000");
      break;
    }
    default: fail(urdf_file, where + ": unsupported geometry type");
  }
  const Eigen::Isometry3d t = to_iso(origin);
  if (!finite_pose(t)) fail(urdf_file, where + ": origin must be finite, within 100 m");
  for (auto& v : m.vertices) v = t * scale.cwiseProduct(v);
  return m;
}

void append(TriangleMesh& to, const TriangleMesh& m) {
  const int base = static_cast<int>(to.vertices.size());
  to.vertices.insert(to.vertices.end(), m.vertices.begin(), m.vertices.end());
  for (const auto& t : m.triangles) to.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
}

// A link's visual and collision meshes; false when it has neither. `triangles` counts every
// triangle of the robot so far, and the limit holds after each geometry.
bool read_shape(const std::filesystem::path& file, const urdf::Link& link, LinkShape& out, std::size_t& triangles) {
  bool any = false;
  const auto add = [&](TriangleMesh& to, const TriangleMesh& m) {
    triangles += m.triangles.size();
    if (triangles > kMaxArmTriangles)
      fail(file, "more than " + std::to_string(kMaxArmTriangles) + " triangles in the robot's meshes (the limit), at link '" +
                     common::printable(link.name) + "'");
    append(to, m);
  };
  const auto left = [&] { return kMaxArmTriangles - std::min(triangles, kMaxArmTriangles); };
  for (const auto& v : link.visual_array) {
    if (!v) continue;
    add(out.visual, geometry_mesh(file, v->geometry, v->origin, "link '" + common::printable(link.name) + "' visual", left()));
    if (v->material) {
      const auto& c = v->material->color;
      const double grey = (c.r + c.g + c.b) / 3.0;
      if (std::isfinite(grey) && grey > 0) out.albedo = static_cast<float>(std::clamp(grey, 0.02, 1.0));
    }
    any = true;
  }
  for (const auto& c : link.collision_array) {
    if (!c) continue;
    add(out.collision,
        geometry_mesh(file, c->geometry, c->origin, "link '" + common::printable(link.name) + "' collision", left()));
    any = true;
  }
  if (out.collision.triangles.empty()) {
    out.collision = out.visual;
    triangles += out.visual.triangles.size();
    if (triangles > kMaxArmTriangles)
      fail(file, "more than " + std::to_string(kMaxArmTriangles) + " triangles in the robot's meshes (the limit), at link '" +
                     common::printable(link.name) + "'");
  }
  return any;
}

// A number as a URDF should spell it: plain decimal, finite ("nan", "inf" and hex floats are
// not lengths or angles).
bool strict_number(const std::string& tok, double& v) {
  if (tok.empty() || tok.size() > 64 || tok.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
  char* end = nullptr;
  v = std::strtod(tok.c_str(), &end);
  return end == tok.c_str() + tok.size() && std::isfinite(v);
}

// `n` strict numbers separated by white space; "" when they are, else what is wrong.
std::string numbers_problem(const char* text, std::size_t n) {
  std::istringstream in(text ? text : "");
  std::string tok;
  std::size_t count = 0;
  double v = 0;
  while (in >> tok) {
    if (!strict_number(tok, v)) return "'" + common::printable(tok, 32) + "' is not a finite number";
    ++count;
  }
  if (count != n) return "has " + std::to_string(count) + " numbers, expected " + std::to_string(n);
  return "";
}

// Every <visual> and <collision> of every link, walked on the XML itself: urdfdom reads "nan"
// as a number, turns an unreadable origin into the identity and drops an element whose
// geometry it cannot read, so a broken shape used to vanish in silence (issue 18, item 14).
// Returns the number of visual and collision elements per link.
std::map<std::string, std::pair<std::size_t, std::size_t>> check_urdf_geometry(const std::filesystem::path& file,
                                                                               const std::string& text) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(text.c_str(), text.size()) != tinyxml2::XML_SUCCESS)
    fail(file, std::string("not a valid URDF: ") + common::printable(doc.ErrorStr() ? doc.ErrorStr() : "XML error", 160));
  const tinyxml2::XMLElement* robot = doc.FirstChildElement("robot");
  if (!robot) fail(file, "not a valid URDF: no <robot> element");
  std::map<std::string, std::pair<std::size_t, std::size_t>> counts;
  for (const auto* link = robot->FirstChildElement("link"); link; link = link->NextSiblingElement("link")) {
    const char* name_attr = link->Attribute("name");
    const std::string name = name_attr ? name_attr : "";
    auto& count = counts[name];
    for (const auto* e = link->FirstChildElement(); e; e = e->NextSiblingElement()) {
      const std::string kind = e->Name();
      if (kind != "visual" && kind != "collision") continue;
      (kind == "visual" ? count.first : count.second)++;
      const std::string where = "link '" + common::printable(name) + "' " + kind + " " +
                                std::to_string(kind == "visual" ? count.first : count.second);
      const auto check = [&](const tinyxml2::XMLElement* el, const char* attr, std::size_t n, bool required) {
        const char* v = el->Attribute(attr);
        if (!v) {
          if (required) fail(file, where + ": <" + el->Name() + "> has no " + attr);
          return;
        }
        if (const std::string bad = numbers_problem(v, n); !bad.empty())
          fail(file, where + ": <" + el->Name() + "> " + attr + " " + bad);
      };
      if (const auto* o = e->FirstChildElement("origin")) {
        check(o, "xyz", 3, false);
        check(o, "rpy", 3, false);
      }
      const auto* g = e->FirstChildElement("geometry");
      if (!g) fail(file, where + ": no <geometry>");
      const auto* shape = g->FirstChildElement();
      if (!shape) fail(file, where + ": <geometry> is empty");
      if (shape->NextSiblingElement()) fail(file, where + ": <geometry> holds more than one shape");
      const std::string type = shape->Name();
      if (type == "box") {
        check(shape, "size", 3, true);
      } else if (type == "cylinder") {
        check(shape, "radius", 1, true);
        check(shape, "length", 1, true);
      } else if (type == "sphere") {
        check(shape, "radius", 1, true);
      } else if (type == "mesh") {
        if (!shape->Attribute("filename")) fail(file, where + ": <mesh> has no filename");
        check(shape, "scale", 3, false);
      } else {
        fail(file, where + ": unsupported geometry <" + common::printable(type, 32) + ">");
      }
    }
  }
  return counts;
}

// The XML walked before any parser sees it: TinyXML2 recurses once per nesting level (a
// file of 140 000 nested elements overflows the stack), and DTDs (entity expansion) have no
// place in a URDF. Returns what is wrong, or "".
std::string check_xml_structure(const std::string& text) {
  std::size_t depth = 0, elements = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const unsigned char ch = static_cast<unsigned char>(text[i]);
    if (ch == 0) return "a NUL byte at offset " + std::to_string(i);
    if (ch != '<') continue;
    if (text.compare(i, 4, "<!--") == 0) {
      const std::size_t end = text.find("-->", i + 4);
      if (end == std::string::npos) return "a comment that never ends";
      i = end + 2;
      continue;
    }
    if (text.compare(i, 9, "<![CDATA[") == 0) {
      const std::size_t end = text.find("]]>", i + 9);
      if (end == std::string::npos) return "a CDATA section that never ends";
      i = end + 2;
      continue;
    }
    if (i + 1 < text.size() && text[i + 1] == '!') return "a DTD or declaration (<!...>): not allowed in a URDF";
    if (i + 1 < text.size() && text[i + 1] == '?') {
      const std::size_t end = text.find("?>", i + 2);
      if (end == std::string::npos) return "a processing instruction that never ends";
      i = end + 1;
      continue;
    }
    const std::size_t close = text.find('>', i + 1);
    if (close == std::string::npos) return "a tag that never ends";
    if (text[i + 1] == '/') {
      if (depth == 0) return "a closing tag without its opening one";
      --depth;
    } else if (text[close - 1] != '/') {
      if (++depth > kMaxUrdfDepth) return "elements nested deeper than " + std::to_string(kMaxUrdfDepth) + " levels";
      ++elements;
    } else {
      ++elements;
    }
    if (elements > kMaxUrdfElements) return "more than " + std::to_string(kMaxUrdfElements) + " elements";
    i = close;
  }
  return "";
}

}  // namespace

int RobotModel::dof() const {
  int n = 0;
  for (const auto& s : chain) n += s.type != JointType::kFixed;
  return n;
}

std::vector<std::string> RobotModel::joint_names() const {
  std::vector<std::string> names;
  for (const auto& s : chain)
    if (s.type != JointType::kFixed) names.push_back(s.joint);
  return names;
}

namespace {
template <typename F>
Eigen::VectorXd per_joint(const RobotModel& m, F f) {
  Eigen::VectorXd v(m.dof());
  int i = 0;
  for (const auto& s : m.chain)
    if (s.type != JointType::kFixed) v[i++] = f(s);
  return v;
}
}  // namespace

Eigen::VectorXd RobotModel::lower_limits() const { return per_joint(*this, [](const ChainSegment& s) { return s.lower; }); }
Eigen::VectorXd RobotModel::upper_limits() const { return per_joint(*this, [](const ChainSegment& s) { return s.upper; }); }
Eigen::VectorXd RobotModel::velocity_limits() const {
  return per_joint(*this, [](const ChainSegment& s) { return s.max_velocity; });
}
Eigen::VectorXd RobotModel::effort_limits() const {
  return per_joint(*this, [](const ChainSegment& s) { return s.max_effort; });
}

namespace {

// urdfdom's parse, its console output captured: its first error is the one line we give
urdf::ModelInterfaceSharedPtr parse_urdf(const std::filesystem::path& file, const std::string& text) {
  urdf::ModelInterfaceSharedPtr urdf;
  std::lock_guard<std::mutex> lock(console_mutex());
  CapturedLog captured;
  console_bridge::useOutputHandler(&captured);
  try {
    urdf = urdf::parseURDF(text);
  } catch (const std::exception& e) {
    captured.first_error = e.what();
  }
  console_bridge::restorePreviousOutputHandler();
  if (!urdf)
    fail(file, "not a valid URDF: " +
                   common::printable(captured.first_error.empty() ? "parse error" : captured.first_error, 160));
  return urdf;
}

// from the camera link up to the root: the serial chain, root first
std::vector<urdf::LinkConstSharedPtr> chain_to(const std::filesystem::path& file, const urdf::ModelInterface& urdf,
                                               const urdf::LinkConstSharedPtr& tip, const std::string& camera_link) {
  std::vector<urdf::LinkConstSharedPtr> links{tip};
  while (links.back()->parent_joint) {
    if (links.size() > kMaxChainSegments)
      fail(file, "more than " + std::to_string(kMaxChainSegments) + " links from the root to '" + camera_link + "'");
    urdf::LinkConstSharedPtr parent = urdf.getLink(links.back()->parent_joint->parent_link_name);
    if (!parent) fail(file, "joint '" + links.back()->parent_joint->name + "' has no parent link");
    links.push_back(parent);
  }
  std::reverse(links.begin(), links.end());
  return links;
}

// One joint of the chain and the link it carries, checked: type, axis, limits, inertia.
ChainSegment read_segment(const std::filesystem::path& file, const urdf::Link& link) {
  const urdf::Joint& j = *link.parent_joint;
  ChainSegment s;
  s.joint = j.name;
  s.link = link.name;
  const std::string where = "joint '" + j.name + "'";
  s.parent_T_origin = to_iso(j.parent_to_joint_origin_transform);
  if (!finite_pose(s.parent_T_origin)) fail(file, where + ": origin must be finite, within 100 m");
  switch (j.type) {
    case urdf::Joint::FIXED: s.type = JointType::kFixed; break;
    case urdf::Joint::REVOLUTE: s.type = JointType::kRevolute; break;
    case urdf::Joint::CONTINUOUS:
      s.type = JointType::kRevolute;
      s.continuous = true;
      break;
    case urdf::Joint::PRISMATIC: s.type = JointType::kPrismatic; break;
    default: fail(file, where + ": only fixed, revolute, continuous and prismatic joints are supported");
  }
  if (s.type != JointType::kFixed) {
    s.axis = Eigen::Vector3d(j.axis.x, j.axis.y, j.axis.z);
    // scaled by its largest component before normalising: (1e300, 0, 1) has a norm that
    // overflows to infinity, and dividing by it gave a zero axis (the fuzzer found it)
    const double largest = s.axis.allFinite() ? s.axis.cwiseAbs().maxCoeff() : 0.0;
    if (!(largest > 0) || (s.axis / largest).norm() < 1e-9 || !std::isfinite(largest))
      fail(file, where + ": axis must be a finite non-zero vector");
    s.axis = (s.axis / largest).normalized();
    if (!j.limits) fail(file, where + ": no <limit> (velocity and effort limits are required)");
    s.max_velocity = j.limits->velocity;
    s.max_effort = j.limits->effort;
    if (!(s.max_velocity > 0 && s.max_velocity <= 100)) fail(file, where + ": velocity limit must be in (0, 100]");
    if (!(s.max_effort > 0 && s.max_effort <= 1e5)) fail(file, where + ": effort limit must be in (0, 1e5]");
    if (s.continuous) {
      s.lower = -2 * kPi;
      s.upper = 2 * kPi;
    } else {
      s.lower = j.limits->lower;
      s.upper = j.limits->upper;
      const double range = s.type == JointType::kRevolute ? 4 * kPi : 100.0;
      if (!(std::isfinite(s.lower) && std::isfinite(s.upper) && s.lower < s.upper && s.lower >= -range && s.upper <= range))
        fail(file, where + ": position limits must be finite with lower < upper (and within +-4 pi rad)");
    }
  }
  if (link.inertial) {
    const urdf::Inertial& in = *link.inertial;
    s.mass = in.mass;
    s.com = Eigen::Vector3d(in.origin.position.x, in.origin.position.y, in.origin.position.z);
    s.inertia_diagonal = Eigen::Vector3d(in.ixx, in.iyy, in.izz);
    if (!(s.mass >= 1e-6 && s.mass <= 1e4) || !s.com.allFinite() || s.com.norm() > 10 || !s.inertia_diagonal.allFinite() ||
        s.inertia_diagonal.minCoeff() < 1e-9 || s.inertia_diagonal.maxCoeff() > 1e4)
      fail(file, "link '" + link.name +
                     "': inertial mass must be in [1e-6, 1e4] kg, its origin within 10 m, its diagonal inertia in "
                     "[1e-9, 1e4] kg m^2");
  }
  return s;
}

}  // namespace

RobotModel load_robot_model(const std::filesystem::path& file, const std::string& camera_link) {
  RobotModel model;
  model.file = file;
  try {
    model.urdf = common::read_regular_file(file, kMaxUrdfBytes, "robot description");
  } catch (const common::FileError& e) {
    throw RobotModelError(e.what());
  }
  if (const std::string bad = check_xml_structure(model.urdf); !bad.empty()) fail(file, "not a valid URDF: " + bad);
  const auto geometry_counts = check_urdf_geometry(file, model.urdf);
  model.camera_link = camera_link;
  const urdf::ModelInterfaceSharedPtr urdf = parse_urdf(file, model.urdf);
  for (const auto& [name, count] : geometry_counts) {
    const urdf::LinkConstSharedPtr link = urdf->getLink(name);
    if (link && (link->visual_array.size() != count.first || link->collision_array.size() != count.second))
      fail(file, "link '" + common::printable(name) + "': " + std::to_string(count.first) + " visual and " +
                     std::to_string(count.second) + " collision elements, but the URDF parser read " +
                     std::to_string(link->visual_array.size()) + " and " + std::to_string(link->collision_array.size()));
  }
  model.name = urdf->getName();
  urdf::LinkConstSharedPtr tip = urdf->getLink(camera_link);
  if (!tip) fail(file, "no link named '" + common::printable(camera_link) + "' (the camera link)");

  const std::vector<urdf::LinkConstSharedPtr> links = chain_to(file, *urdf, tip, camera_link);
  model.root_link = links.front()->name;
  std::size_t triangles = 0;
  model.root_has_shape = read_shape(file, *links.front(), model.root_shape, triangles);
  for (std::size_t i = 1; i < links.size(); ++i) {
    ChainSegment s = read_segment(file, *links[i]);
    s.has_shape = read_shape(file, *links[i], s.shape, triangles);
    model.chain.push_back(std::move(s));
  }
  if (model.dof() == 0) fail(file, "no moving joint between the root and '" + camera_link + "'");
  return model;
}

}  // namespace sim
