// The cell compiler: a resolved scenario into the cell a frame is rendered from (its meshes,
// the arm's link meshes, the pattern, the projector and the camera, then the renderer's own
// tables: sim::prepare_rendering), and the robot the scenario names.
#include "sim/cell/build_cell.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>

#include "servo/pattern/pattern_file.hpp"
#include "sim/arm/arm_robot.hpp"
#include "sim/arm/arm_scenario.hpp"
#include "sim/render/renderer.hpp"
#include "sim/scene/mesh_check.hpp"

namespace sim {

ResolvedScenario resolve(Scenario spec) {
  if (spec.robot.arm_enabled) {
    resolve_arm(spec);
    settle_workspace(spec);
  }
  // a projector on the camera stands, in the cell's own tables, where the desired pose puts it
  if (spec.projector.on_camera) spec.projector.world_T_projector = spec.world_T_desired * *spec.projector.on_camera;
  return ResolvedScenario(std::move(spec));
}

ResolvedScenario load_scenario(const std::filesystem::path& file) { return resolve(read_scenario(file)); }

namespace {

// The scenario's objects into the cell's world. load_mesh walks each file (bounded counts)
// before assimp imports it; the scene's total is checked as the meshes come, so at most one
// mesh beyond the limit is ever held.
void load_objects(const Scenario& scenario, Cell& cell) {
  std::size_t total = 0;
  for (const ObjectSpec& o : scenario.objects) {
    TriangleMesh mesh = load_mesh(o.mesh);
    if (o.scale != Eigen::Vector3d::Ones())
      for (auto& v : mesh.vertices) v = v.cwiseProduct(o.scale);
    total += mesh.triangles.size();
    if (total > kMaxSceneTriangles)
      throw MeshError(scenario.file.string() + ": objects: more than " + std::to_string(kMaxSceneTriangles) +
                      " triangles in the scene (the limit), reached at mesh " + o.mesh.string());
    cell.world.add_object(std::move(mesh), o.world_T_object, o.albedo);
    cell.object_names.push_back(o.name);
  }
}

// The arm's link meshes (none for the free-flying camera), in their link frames.
void load_arm_meshes(const Scenario& scenario, Cell& cell) {
  if (!scenario.robot.arm_enabled || !scenario.robot.model) return;
  const RobotModel& m = *scenario.robot.model;
  if (m.root_has_shape) cell.arm_meshes.add(m.root_shape.visual, 0, m.root_shape.albedo);
  for (std::size_t i = 0; i < m.chain.size(); ++i)
    if (m.chain[i].has_shape && !m.chain[i].shape.visual.triangles.empty())
      cell.arm_meshes.add(m.chain[i].shape.visual, static_cast<int>(i) + 1, m.chain[i].shape.albedo);
}

// The plane through the spots a projector on the camera lights from the desired pose (least
// squares), its normal away from the camera. Throws ScenarioError when they give none.
GoalPlane lit_plane(const Cell& cell) {
  const Scenario& s = cell.scenario;
  std::vector<Eigen::Vector3d> points;
  for (const SpotTruth& t : compute_truth(cell, s.world_T_desired))
    if (t.visible) points.push_back(t.point_w);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= std::max<std::size_t>(1, points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  if (points.size() < 3 || !(eig.eigenvalues()[1] > 1e-12 * eig.eigenvalues()[2]))
    throw ScenarioError(s.file.string() + ": projector: mounted on the camera, it lights " + std::to_string(points.size()) +
                        " spots the camera sees from the desired pose: 3 or more, not on one line, are needed");
  GoalPlane g{eig.eigenvectors().col(0).normalized(), 0};
  if (g.n_w.dot(mean - s.world_T_desired.translation()) < 0) g.n_w = -g.n_w;
  g.d = g.n_w.dot(mean);
  return g;
}

}  // namespace

std::unique_ptr<Cell> build_cell(const ResolvedScenario& scenario) {
  auto cell = std::make_unique<Cell>(scenario);
  load_objects(scenario, *cell);
  load_arm_meshes(scenario, *cell);
  cell->triangles = collect_triangles(cell->world);
  cell->textures = pool_textures(cell->world);

  pattern::MArray marray = pattern::load_pattern(scenario.projector.pattern, {3, 3});
  cell->projector = std::make_unique<Projector>(scenario.projector, std::move(marray));
  cell->camera = std::make_unique<CameraModel>(scenario.camera.intrinsics, scenario.camera.distortion);

  prepare_rendering(*cell);
  if (scenario.projector.on_camera) cell->goal_plane = lit_plane(*cell);
  return cell;
}

std::unique_ptr<Robot> make_robot(const Cell& cell, const RobotBelief* belief) {
  const Scenario& s = cell.scenario;
  // set once, at the end: the run's belief, or the scenario's when it has errors
  const auto believe = [&](Robot& r) {
    if (belief)
      r.set_belief(*belief);
    else if (s.errors.any())
      r.set_belief(scenario_errors(s).robot);
  };
  if (!s.robot.arm_enabled || !s.robot.model) {
    auto cam = std::make_unique<FreeFlyingCamera>(s.world_T_desired, s.robot.max_linear_mps, s.robot.max_angular_radps);
    believe(*cam);
    return cam;
  }
  const ArmSpec& a = s.robot.arm;
  ArmControllerOptions p;
  p.max_linear_mps = s.robot.max_linear_mps;
  p.max_angular_radps = s.robot.max_angular_radps;
  p.damping = a.damping;
  p.slowdown_condition = a.slowdown_condition;
  p.stop_condition = a.stop_condition;
  p.joint_margin_rad = a.joint_margin_rad;
  Eigen::VectorXd home = s.robot.desired_q;
  if (a.home_rad.size() == static_cast<std::size_t>(home.size()))
    home = Eigen::Map<const Eigen::VectorXd>(a.home_rad.data(), home.size());
  auto arm = std::make_unique<ArmRobot>(s.robot.model, a.world_T_base, cell.world, cell.object_names, p, home,
                                        1.0 / a.physics_hz);
  arm->pin(s.world_T_desired, s.robot.desired_q);
  arm->pin(s.world_T_initial(), s.robot.initial_q);
  try {
    arm->reset(s.world_T_desired);
  } catch (const std::invalid_argument& e) {
    // the file whose pose it is (issue 18, item 18): "the arm would be in collision there" alone named none
    throw std::invalid_argument(s.file.string() + ": desired_pose: " + e.what());
  }
  believe(*arm);
  return arm;
}

}  // namespace sim
