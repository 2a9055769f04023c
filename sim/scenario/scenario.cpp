#include "sim/scenario/scenario.hpp"

#include "common/strict_yaml.hpp"

#include <cmath>
#include <set>
#include <sstream>
#include <tuple>

#include "sim/geometry/se3.hpp"

namespace sim {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

using common::Reader;

// a position in the cell, within kMaxCoordinateM of the world origin
Eigen::Vector3d vec3(const Reader& r, double limit = kMaxCoordinateM) {
  const auto a = r.numbers_in<3>(-limit, limit);
  return {a[0], a[1], a[2]};
}

// position_m + (rotation_deg | look_at_m [+ up])
Eigen::Isometry3d read_pose(const Reader& r, const Eigen::Vector3d& default_up) {
  r.only_keys({"position_m", "rotation_deg", "look_at_m", "up"});
  const Eigen::Vector3d p = vec3(r.at("position_m"));
  if (r.has("look_at_m")) {
    if (r.has("rotation_deg")) r.fail("give either rotation_deg or look_at_m, not both");
    const Eigen::Vector3d target = vec3(r.at("look_at_m"));
    if ((target - p).norm() < 1e-9) r.fail("look_at_m equals position_m");
    const Eigen::Vector3d up = r.has("up") ? vec3(r.at("up"), 1.0) : default_up;
    if (up.norm() < 1e-9) r.fail("up must not be zero");
    return look_at(p, target, up.normalized());
  }
  if (r.has("up")) r.fail("up only goes with look_at_m");
  const auto rot = r.has("rotation_deg") ? r.at("rotation_deg").numbers_in<3>(-kMaxAngleDeg, kMaxAngleDeg) : std::array<double, 3>{0, 0, 0};
  return pose_from_xyz_rxyz(p.x(), p.y(), p.z(), rot[0] * kDeg, rot[1] * kDeg, rot[2] * kDeg);
}

Intrinsics read_intrinsics(const Reader& r, Intrinsics in) {
  const Reader res = r.at("resolution");
  if (res.size() != 2) res.fail("must be a list of 2 integers [width, height]");
  in.width = res.at(std::size_t{0}).integer_in(kMinImageSide, kMaxImageSide);
  in.height = res.at(std::size_t{1}).integer_in(kMinImageSide, kMaxImageSide);
  if (static_cast<long long>(in.width) * in.height > kMaxImagePixels)
    res.fail(std::to_string(in.width) + " x " + std::to_string(in.height) + " is more than the limit of " +
             std::to_string(kMaxImagePixels) + " pixels");
  if (r.has("focal_px")) {
    const auto f = r.at("focal_px").numbers_in<2>(kMinFocalPx, kMaxFocalPx);
    in.fx = f[0];
    in.fy = f[1];
  } else if (r.has("fov_deg")) {
    const double fov = r.at("fov_deg").in_range(1, 170);
    in.fx = in.fy = 0.5 * in.width / std::tan(0.5 * fov * kDeg);
  } else {
    r.fail("give focal_px [fx, fy] or fov_deg (horizontal)");
  }
  if (r.has("principal_point_px")) {
    const Reader c = r.at("principal_point_px");
    if (c.size() != 2) c.fail("must be a list of 2 numbers [cx, cy]");
    // within the image, give or take one image size: beyond, no ray of the lens is sane
    in.cx = c.at(std::size_t{0}).in_range(-in.width, 2.0 * in.width);
    in.cy = c.at(std::size_t{1}).in_range(-in.height, 2.0 * in.height);
  } else {
    in.cx = 0.5 * (in.width - 1);
    in.cy = 0.5 * (in.height - 1);
  }
  return in;
}

std::vector<double> joint_list(const Reader& r) {
  std::vector<double> q(r.size_at_most(kMaxJointAngles));
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = r.at(i).in_range(-720, 720) * kDeg;
  return q;
}

// robot: free_flying | {type: free_flying, max_linear_mps, max_angular_dps}
//      | {type: arm, urdf, camera_link, base_pose, home_joints_deg, desired_joints_deg,
//         initial_joints_deg, max_linear_mps, max_angular_dps, controller: {...}}
void read_robot(const Reader& r, RobotSpec& robot) {
  if (r.node().IsScalar()) {
    if (r.text(40) != "free_flying") r.fail("give free_flying, or a map with type: arm or type: free_flying");
    return;
  }
  r.only_keys({"type", "max_linear_mps", "max_angular_dps", "urdf", "camera_link", "base_pose", "home_joints_deg",
               "desired_joints_deg", "initial_joints_deg", "controller"});
  const std::string type = r.has("type") ? r.at("type").text(40) : "free_flying";
  if (type == "arm") robot.arm_enabled = true;
  else if (type != "free_flying") r.at("type").fail("must be arm or free_flying");
  if (r.has("max_linear_mps")) robot.max_linear_mps = r.at("max_linear_mps").in_range(1e-6, 10);
  if (r.has("max_angular_dps")) robot.max_angular_radps = r.at("max_angular_dps").in_range(1e-6, 3600) * kDeg;
  if (!robot.arm_enabled) {
    for (const char* k : {"urdf", "camera_link", "base_pose", "home_joints_deg", "desired_joints_deg", "initial_joints_deg",
                          "controller"})
      if (r.has(k)) r.at(k).fail("only with type: arm");
    return;
  }
  ArmSpec& a = robot.arm;
  a.urdf = r.at("urdf").existing_file();
  if (r.has("camera_link")) a.camera_link = r.at("camera_link").text(200);
  if (r.has("base_pose")) a.world_T_base = read_pose(r.at("base_pose"), Eigen::Vector3d::UnitZ());
  if (r.has("home_joints_deg")) a.home_rad = joint_list(r.at("home_joints_deg"));
  if (r.has("desired_joints_deg")) a.desired_joints_rad = joint_list(r.at("desired_joints_deg"));
  if (r.has("initial_joints_deg")) a.initial_joints_rad = joint_list(r.at("initial_joints_deg"));
  if (r.has("controller")) {
    const Reader c = r.at("controller");
    c.only_keys({"damping", "slowdown_condition", "stop_condition", "joint_margin_deg", "physics_hz"});
    if (c.has("damping")) a.damping = c.at("damping").in_range(1e-6, 10);
    if (c.has("slowdown_condition")) a.slowdown_condition = c.at("slowdown_condition").in_range(1, 1e6);
    if (c.has("stop_condition")) a.stop_condition = c.at("stop_condition").in_range(1, 1e6);
    if (a.stop_condition <= a.slowdown_condition) c.fail("stop_condition must exceed slowdown_condition");
    if (c.has("joint_margin_deg")) a.joint_margin_rad = c.at("joint_margin_deg").in_range(0, 45) * kDeg;
    if (c.has("physics_hz")) a.physics_hz = c.at("physics_hz").in_range(250, 10000);
  }
}

// errors: {focal_pct: 1, hand_eye_rotation_deg: 0.5, seed: 3, ...} (sim/scenario/cell_errors.hpp)
void read_errors(const Reader& r, CalibrationErrors& e) {
  std::vector<std::string> names = error_names();
  names.push_back("seed");
  r.only_keys(names);
  if (r.has("seed")) e.seed = r.at("seed").unsigned_integer();
  for (const std::string& name : error_names())
    if (r.has(name.c_str())) try {
        set_error(e, name, r.at(name.c_str()).in_range(0, 1e6));
      } catch (const std::invalid_argument& ex) {
        r.at(name.c_str()).fail(ex.what());
      }
}

void read_objects(const Reader& top, Scenario& s) {
  const Reader objs = top.at("objects");
  if (objs.size_at_most(kMaxObjects) == 0) objs.fail("needs at least one object");
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const Reader o = objs.at(i);
    o.only_keys({"name", "mesh", "position_m", "rotation_deg", "albedo", "scale"});
    ObjectSpec spec;
    spec.name = o.has("name") ? o.at("name").text(200) : "object" + std::to_string(i);
    spec.mesh = o.at("mesh").existing_file();
    const Eigen::Vector3d p = vec3(o.at("position_m"));
    const auto r = o.has("rotation_deg") ? o.at("rotation_deg").numbers_in<3>(-kMaxAngleDeg, kMaxAngleDeg)
                                         : std::array<double, 3>{0, 0, 0};
    spec.world_T_object = pose_from_xyz_rxyz(p.x(), p.y(), p.z(), r[0] * kDeg, r[1] * kDeg, r[2] * kDeg);
    if (o.has("albedo")) {
      const Reader a = o.at("albedo");
      if (a.node().IsSequence()) {
        const auto rgb = a.numbers_in<3>(0, 1);  // [r, g, b]
        spec.albedo = {rgb[0], rgb[1], rgb[2]};
      } else {
        spec.albedo = Eigen::Vector3d::Constant(a.in_range(0, 1));  // grey
      }
    }
    if (o.has("scale")) {
      const auto k = o.at("scale").numbers_in<3>(0.01, 100);
      spec.scale = {k[0], k[1], k[2]};
    }
    s.objects.push_back(spec);
  }

}

void read_projector(const Reader& p, ProjectorSpec& pr) {
  p.only_keys({"mount", "pose", "resolution", "focal_px", "fov_deg", "principal_point_px", "pattern", "spot_pitch_px",
               "spot_radius_px", "brightness", "focus_range_m", "defocus_px_per_m", "focused_blur_px", "only_spots"});
  const std::string mount = p.has("mount") ? p.at("mount").text(16) : "world";
  if (mount == "camera")
    pr.on_camera = read_pose(p.at("pose"), -Eigen::Vector3d::UnitY());  // the camera frame's up is -Y
  else if (mount == "world")
    pr.world_T_projector = read_pose(p.at("pose"), Eigen::Vector3d::UnitZ());
  else
    p.at("mount").fail("must be world or camera");
  pr.intrinsics = read_intrinsics(p, pr.intrinsics);
  pr.pattern = p.at("pattern").existing_file();
  pr.spot_pitch_px = p.at("spot_pitch_px").in_range(1, 1000);
  pr.spot_radius_px = p.at("spot_radius_px").in_range(0.1, 500);
  if (pr.spot_radius_px >= 0.5 * pr.spot_pitch_px) p.at("spot_radius_px").fail("must be less than half spot_pitch_px (spots would merge)");
  if (p.has("brightness")) pr.brightness = p.at("brightness").in_range(1e-6, 1e3);
  if (p.has("focus_range_m")) {
    const auto f = p.at("focus_range_m").numbers_in<2>(0, kMaxCoordinateM);
    if (!(f[0] > 0 && f[1] >= f[0])) p.at("focus_range_m").fail("must be [near, far] with 0 < near <= far");
    pr.focus_near_m = f[0];
    pr.focus_far_m = f[1];
  }
  if (p.has("defocus_px_per_m")) pr.defocus_px_per_m = p.at("defocus_px_per_m").in_range(0, 1e3);
  if (p.has("focused_blur_px")) pr.focused_blur_px = p.at("focused_blur_px").in_range(0, 100);
  if (p.has("only_spots")) {
    const Reader list = p.at("only_spots");
    for (std::size_t i = 0; i < list.size_at_most(kMaxPatternSide * kMaxPatternSide); ++i) {
      const Reader rc = list.at(i);
      if (rc.size() != 2) rc.fail("must be [row, col]");
      pr.only_spots.push_back({rc.at(std::size_t{0}).integer_in(0, kMaxPatternSide - 1),
                               rc.at(std::size_t{1}).integer_in(0, kMaxPatternSide - 1)});
    }
  }
}

void read_camera(const Reader& c, CameraSpec& cam) {
  c.only_keys({"resolution", "focal_px", "fov_deg", "principal_point_px", "distortion", "exposure", "ambient",
               "noise_sigma", "shot_noise", "crosstalk"});
  cam.intrinsics = read_intrinsics(c, cam.intrinsics);
  if (c.has("distortion")) cam.distortion = c.at("distortion").numbers_in<5>(-kMaxDistortion, kMaxDistortion);
  if (c.has("exposure")) cam.exposure = c.at("exposure").in_range(1e-6, 1e3);
  if (c.has("ambient")) cam.ambient = c.at("ambient").in_range(0, 1);
  if (c.has("noise_sigma")) cam.noise_sigma = c.at("noise_sigma").in_range(0, 255);
  if (c.has("shot_noise")) cam.shot_noise = c.at("shot_noise").in_range(0, 255);
  // beyond 0.3 a primary keeps under a tenth of its chroma (at 1/3 none): no decoder tells the colours
  if (c.has("crosstalk")) cam.crosstalk = c.at("crosstalk").in_range(0, 0.3);
}

void read_initial_offset(const Reader& top, Scenario& s) {
  if (top.has("initial_offset")) {
    const Reader o = top.at("initial_offset");
    o.only_keys({"translation_cm", "rotation_deg", "frame_rotation_deg"});
    if (o.has("translation_cm"))
      s.initial_translation_cm = o.at("translation_cm").numbers_in<3>(-100 * kMaxCoordinateM, 100 * kMaxCoordinateM);
    if (o.has("frame_rotation_deg"))
      s.offset_frame_rotation_deg = o.at("frame_rotation_deg").numbers_in<3>(-kMaxAngleDeg, kMaxAngleDeg);
    if (o.has("rotation_deg")) s.initial_rotation_deg = o.at("rotation_deg").numbers_in<3>(-kMaxAngleDeg, kMaxAngleDeg);
  }

}

void read_latency(const Reader& top, Scenario& s) {
  if (top.has("latency")) {
    const Reader l = top.at("latency");
    l.only_keys({"acquisition_frames", "processing_frames", "actuation_s"});
    for (const std::string& name : latency_names())
      if (l.has(name.c_str())) try {
          set_latency(s.latency, name, l.at(name.c_str()).in_range(0, 1e6));
        } catch (const std::invalid_argument& e) {
          l.at(name.c_str()).fail(e.what());
        }
  }

}

// the camera's workspace, when given (settle_workspace gives the default)
void read_workspace(const Reader& top, Scenario& s) {
  if (!top.has("workspace")) return;
  const Reader w = top.at("workspace");
  w.only_keys({"min_m", "max_m"});
  s.workspace.min_m = vec3(w.at("min_m"));
  s.workspace.max_m = vec3(w.at("max_m"));
  if ((s.workspace.max_m - s.workspace.min_m).minCoeff() <= 0) w.fail("max_m must exceed min_m on every axis");
  s.workspace_given = true;
}

Scenario read_scenario_yaml(const std::filesystem::path& file) {
  const YAML::Node root = common::load_yaml_file(file, "scenario file");
  Scenario s;
  s.file = std::filesystem::absolute(file).lexically_normal();
  const Reader top(s.file, root, "");
  top.only_keys({"name", "seed", "timing", "objects", "projector", "camera", "robot", "desired_pose", "initial_offset",
                 "workspace", "errors", "latency"});
  s.name = top.at("name").text(200);
  s.seed = top.at("seed").unsigned_integer();
  if (top.has("timing")) {
    const Reader t = top.at("timing");
    t.only_keys({"dt_s"});
    s.dt_s = t.at("dt_s").in_range(kMinDtS, kMaxDtS);
  }
  read_objects(top, s);
  read_projector(top.at("projector"), s.projector);
  read_camera(top.at("camera"), s.camera);
  if (top.has("robot")) read_robot(top.at("robot"), s.robot);
  if (top.has("desired_pose") || s.robot.arm.desired_joints_rad.empty())
    s.world_T_desired = read_pose(top.at("desired_pose"), Eigen::Vector3d::UnitZ());
  read_initial_offset(top, s);
  if (top.has("errors")) read_errors(top.at("errors"), s.errors);
  read_latency(top, s);
  read_workspace(top, s);
  s.has_desired_pose = top.has("desired_pose");
  s.has_initial_offset = top.has("initial_offset");
  return s;
}

}  // namespace

Eigen::Isometry3d offset_pose(const Eigen::Isometry3d& world_T_desired, const std::array<double, 3>& t_cm,
                              const std::array<double, 3>& r_deg, const std::array<double, 3>& f_deg) {
  const Eigen::Isometry3d d_T_f = pose_from_xyz_rxyz(0, 0, 0, f_deg[0] * kDeg, f_deg[1] * kDeg, f_deg[2] * kDeg);
  const Eigen::Isometry3d motion = pose_from_xyz_rxyz(t_cm[0] / 100, t_cm[1] / 100, t_cm[2] / 100, r_deg[0] * kDeg,
                                                      r_deg[1] * kDeg, r_deg[2] * kDeg);
  return world_T_desired * d_T_f * motion * d_T_f.inverse();
}

DrawnErrors scenario_errors(const Scenario& s, const CalibrationErrors& errors, std::uint64_t seed) {
  return draw_errors(errors, seed, s.robot.chain_segments);
}

DrawnErrors scenario_errors(const Scenario& s) { return scenario_errors(s, s.errors, s.seed); }

CameraSpec believed_camera(const CameraSpec& truth, const DrawnErrors& d) {
  CameraSpec c = truth;
  c.intrinsics.fx *= d.fx_scale;
  c.intrinsics.fy *= d.fy_scale;
  c.intrinsics.cx += d.principal_shift_px.x();
  c.intrinsics.cy += d.principal_shift_px.y();
  c.distortion[0] += d.k1_shift;
  return c;
}


Eigen::Isometry3d Scenario::world_T_initial() const {
  if (initial_pose) return *initial_pose;
  return offset_pose(world_T_desired, initial_translation_cm, initial_rotation_deg, offset_frame_rotation_deg);
}

Scenario read_scenario(const std::filesystem::path& file) {
  try {
    Scenario s = read_scenario_yaml(file);
    if (!s.robot.arm_enabled) settle_workspace(s);  // an arm's poses are known once it is resolved
    return s;
  } catch (const common::ConfigError& e) {
    throw ScenarioError(e.what());
  }
}

void settle_workspace(Scenario& s) {
  if (!s.workspace_given) {
    const Eigen::Vector3d a = s.world_T_desired.translation();
    const Eigen::Vector3d b = s.world_T_initial().translation();
    s.workspace.min_m = a.cwiseMin(b) - Eigen::Vector3d::Constant(kDefaultWorkspaceMarginM);
    s.workspace.max_m = a.cwiseMax(b) + Eigen::Vector3d::Constant(kDefaultWorkspaceMarginM);
  }
  for (const auto& [name, given, pose] :
       {std::tuple<const char*, bool, Eigen::Isometry3d>{"desired_pose", s.has_desired_pose, s.world_T_desired},
        {"initial_offset", s.has_initial_offset, s.world_T_initial()}})
    if (!s.workspace.contains(pose.translation()))
      throw ScenarioError(s.file.string() + ": " + (given ? name : "robot") + ": " + name +
                          ": the camera would be outside the workspace");
}

Eigen::Isometry3d resolve_pose(const Scenario& s, const std::string& spec) {
  if (spec == "desired") return s.world_T_desired;
  if (spec == "initial") return s.world_T_initial();
  const std::string shown = common::printable(spec);
  if (spec.size() > 200) throw std::invalid_argument("pose '" + shown + "': more than 200 characters");
  std::istringstream in(spec);
  std::array<double, 6> v{};
  for (double& x : v)
    if (!(in >> x) || !std::isfinite(x))
      throw std::invalid_argument("pose '" + shown + "': expected desired, initial or six numbers \"x y z rx ry rz\" (cm, deg)");
  std::string rest;
  if (in >> rest) throw std::invalid_argument("pose '" + shown + "': more than six numbers");
  for (int i = 3; i < 6; ++i)
    if (std::abs(v[i]) > kMaxAngleDeg) throw std::invalid_argument("pose '" + shown + "': a rotation beyond 3600 deg");
  for (int i = 0; i < 3; ++i)
    if (std::abs(v[i]) > 100 * kMaxCoordinateM)
      throw std::invalid_argument("pose '" + shown + "': a translation beyond 100 m");
  const Eigen::Isometry3d pose =
      offset_pose(s.world_T_desired, {v[0], v[1], v[2]}, {v[3], v[4], v[5]}, s.offset_frame_rotation_deg);
  if (!s.workspace.contains(pose.translation())) {
    std::ostringstream m;
    m << "pose '" << shown << "': the camera would be at (" << pose.translation().transpose()
      << ") m, outside the workspace [" << s.workspace.min_m.transpose() << "] .. [" << s.workspace.max_m.transpose()
      << "]";
    throw std::invalid_argument(m.str());
  }
  return pose;
}

}  // namespace sim
