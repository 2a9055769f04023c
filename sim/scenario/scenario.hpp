// A scenario: the cell (objects, projector, camera), the task (desired and initial camera
// poses), timing and the seed. Plain data, read from YAML by read_scenario: the spec as the
// file gives it, with no URDF read and no IK run (sim/cell/build_cell.hpp's load_scenario
// resolves the arm).
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim/scenario/cell_errors.hpp"
#include "sim/geometry/workspace.hpp"

namespace sim {

struct RobotModel;  // sim/arm/robot_model.hpp: what a URDF describes

// a joint-angle list's longest (an arm's chain has at most as many segments)
inline constexpr std::size_t kMaxJointAngles = 32;

// A malformed scenario. what() is one line: "<file>: <key>: <what is wrong>".
class ScenarioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Limits every scenario is checked against at load (docs/topics.md, Safety): beyond them a
// frame would take gigabytes or a step would divide by almost nothing.
inline constexpr int kMinImageSide = 8;
inline constexpr int kMaxImageSide = 4096;
inline constexpr long long kMaxImagePixels = 4096LL * 2304;  // 4K UHD fits
inline constexpr double kMinFocalPx = 1.0, kMaxFocalPx = 1e5;
inline constexpr double kMaxDistortion = 10.0;               // |k1..k3|, |p1|, |p2|
inline constexpr double kMinDtS = 1e-4, kMaxDtS = 1.0;       // camera period
inline constexpr std::size_t kMaxObjects = 64;
inline constexpr double kMaxCoordinateM = 100.0;             // |x|, |y|, |z| of anything placed
inline constexpr double kMaxAngleDeg = 3600.0;
inline constexpr int kMaxPatternSide = 1024;
inline constexpr double kDefaultWorkspaceMarginM = 1.0;

struct ObjectSpec {
  std::string name;
  std::filesystem::path mesh;            // absolute (resolved against the scenario file)
  Eigen::Isometry3d world_T_object = Eigen::Isometry3d::Identity();
  // Lambertian reflectance per channel (R, G, B), each 0..1: `albedo: 0.8` is grey, `albedo:
  // [0.8, 0.5, 0.45]` a coloured surface (a spot's colour is its light times this)
  Eigen::Vector3d albedo = Eigen::Vector3d::Constant(0.8);
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();  // of the mesh, along its own axes
};

// Pinhole intrinsics in pixels; the pixel (i, j) has its centre at (u, v) = (i, j).
struct Intrinsics {
  int width = 640;
  int height = 480;
  double fx = 800, fy = 800, cx = 319.5, cy = 239.5;
};

struct ProjectorSpec {
  // where the projector stands; on the camera (`mount: camera`), where it stands when the camera
  // is at the desired pose: world_T_desired * camera_T_projector
  Eigen::Isometry3d world_T_projector = Eigen::Isometry3d::Identity();
  // `mount: camera` (issue 44, the paper's future work): the projector rides on the camera's
  // link, fixed to it by this camera_T_projector (`pose` in the camera frame: X right, Y down,
  // Z along the optical axis); its spots move with the camera. Empty: static in the world.
  std::optional<Eigen::Isometry3d> on_camera;
  Intrinsics intrinsics{1024, 768, 1500, 1500, 511.5, 383.5};
  std::filesystem::path pattern;          // pattern file (absolute)
  double spot_pitch_px = 22;              // distance between neighbouring spot centres
  double spot_radius_px = 5;              // disc radius on the projector's image plane
  double brightness = 1.0;                // irradiance scale at the focus distance
  double focus_near_m = 1.6;              // acceptably focused between these distances
  double focus_far_m = 1.8;
  double defocus_px_per_m = 12;           // blur (sigma, projector px) per metre outside focus
  double focused_blur_px = 0.6;           // residual blur inside the focus range
  std::vector<std::array<int, 2>> only_spots;  // when non-empty, only these (row, col) are lit
};

struct CameraSpec {
  Intrinsics intrinsics;
  std::array<double, 5> distortion{0, 0, 0, 0, 0};  // k1 k2 p1 p2 k3 (plumb bob)
  double exposure = 1.0;        // gain from scene radiance to pixel value (1: white at 255)
  double ambient = 0.06;        // ambient irradiance on every surface, fraction of full scale
  double noise_sigma = 1.5;     // read noise, 8-bit units
  double shot_noise = 0.02;     // signal-dependent noise variance per unit of signal (8-bit units)
  double crosstalk = 0.06;      // fraction of each colour channel leaking into the others
};

// The arm carrying the camera (robot: {type: arm, ...}): a URDF with a serial chain to
// the camera's optical link, placed in the world, and its controller's settings.
struct ArmSpec {
  std::filesystem::path urdf;                     // absolute
  std::string camera_link = "camera_optical";
  Eigen::Isometry3d world_T_base = Eigen::Isometry3d::Identity();
  std::vector<double> home_rad;                   // IK seed: picks the arm's configuration family
  std::vector<double> desired_joints_rad;         // when given, the desired pose is their FK
  std::vector<double> initial_joints_rad;         // when given, the initial pose is their FK
  double damping = 0.05;
  double slowdown_condition = 17, stop_condition = 30;  // MoveIt Servo's thresholds
  double joint_margin_rad = 0.05;
  double physics_hz = 500;                        // the arm's physics (and controller) rate
};

struct RobotSpec {
  bool arm_enabled = false;  // false: the free-flying camera
  double max_linear_mps = 0.5;
  double max_angular_radps = 1.0;
  ArmSpec arm;
  // resolved by load_scenario (sim/arm): the robot read from the URDF, its number of chain
  // segments, and the joint angles of the desired and initial camera poses (by IK from home,
  // or as given)
  std::shared_ptr<const RobotModel> model;
  std::size_t chain_segments = 0;
  Eigen::VectorXd desired_q, initial_q;
};

struct Scenario {
  std::filesystem::path file;
  std::string name;
  std::uint64_t seed = 1;
  double dt_s = 0.04;
  std::vector<ObjectSpec> objects;
  ProjectorSpec projector;
  CameraSpec camera;
  RobotSpec robot;
  Eigen::Isometry3d world_T_desired = Eigen::Isometry3d::Identity();  // camera, desired pose
  Workspace workspace;  // default: the desired and initial positions, kDefaultWorkspaceMarginM around
  // initial pose as the paper gives it: translation (cm) along the X, Y, Z axes of the
  // offset frame F, then rotations (deg) about the moved frame's X, then Y, then Z. F is
  // the desired camera frame turned by offset_frame_rotation_deg (same convention) about
  // its centre: the robot's end-effector axes, which the paper does not relate to the camera.
  std::array<double, 3> initial_translation_cm{0, 0, 0};
  std::array<double, 3> initial_rotation_deg{0, 0, 0};
  std::array<double, 3> offset_frame_rotation_deg{0, 0, 0};
  Eigen::Isometry3d world_T_initial() const;
  // set when the initial pose is given as joint angles (build_cell fills it by FK)
  std::optional<Eigen::Isometry3d> initial_pose;
  // what the servo is told against the truth, and the loop's delays (all zero: none)
  CalibrationErrors errors;
  Latency latency;
  // what the file said, for the checks that come once the arm is resolved
  bool workspace_given = false, has_desired_pose = false, has_initial_offset = false;
};

// The scenario's calibration errors drawn with its seed (errors.seed, or the scenario's):
// what `cellsim serve` and `cellsim calibration` tell the servo, and what an in-process run
// with the scenario's seed draws too.
DrawnErrors scenario_errors(const Scenario& scenario);
// The camera as calibration gave it: the true intrinsics and distortion off by the draw's
// focal, principal-point and k1 errors (what the cell publishes on camera_info, what the
// in-process servo is told).
CameraSpec believed_camera(const CameraSpec& truth, const DrawnErrors& drawn);
// Other errors drawn for this scenario's robot, with another seed (a campaign run's).
DrawnErrors scenario_errors(const Scenario& scenario, const CalibrationErrors& errors, std::uint64_t seed);

// The scenario as the file gives it. Throws ScenarioError (one line naming the file and the
// key) on unknown keys, wrong types, missing files, non-positive focal lengths or sizes, NaN
// or infinite numbers. A scenario with an arm has its arm unresolved (no model, no joint
// angles) and its workspace unsettled: sim::load_scenario (sim/cell/build_cell.hpp) does both.
Scenario read_scenario(const std::filesystem::path& file);

// A scenario ready to build a cell from: read, its arm resolved (URDF, IK of the desired and
// initial poses) and its workspace settled. Only sim::resolve (sim/cell/build_cell.hpp) makes
// one, and sim::build_cell takes nothing else: a spec that was never resolved cannot reach a
// cell (a type error, where an unresolved arm scenario used to give a free-flying camera). Read
// it as the Scenario it is; to change one, change a copy of the spec and resolve that.
class ResolvedScenario : public Scenario {
 private:
  explicit ResolvedScenario(Scenario s) : Scenario(std::move(s)) {}
  friend ResolvedScenario resolve(Scenario spec);
};

// The workspace's default (the desired and initial positions with a margin) when the file
// gave none, and the check that both poses lie in it. Throws ScenarioError.
void settle_workspace(Scenario& scenario);

// The camera pose for a --pose argument: "desired", "initial" or "x y z rx ry rz" (cm,
// degrees, an offset from the desired pose in the paper's convention). Throws
// std::invalid_argument with the reason, also for a pose outside the workspace.
Eigen::Isometry3d resolve_pose(const Scenario& scenario, const std::string& spec);

// The paper's displacement (translation cm, rotations deg) applied to a desired pose.
// wTc = wTd * dTf * Trans(t) * Rx * Ry * Rz * fTd, with dTf the pure rotation of the offset frame.
Eigen::Isometry3d offset_pose(const Eigen::Isometry3d& world_T_desired, const std::array<double, 3>& translation_cm,
                              const std::array<double, 3>& rotation_deg,
                              const std::array<double, 3>& frame_rotation_deg = {0, 0, 0});

}  // namespace sim
