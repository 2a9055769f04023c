#include "sim/arm/arm_scenario.hpp"

#include <string>

#include "sim/arm/kinematics.hpp"
#include "sim/arm/robot_model.hpp"

namespace sim {

static_assert(kMaxJointAngles == kMaxChainSegments, "a scenario lists at most one angle per chain segment");

namespace {

// "<file>: <key>: <what>", as the scenario reader words every error
[[noreturn]] void fail_at(const Scenario& s, const std::string& key, const std::string& what) {
  throw ScenarioError(s.file.string() + ": " + key + ": " + what);
}

}  // namespace

// a pose out of the arm's reach is refused here, at load, not at the first RESET
void resolve_arm(Scenario& s) {
  ArmSpec& a = s.robot.arm;
  try {
    s.robot.model = std::make_shared<const RobotModel>(load_robot_model(a.urdf, a.camera_link));
  } catch (const std::exception& e) {
    fail_at(s, "robot.urdf", e.what());
  }
  s.robot.chain_segments = s.robot.model->chain.size();
  const ArmKinematics kin(*s.robot.model);
  const auto sized = [&](const std::vector<double>& q, const char* key) {
    const std::string where = std::string("robot.") + key;
    if (q.size() != static_cast<std::size_t>(kin.dof()))
      fail_at(s, where, "must list " + std::to_string(kin.dof()) + " angles (the arm's joints)");
    const Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
    if (!kin.within_limits(v)) fail_at(s, where, "outside the joint limits of " + a.urdf.filename().string());
    return v;
  };
  const Eigen::VectorXd home = a.home_rad.empty() ? Eigen::VectorXd(0.5 * (kin.lower() + kin.upper()))
                                                  : sized(a.home_rad, "home_joints_deg");
  const Eigen::Isometry3d base_T_world = a.world_T_base.inverse();
  std::string why;
  if (!a.desired_joints_rad.empty()) {
    s.robot.desired_q = sized(a.desired_joints_rad, "desired_joints_deg");
    s.world_T_desired = a.world_T_base * kin.base_T_camera(s.robot.desired_q);
  } else if (const auto q = kin.inverse(base_T_world * s.world_T_desired, home, &why)) {
    s.robot.desired_q = *q;
  } else {
    fail_at(s, "desired_pose", "the arm cannot place the camera there: " + why);
  }
  if (!a.initial_joints_rad.empty()) {
    s.robot.initial_q = sized(a.initial_joints_rad, "initial_joints_deg");
    s.initial_pose = a.world_T_base * kin.base_T_camera(s.robot.initial_q);
  } else if (const auto q = kin.inverse(base_T_world * s.world_T_initial(), s.robot.desired_q, &why)) {
    s.robot.initial_q = *q;
  } else {
    fail_at(s, s.has_initial_offset ? "initial_offset" : "robot", "the arm cannot place the camera there: " + why);
  }
}



}  // namespace sim
