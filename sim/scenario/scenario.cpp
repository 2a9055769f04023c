#include "sim/scenario/scenario.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <sstream>

#include "sim/geometry/se3.hpp"

namespace sim {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// Walks the YAML tree with the key path at hand, so every error names file and key.
class Reader {
 public:
  Reader(const std::filesystem::path& file, YAML::Node node, std::string path)
      : file_(file), node_(std::move(node)), path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw ScenarioError(file_.string() + ": " + (path_.empty() ? "(top level)" : path_) + ": " + what);
  }

  // Rejects keys not in `allowed`: a misspelt key must not be silently ignored.
  void only_keys(std::initializer_list<const char*> allowed) const {
    if (!node_.IsMap()) fail("must be a mapping");
    const std::set<std::string> ok(allowed.begin(), allowed.end());
    for (const auto& kv : node_) {
      const std::string key = kv.first.as<std::string>();
      if (!ok.count(key)) {
        std::string list;
        for (const auto& k : ok) list += (list.empty() ? "" : ", ") + k;
        child_path_fail(key, "unknown key (expected one of: " + list + ")");
      }
    }
  }

  bool has(const char* key) const { return node_.IsMap() && node_[key]; }

  Reader at(const char* key) const {
    if (!has(key)) child_path_fail(key, "missing");
    return Reader(file_, node_[key], join(key));
  }
  Reader at(std::size_t i) const { return Reader(file_, node_[i], path_ + "[" + std::to_string(i) + "]"); }
  std::size_t size() const {
    if (!node_.IsSequence()) fail("must be a list");
    return node_.size();
  }

  double number() const {
    if (!node_.IsScalar()) fail("must be a number");
    double v;
    try {
      v = node_.as<double>();
    } catch (const YAML::Exception&) {
      fail("must be a number, got '" + node_.Scalar() + "'");
    }
    if (!std::isfinite(v)) fail("must be a finite number, got '" + node_.Scalar() + "'");
    return v;
  }
  double positive() const {
    const double v = number();
    if (!(v > 0)) fail("must be positive, got " + node_.Scalar());
    return v;
  }
  double non_negative() const {
    const double v = number();
    if (v < 0) fail("must be >= 0, got " + node_.Scalar());
    return v;
  }
  double in_range(double lo, double hi) const {
    const double v = number();
    if (v < lo || v > hi) {
      std::ostringstream s;
      s << "must be in [" << lo << ", " << hi << "], got " << node_.Scalar();
      fail(s.str());
    }
    return v;
  }
  int integer() const {
    const double v = number();
    if (v != std::floor(v) || std::abs(v) > 1e9) fail("must be an integer, got " + node_.Scalar());
    return static_cast<int>(v);
  }
  std::uint64_t unsigned_integer() const {
    if (!node_.IsScalar()) fail("must be a non-negative integer");
    try {
      return node_.as<std::uint64_t>();
    } catch (const YAML::Exception&) {
      fail("must be a non-negative integer, got '" + node_.Scalar() + "'");
    }
  }
  std::string text() const {
    if (!node_.IsScalar()) fail("must be a string");
    return node_.Scalar();
  }
  template <std::size_t N>
  std::array<double, N> numbers() const {
    if (!node_.IsSequence() || node_.size() != N) fail("must be a list of " + std::to_string(N) + " numbers");
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) out[i] = at(i).number();
    return out;
  }
  Eigen::Vector3d vec3() const {
    const auto a = numbers<3>();
    return {a[0], a[1], a[2]};
  }
  // A file path, resolved against the scenario file's folder, that must exist.
  std::filesystem::path existing_file() const {
    std::filesystem::path p = text();
    if (p.is_relative()) p = file_.parent_path() / p;
    p = p.lexically_normal();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(p, ec)) fail("file not found: " + p.string());
    return p;
  }

  const std::string& path() const { return path_; }

 private:
  std::string join(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  [[noreturn]] void child_path_fail(const std::string& key, const std::string& what) const {
    throw ScenarioError(file_.string() + ": " + join(key) + ": " + what);
  }

  std::filesystem::path file_;
  YAML::Node node_;
  std::string path_;
};

// position_m + (rotation_deg | look_at_m [+ up])
Eigen::Isometry3d read_pose(const Reader& r, const Eigen::Vector3d& default_up) {
  r.only_keys({"position_m", "rotation_deg", "look_at_m", "up"});
  const Eigen::Vector3d p = r.at("position_m").vec3();
  if (r.has("look_at_m")) {
    if (r.has("rotation_deg")) r.fail("give either rotation_deg or look_at_m, not both");
    const Eigen::Vector3d target = r.at("look_at_m").vec3();
    if ((target - p).norm() < 1e-9) r.fail("look_at_m equals position_m");
    const Eigen::Vector3d up = r.has("up") ? r.at("up").vec3() : default_up;
    if (up.norm() < 1e-9) r.fail("up must not be zero");
    return look_at(p, target, up.normalized());
  }
  if (r.has("up")) r.fail("up only goes with look_at_m");
  const auto rot = r.has("rotation_deg") ? r.at("rotation_deg").numbers<3>() : std::array<double, 3>{0, 0, 0};
  return pose_from_xyz_rxyz(p.x(), p.y(), p.z(), rot[0] * kDeg, rot[1] * kDeg, rot[2] * kDeg);
}

Intrinsics read_intrinsics(const Reader& r, Intrinsics in) {
  const Reader res = r.at("resolution");
  const auto wh = res.numbers<2>();
  for (int i = 0; i < 2; ++i) {
    const Reader d = res.at(static_cast<std::size_t>(i));
    if (d.integer() < 8 || d.integer() > 16384) d.fail("image size must be an integer in 8..16384");
  }
  in.width = static_cast<int>(wh[0]);
  in.height = static_cast<int>(wh[1]);
  if (r.has("focal_px")) {
    const auto f = r.at("focal_px").numbers<2>();
    for (int i = 0; i < 2; ++i) r.at("focal_px").at(static_cast<std::size_t>(i)).positive();
    in.fx = f[0];
    in.fy = f[1];
  } else if (r.has("fov_deg")) {
    const double fov = r.at("fov_deg").in_range(1, 170);
    in.fx = in.fy = 0.5 * in.width / std::tan(0.5 * fov * kDeg);
  } else {
    r.fail("give focal_px [fx, fy] or fov_deg (horizontal)");
  }
  if (r.has("principal_point_px")) {
    const auto c = r.at("principal_point_px").numbers<2>();
    in.cx = c[0];
    in.cy = c[1];
  } else {
    in.cx = 0.5 * (in.width - 1);
    in.cy = 0.5 * (in.height - 1);
  }
  return in;
}

}  // namespace

Eigen::Isometry3d offset_pose(const Eigen::Isometry3d& world_T_desired, const std::array<double, 3>& t_cm,
                              const std::array<double, 3>& r_deg, const std::array<double, 3>& f_deg) {
  const Eigen::Isometry3d d_T_f = pose_from_xyz_rxyz(0, 0, 0, f_deg[0] * kDeg, f_deg[1] * kDeg, f_deg[2] * kDeg);
  const Eigen::Isometry3d motion = pose_from_xyz_rxyz(t_cm[0] / 100, t_cm[1] / 100, t_cm[2] / 100, r_deg[0] * kDeg,
                                                      r_deg[1] * kDeg, r_deg[2] * kDeg);
  return world_T_desired * d_T_f * motion * d_T_f.inverse();
}

Eigen::Isometry3d Scenario::world_T_initial() const {
  return offset_pose(world_T_desired, initial_translation_cm, initial_rotation_deg, offset_frame_rotation_deg);
}

Scenario load_scenario(const std::filesystem::path& file) {
  YAML::Node root;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw ScenarioError(file.string() + ": scenario file not found");
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw ScenarioError(file.string() + ": line " + std::to_string(e.mark.line + 1) + ": YAML syntax error: " + e.msg);
  }
  Scenario s;
  s.file = std::filesystem::absolute(file).lexically_normal();
  const Reader top(s.file, root, "");
  top.only_keys({"name", "seed", "timing", "objects", "projector", "camera", "robot", "desired_pose", "initial_offset"});
  s.name = top.at("name").text();
  s.seed = top.at("seed").unsigned_integer();

  if (top.has("timing")) {
    const Reader t = top.at("timing");
    t.only_keys({"dt_s"});
    s.dt_s = t.at("dt_s").positive();
  }

  const Reader objs = top.at("objects");
  if (objs.size() == 0) objs.fail("needs at least one object");
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const Reader o = objs.at(i);
    o.only_keys({"name", "mesh", "position_m", "rotation_deg", "albedo"});
    ObjectSpec spec;
    spec.name = o.has("name") ? o.at("name").text() : "object" + std::to_string(i);
    spec.mesh = o.at("mesh").existing_file();
    const Eigen::Vector3d p = o.at("position_m").vec3();
    const auto r = o.has("rotation_deg") ? o.at("rotation_deg").numbers<3>() : std::array<double, 3>{0, 0, 0};
    spec.world_T_object = pose_from_xyz_rxyz(p.x(), p.y(), p.z(), r[0] * kDeg, r[1] * kDeg, r[2] * kDeg);
    if (o.has("albedo")) spec.albedo = o.at("albedo").in_range(0, 1);
    s.objects.push_back(spec);
  }

  {
    const Reader p = top.at("projector");
    p.only_keys({"pose", "resolution", "focal_px", "fov_deg", "principal_point_px", "pattern", "spot_pitch_px",
                 "spot_radius_px", "brightness", "focus_range_m", "defocus_px_per_m", "focused_blur_px", "only_spots"});
    ProjectorSpec& pr = s.projector;
    pr.world_T_projector = read_pose(p.at("pose"), Eigen::Vector3d::UnitZ());
    pr.intrinsics = read_intrinsics(p, pr.intrinsics);
    pr.pattern = p.at("pattern").existing_file();
    pr.spot_pitch_px = p.at("spot_pitch_px").positive();
    pr.spot_radius_px = p.at("spot_radius_px").positive();
    if (pr.spot_radius_px >= 0.5 * pr.spot_pitch_px) p.at("spot_radius_px").fail("must be less than half spot_pitch_px (spots would merge)");
    if (p.has("brightness")) pr.brightness = p.at("brightness").positive();
    if (p.has("focus_range_m")) {
      const auto f = p.at("focus_range_m").numbers<2>();
      if (!(f[0] > 0 && f[1] >= f[0])) p.at("focus_range_m").fail("must be [near, far] with 0 < near <= far");
      pr.focus_near_m = f[0];
      pr.focus_far_m = f[1];
    }
    if (p.has("defocus_px_per_m")) pr.defocus_px_per_m = p.at("defocus_px_per_m").non_negative();
    if (p.has("focused_blur_px")) pr.focused_blur_px = p.at("focused_blur_px").non_negative();
    if (p.has("only_spots")) {
      const Reader list = p.at("only_spots");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const auto rc = list.at(i).numbers<2>();
        pr.only_spots.push_back({static_cast<int>(rc[0]), static_cast<int>(rc[1])});
      }
    }
  }

  {
    const Reader c = top.at("camera");
    c.only_keys({"resolution", "focal_px", "fov_deg", "principal_point_px", "distortion", "exposure", "ambient",
                 "noise_sigma", "shot_noise", "crosstalk"});
    CameraSpec& cam = s.camera;
    cam.intrinsics = read_intrinsics(c, cam.intrinsics);
    if (c.has("distortion")) cam.distortion = c.at("distortion").numbers<5>();
    if (c.has("exposure")) cam.exposure = c.at("exposure").positive();
    if (c.has("ambient")) cam.ambient = c.at("ambient").in_range(0, 1);
    if (c.has("noise_sigma")) cam.noise_sigma = c.at("noise_sigma").non_negative();
    if (c.has("shot_noise")) cam.shot_noise = c.at("shot_noise").non_negative();
    if (c.has("crosstalk")) cam.crosstalk = c.at("crosstalk").in_range(0, 0.5);
  }

  if (top.has("robot")) {
    const Reader r = top.at("robot");
    r.only_keys({"max_linear_mps", "max_angular_dps"});
    if (r.has("max_linear_mps")) s.robot.max_linear_mps = r.at("max_linear_mps").positive();
    if (r.has("max_angular_dps")) s.robot.max_angular_radps = r.at("max_angular_dps").positive() * kDeg;
  }

  s.world_T_desired = read_pose(top.at("desired_pose"), Eigen::Vector3d::UnitZ());
  if (top.has("initial_offset")) {
    const Reader o = top.at("initial_offset");
    o.only_keys({"translation_cm", "rotation_deg", "frame_rotation_deg"});
    if (o.has("translation_cm")) s.initial_translation_cm = o.at("translation_cm").numbers<3>();
    if (o.has("frame_rotation_deg")) s.offset_frame_rotation_deg = o.at("frame_rotation_deg").numbers<3>();
    if (o.has("rotation_deg")) s.initial_rotation_deg = o.at("rotation_deg").numbers<3>();
  }
  return s;
}

Eigen::Isometry3d resolve_pose(const Scenario& s, const std::string& spec) {
  if (spec == "desired") return s.world_T_desired;
  if (spec == "initial") return s.world_T_initial();
  std::istringstream in(spec);
  std::array<double, 6> v{};
  for (double& x : v)
    if (!(in >> x) || !std::isfinite(x))
      throw std::invalid_argument("pose '" + spec + "': expected desired, initial or six numbers \"x y z rx ry rz\" (cm, deg)");
  std::string rest;
  if (in >> rest) throw std::invalid_argument("pose '" + spec + "': more than six numbers");
  return offset_pose(s.world_T_desired, {v[0], v[1], v[2]}, {v[3], v[4], v[5]}, s.offset_frame_rotation_deg);
}

}  // namespace sim
