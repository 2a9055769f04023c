// The arm: URDF loading (and refusing), KDL kinematics against the published DH chain and
// finite differences, IK round trips, the robot controller's limits, and the Bullet arm
// (motors, a scripted collision, bit-for-bit determinism). Two different arms.
#include <gtest/gtest.h>

#include <filesystem>

#include <fstream>
#include <random>

#include "sim/arm/arm_controller.hpp"
#include "sim/arm/arm_robot.hpp"
#include "sim/arm/bullet_arm.hpp"
#include "sim/arm/kinematics.hpp"
#include "sim/arm/robot_model.hpp"
#include "sim/scene/world.hpp"

namespace sim {
namespace {

const std::string kRobots = std::string(CELL_SOURCE_DIR) + "/sim/robots/";
const std::string kUr5e = kRobots + "ur5e/ur5e.urdf";
const std::string kPuma = kRobots + "puma560/puma560.urdf";

Eigen::VectorXd random_q(const ArmKinematics& k, std::mt19937_64& rng, double shrink = 0.9) {
  Eigen::VectorXd q(k.dof());
  for (int i = 0; i < k.dof(); ++i) {
    const double mid = 0.5 * (k.lower()[i] + k.upper()[i]), half = 0.5 * (k.upper()[i] - k.lower()[i]) * shrink;
    q[i] = std::uniform_real_distribution<double>(mid - half, mid + half)(rng);
  }
  return q;
}

// the published standard DH chain, written out independently of the URDF
Eigen::Isometry3d ur5e_dh(const Eigen::VectorXd& q) {
  const double d[6] = {0.1625, 0, 0, 0.1333, 0.0997, 0.0996};
  const double a[6] = {0, -0.425, -0.3922, 0, 0, 0};
  const double alpha[6] = {M_PI / 2, 0, 0, M_PI / 2, -M_PI / 2, 0};
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 6; ++i)
    t = t * Eigen::AngleAxisd(q[i], Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(a[i], 0, d[i]) *
        Eigen::AngleAxisd(alpha[i], Eigen::Vector3d::UnitX());
  return t;
}

TEST(RobotModel, Ur5eChainFromUrdf) {
  const RobotModel m = load_robot_model(kUr5e, "camera_optical");
  EXPECT_EQ(m.dof(), 6);
  EXPECT_EQ(m.joint_names().front(), "shoulder_pan_joint");
  EXPECT_EQ(m.joint_names().back(), "wrist_3_joint");
  EXPECT_NEAR(m.velocity_limits()[0], M_PI, 1e-6);  // 180 deg/s
  EXPECT_TRUE(m.root_has_shape);
  EXPECT_FALSE(m.urdf.empty());
}

TEST(Kinematics, Ur5eFlangeEqualsThePublishedDhChain) {
  const RobotModel m = load_robot_model(kUr5e, "tool0");
  const ArmKinematics k(m);
  std::mt19937_64 rng(1);
  for (int n = 0; n < 50; ++n) {
    const Eigen::VectorXd q = random_q(k, rng);
    const Eigen::Isometry3d a = k.base_T_camera(q), b = ur5e_dh(q);
    // the URDF's rpy are pi/2 to 10 digits
    EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), 1e-8);
  }
}

class BothArms : public ::testing::TestWithParam<std::string> {};

TEST_P(BothArms, JacobianMatchesFiniteDifferencesOfForwardKinematics) {
  const RobotModel m = load_robot_model(GetParam(), "camera_optical");
  const ArmKinematics k(m);
  std::mt19937_64 rng(2);
  for (int n = 0; n < 30; ++n) {
    const Eigen::VectorXd q = random_q(k, rng);
    const Matrix6Xd J = k.jacobian_base(q);
    const Eigen::Isometry3d T = k.base_T_camera(q);
    for (int j = 0; j < k.dof(); ++j) {
      const double h = 1e-6;
      Eigen::VectorXd qp = q, qm = q;
      qp[j] += h;
      qm[j] -= h;
      const Eigen::Isometry3d Tp = k.base_T_camera(qp), Tm = k.base_T_camera(qm);
      const Eigen::Vector3d v = (Tp.translation() - Tm.translation()) / (2 * h);
      // angular velocity: vee(dR R^T)
      const Eigen::Matrix3d W = (Tp.rotation() - Tm.rotation()) / (2 * h) * T.rotation().transpose();
      const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));
      EXPECT_LT((J.col(j).head<3>() - v).norm(), 1e-7) << "joint " << j;
      EXPECT_LT((J.col(j).tail<3>() - w).norm(), 1e-7) << "joint " << j;
    }
    // the camera-frame Jacobian is the same twist in the camera's axes
    const Matrix6Xd Jc = k.jacobian_camera(q);
    EXPECT_LT((T.rotation() * Jc.topRows<3>() - J.topRows<3>()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST_P(BothArms, InverseKinematicsRoundTripsTo1e6WithinTheLimits) {
  const RobotModel m = load_robot_model(GetParam(), "camera_optical");
  const ArmKinematics k(m);
  std::mt19937_64 rng(3);
  for (int n = 0; n < 30; ++n) {
    const Eigen::VectorXd q = random_q(k, rng, 0.8);
    const Eigen::Isometry3d goal = k.base_T_camera(q);
    Eigen::VectorXd seed = q;
    for (int i = 0; i < k.dof(); ++i) seed[i] += std::uniform_real_distribution<double>(-0.3, 0.3)(rng);
    std::string why;
    const auto sol = k.inverse(goal, seed, &why);
    ASSERT_TRUE(sol) << why;
    EXPECT_TRUE(k.within_limits(*sol));
    const Eigen::Isometry3d reached = k.base_T_camera(*sol);
    EXPECT_LT((reached.translation() - goal.translation()).norm(), 1e-6);
    EXPECT_LT(Eigen::AngleAxisd(reached.rotation().transpose() * goal.rotation()).angle(), 1e-6);
  }
  std::string why;
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(5, 0, 0);
  EXPECT_FALSE(k.inverse(far, Eigen::VectorXd::Zero(k.dof()), &why));
  EXPECT_NE(why.find("no joint configuration"), std::string::npos);
}

TEST_P(BothArms, TheControllerMakesTheCommandedTwistAwayFromLimitsAndSingularities) {
  const RobotModel m = load_robot_model(GetParam(), "camera_optical");
  const ArmKinematics k(m);
  const ArmController c;
  std::mt19937_64 rng(5);
  int checked = 0;
  for (int n = 0; n < 100; ++n) {
    const Eigen::VectorXd q = random_q(k, rng, 0.6);
    Vector6d v;
    for (int i = 0; i < 6; ++i) v[i] = std::uniform_real_distribution<double>(-0.02, 0.02)(rng);
    const ArmCommand cmd = c.step(k, q, v, 0.002);
    const Eigen::JacobiSVD<Matrix6Xd> svd(k.jacobian_camera(q));
    if (cmd.limits != 0 || svd.singularValues()[5] < 0.05) continue;  // damped or limited: not the exact twist
    EXPECT_LT((k.jacobian_camera(q) * cmd.qdot - v).norm(), 1e-9);
    ++checked;
  }
  EXPECT_GT(checked, 5);
}

INSTANTIATE_TEST_SUITE_P(Arms, BothArms, ::testing::Values(kUr5e, kPuma),
                         [](const auto& info) { return info.param.find("ur5e") != std::string::npos ? "Ur5e" : "Puma560"; });

struct Ur5e : ::testing::Test {
  RobotModel model = load_robot_model(kUr5e, "camera_optical");
  ArmKinematics kin{model};
  Eigen::VectorXd home() const {
    Eigen::VectorXd q(6);
    q << 2.9093, -1.49006, 2.30655, 2.3251, -1.3385, 1.5708;  // elbow up, camera looking along +x
    return q;
  }
};

TEST_F(Ur5e, ATwistThatWouldCrossAJointLimitStopsAtTheMargin) {
  ArmControllerOptions p;
  const ArmController c(p);
  Eigen::VectorXd q = home();
  q[0] = kin.upper()[0] - p.joint_margin_rad - 0.01;  // the base joint 10 mrad from its margin
  // a twist that turns the base joint on: its column of J
  const Vector6d v = kin.jacobian_camera(q).col(0) * 0.5;
  double last = q[0];
  for (int k = 0; k < 200; ++k) {
    const ArmCommand cmd = c.step(kin, q, v, 0.001);
    q += cmd.qdot * 0.001;
    last = q[0];
  }
  EXPECT_LE(last, kin.upper()[0] - p.joint_margin_rad + 1e-9);
  EXPECT_GT(last, kin.upper()[0] - p.joint_margin_rad - 1e-3);
  const ArmCommand at = c.step(kin, q, v, 0.001);
  EXPECT_TRUE(at.limits & kLimitJointPosition);
  EXPECT_LT(at.qdot.norm(), 1e-6);
}

TEST_F(Ur5e, NearASingularityJointSpeedsStayBoundedAndTheStatusSaysSo) {
  const ArmController c;
  // wrist singularity: wrist 2 at zero aligns joints 4 and 6
  Eigen::VectorXd q = home();
  q[4] = 1e-4;
  const Matrix6Xd J = kin.jacobian_camera(q);
  Eigen::JacobiSVD<Matrix6Xd> svd(J, Eigen::ComputeFullU);
  Vector6d towards = svd.matrixU().col(5) * 0.2;  // along the lost direction
  for (double sign : {1.0, -1.0}) {
    const ArmCommand cmd = c.step(kin, q, sign * towards, 0.001);
    EXPECT_GT(cmd.condition, 30);
    EXPECT_TRUE(cmd.qdot.allFinite());
    EXPECT_LE(cmd.qdot.cwiseAbs().maxCoeff(), M_PI + 1e-9);
    if (cmd.limits & kLimitSingularityStop) {
      EXPECT_EQ(cmd.qdot.norm(), 0);
    }
  }
  // one of the two directions heads into the singularity: stopped, and said
  const ArmCommand a = c.step(kin, q, towards, 0.001), b = c.step(kin, q, -towards, 0.001);
  EXPECT_TRUE((a.limits | b.limits) & kLimitSingularityStop);
  // between the thresholds: slowed, said
  bool slowed = false;
  for (double w5 = 1.3; w5 > 0.001 && !slowed; w5 *= 0.95) {
    q[4] = w5;
    const Matrix6Xd Jq = kin.jacobian_camera(q);
    Eigen::JacobiSVD<Matrix6Xd> s(Jq, Eigen::ComputeFullU);
    for (double sign : {1.0, -1.0}) {
      const ArmCommand cmd = c.step(kin, q, sign * s.matrixU().col(5) * 0.05, 0.001);
      if (cmd.limits & kLimitSingularitySlowdown) {
        slowed = true;
        EXPECT_GT(cmd.condition, 17);
        EXPECT_LT(cmd.condition, 30);
        EXPECT_LT(cmd.scale, 1);
      }
    }
  }
  EXPECT_TRUE(slowed);
}

TEST_F(Ur5e, VelocityLimitsScaleAllJointsTogether) {
  ArmControllerOptions p;
  p.max_linear_mps = 100;
  p.max_angular_radps = 100;
  const ArmController c(p);
  const Eigen::VectorXd q = home();
  Vector6d v;
  v << 0.5, -0.3, 2.0, 3.0, -2.0, 4.0;
  const ArmCommand cmd = c.step(kin, q, v, 0.001);
  EXPECT_TRUE(cmd.limits & kLimitJointVelocity);
  EXPECT_LE(cmd.qdot.cwiseAbs().maxCoeff(), M_PI + 1e-9);
  // the direction of the camera twist is kept
  EXPECT_GT(cmd.twist.normalized().dot(v.normalized()), 0.999);
}

// A wall in front of the arm, and the arm driven into it.
TEST_F(Ur5e, ScriptedCollisionStopsTheArmAndIsReported) {
  World world;
  TriangleMesh wall;
  wall.vertices = {{0, -1, -1}, {0, 1, -1}, {0, 1, 1}, {0, -1, 1}};
  wall.triangles = {{0, 1, 2}, {0, 2, 3}};
  Eigen::Isometry3d at = Eigen::Isometry3d::Identity();
  at.translation() = Eigen::Vector3d(0.75, 0, 0.5);
  world.add_object(wall, at, Eigen::Vector3d::Constant(0.8));
  ArmRobot robot(std::make_shared<RobotModel>(model), Eigen::Isometry3d::Identity(), world, {"wall"}, {}, home());
  Workspace ws;
  Vector6d forward = Vector6d::Zero();
  forward[2] = 0.3;  // along the optical axis, towards the wall
  MotionReport r;
  int frames = 0;
  for (; frames < 200 && !(r.limits & kLimitCollision); ++frames) r = robot.move(forward, 0.04, ws);
  ASSERT_TRUE(r.limits & kLimitCollision) << "never touched the wall";
  EXPECT_NE(r.event.find("touches object 'wall'"), std::string::npos) << r.event;
  ASSERT_TRUE(robot.fault());
  const Eigen::Isometry3d stopped = robot.world_T_camera();
  r = robot.move(forward, 0.04, ws);
  EXPECT_TRUE(r.limits & kLimitCollision);
  EXPECT_EQ((robot.world_T_camera().matrix() - stopped.matrix()).norm(), 0) << "moved after the collision";
  EXPECT_GT(frames, 3);
}

TEST_F(Ur5e, MotorsFollowTheControllerAndTheSameRunIsBitIdentical) {
  World empty;
  const auto run = [&] {
    ArmRobot robot(std::make_shared<RobotModel>(model), Eigen::Isometry3d::Identity(), empty, {}, {}, home());
    Workspace ws;
    Vector6d v;
    v << 0.05, -0.02, 0.03, 0.1, 0.05, -0.2;
    const Eigen::Isometry3d start = robot.world_T_camera();
    for (int k = 0; k < 25; ++k) robot.move(v, 0.04, ws);
    return std::make_pair(start, robot.joint_positions());
  };
  const auto a = run(), b = run();
  EXPECT_EQ(a.second, b.second);  // bit for bit
  // one second of the twist: the camera went about where the exponential map says
  ArmRobot robot(std::make_shared<RobotModel>(model), Eigen::Isometry3d::Identity(), empty, {}, {}, home());
  Vector6d v = Vector6d::Zero();
  v[0] = 0.05;
  const Eigen::Isometry3d start = robot.world_T_camera();
  for (int k = 0; k < 25; ++k) robot.move(v, 0.04, Workspace{});
  const Eigen::Vector3d moved = start.rotation().transpose() * (robot.world_T_camera().translation() - start.translation());
  EXPECT_NEAR(moved.x(), 0.05, 0.002);
  EXPECT_NEAR(moved.y(), 0.0, 0.002);
  EXPECT_NEAR(moved.z(), 0.0, 0.002);
}

TEST_F(Ur5e, ResetPlacesTheCameraByInverseKinematicsOrSaysWhyNot) {
  World empty;
  ArmRobot robot(std::make_shared<RobotModel>(model), Eigen::Isometry3d::Identity(), empty, {}, {}, home());
  Eigen::Isometry3d goal = robot.world_T_camera();
  goal.translation() += Eigen::Vector3d(0.05, 0.05, -0.05);
  robot.reset(goal);
  EXPECT_LT((robot.world_T_camera().translation() - goal.translation()).norm(), 1e-5);  // Bullet holds floats
  Eigen::Isometry3d far = goal;
  far.translation() = Eigen::Vector3d(3, 0, 0.4);
  try {
    robot.reset(far);
    FAIL() << "an unreachable pose was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cannot place the camera"), std::string::npos);
  }
}

std::string write_temp(const std::string& name, const std::string& text) {
  const std::string path = std::string(CELL_BINARY_DIR) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

// An axis whose norm overflows is still a direction: (1e300, 0, 1) is the x axis, not zero
// (a zero axis made the kinematics NaN; the fuzzer found it).
TEST(RobotModel, HugeAxisComponentsGiveAUnitAxis) {
  const std::string file = write_temp("huge_axis.urdf",
                                      "<robot name='r'><link name='a'/><link name='camera'/><joint name='j' "
                                      "type='revolute'><parent link='a'/><child link='camera'/><axis xyz='1e300 0 1'/>"
                                      "<limit lower='-1' upper='1' velocity='1' effort='1'/></joint></robot>");
  const RobotModel m = load_robot_model(file, "camera");
  ASSERT_EQ(m.chain.size(), 1u);
  EXPECT_TRUE(m.chain[0].axis.isApprox(Eigen::Vector3d::UnitX(), 1e-12)) << m.chain[0].axis.transpose();
}

// Issue 18, item 14: a <visual> or <collision> whose origin or size does not parse used to
// vanish (urdfdom drops it, or reads NaN as the identity); each is refused naming the link
// and the element.
TEST(RobotModel, BrokenGeometryIsRefusedNamingTheLinkAndTheElement) {
  const auto robot = [](const std::string& camera_link_body) {
    return "<robot name='r'><link name='a'/><link name='camera'>" + camera_link_body +
           "</link><joint name='j' type='revolute'><parent link='a'/><child link='camera'/><axis xyz='0 0 1'/>"
           "<limit lower='-1' upper='1' velocity='1' effort='1'/></joint></robot>";
  };
  const std::string box = "<geometry><box size='0.1 0.1 0.1'/></geometry>";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"<visual><origin rpy='nan 0 0'/>" + box + "</visual>", "link 'camera' visual 1: <origin> rpy 'nan'"},
      {"<collision><origin xyz='0 inf 0'/>" + box + "</collision>", "link 'camera' collision 1: <origin> xyz 'inf'"},
      {"<visual>" + box + "</visual><collision><geometry><box size='99 99'/></geometry></collision>",
       "link 'camera' collision 1: <box> size has 2 numbers, expected 3"},
      // a box refused for its size must not load when its rpy is NaN
      {"<visual><origin rpy='nan 0 0'/><geometry><box size='200 200 200'/></geometry></visual>", "rpy 'nan'"},
      {"<visual><geometry><cylinder radius='abc' length='1'/></geometry></visual>", "<cylinder> radius 'abc'"},
      {"<visual><geometry><sphere/></geometry></visual>", "<sphere> has no radius"},
      {"<visual><geometry><mesh filename='m.obj' scale='nan 1 1'/></geometry></visual>", "<mesh> scale 'nan'"},
      {"<visual><geometry></geometry></visual>", "<geometry> is empty"},
      {"<visual></visual>", "no <geometry>"},
  };
  int i = 0;
  for (const auto& [body, expected] : cases) {
    const std::string file = write_temp("bad_geometry_" + std::to_string(i++) + ".urdf", robot(body));
    try {
      load_robot_model(file, "camera");
      ADD_FAILURE() << "accepted: " << body;
    } catch (const RobotModelError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file, 0), 0u) << what;
      EXPECT_NE(what.find(expected), std::string::npos) << what;
    }
  }
  // and a box past the size limit is refused as before
  const std::string big = write_temp("big_box.urdf", robot("<visual><geometry><box size='200 200 200'/></geometry></visual>"));
  EXPECT_THROW(load_robot_model(big, "camera"), RobotModelError);
}

// Issue 18, item 15: the arm's triangle limit holds while the meshes load: a URDF of twelve
// visuals of one large mesh is refused at the second, before assimp reads it.
TEST(RobotModel, MeshBombIsRefusedAtTheFirstMeshPastTheLimit) {
  const std::string dir = std::string(CELL_BINARY_DIR) + "/mesh_bomb";
  std::filesystem::create_directories(dir);
  {
    // a binary PLY of 300 000 triangles (the arm's limit is 400 000)
    std::ofstream f(dir + "/big.ply", std::ios::binary);
    const int n = 300000;
    f << "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face " << n << "\nproperty list uchar int vertex_indices\nend_header\n";
    const float v[9] = {0, 0, 0, 0.01f, 0, 0, 0, 0.01f, 0};
    f.write(reinterpret_cast<const char*>(v), sizeof v);
    for (int k = 0; k < n; ++k) {
      const unsigned char c = 3;
      const int idx[3] = {0, 1, 2};
      f.write(reinterpret_cast<const char*>(&c), 1);
      f.write(reinterpret_cast<const char*>(idx), sizeof idx);
    }
  }
  std::string visuals;
  for (int k = 0; k < 12; ++k) visuals += "<visual><geometry><mesh filename='big.ply'/></geometry></visual>";
  const std::string file = dir + "/bomb.urdf";
  std::ofstream(file) << "<robot name='r'><link name='a'/><link name='camera'>" << visuals
                      << "</link><joint name='j' type='revolute'><parent link='a'/><child link='camera'/>"
                         "<axis xyz='0 0 1'/><limit lower='-1' upper='1' velocity='1' effort='1'/></joint></robot>";
  try {
    load_robot_model(file, "camera");
    FAIL() << "a URDF of 3.6 M triangles was accepted";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    // refused while counting the second mesh, before assimp reads it
    EXPECT_NE(what.find("big.ply: 300000 triangles, more than the 100000 left"), std::string::npos) << what;
    EXPECT_NE(what.find("link 'camera' visual"), std::string::npos) << what;
  }
}

TEST(RobotModel, MalformedDescriptionsAreRefusedInOneLineNamingTheFile) {
  const std::string joint_ok =
      "<link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
      "<axis xyz='0 0 1'/><limit lower='-1' upper='1' velocity='1' effort='1'/></joint>";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"<robot name='r'><link name='a'/>", "not a valid URDF"},
      {"<robot name='r'>" + joint_ok + "</robot>", "no link named 'camera'"},
      {"<robot name='r'><link name='a'/><link name='camera'/><joint name='j' type='revolute'><parent link='a'/>"
       "<child link='camera'/><axis xyz='0 0 1'/><limit lower='1' upper='-1' velocity='1' effort='1'/></joint></robot>",
       "lower < upper"},
      {"<robot name='r'><link name='a'/><link name='camera'><visual><geometry><mesh filename='package://x/m.stl'/>"
       "</geometry></visual></link><joint name='j' type='revolute'><parent link='a'/><child link='camera'/>"
       "<axis xyz='0 0 1'/><limit lower='-1' upper='1' velocity='1' effort='1'/></joint></robot>",
       "URIs are not resolved"},
      {"<robot name='r'><link name='a'/><link name='camera'/><joint name='j' type='fixed'><parent link='a'/>"
       "<child link='camera'/></joint></robot>",
       "no moving joint"},
      {"<robot name='r'><link name='a'/><link name='camera'/><joint name='j' type='revolute'><parent link='a'/>"
       "<child link='camera'/><axis xyz='0 0 1'/><limit lower='-1' upper='1' velocity='1e300' effort='1'/></joint></robot>",
       "velocity limit"},
      // the XML parser recurses per level: 100 000 nested elements would overflow the stack
      {"<robot name='r'><link name='a'>" + [] {
         std::string deep;
         for (int i = 0; i < 100000; ++i) deep += "<x>";
         for (int i = 0; i < 100000; ++i) deep += "</x>";
         return deep;
       }() + "</link></robot>",
       "nested deeper than 64"},
      {"<!DOCTYPE r [<!ENTITY a 'aaaa'>]><robot name='r'/>", "DTD"},
      {"<robot name='r'><link name='a'/><link name='camera'/><joint name='j' type='revolute'><parent link='a'/>"
       "<child link='camera'/><axis xyz='0 0 0'/><limit lower='-1' upper='1' velocity='1' effort='1'/></joint></robot>",
       "finite non-zero"},
  };
  int i = 0;
  for (const auto& [text, expected] : cases) {
    const std::string file = write_temp("bad_" + std::to_string(i++) + ".urdf", text);
    try {
      load_robot_model(file, "camera");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const RobotModelError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file, 0), 0u) << what;
      EXPECT_NE(what.find(expected), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}

}  // namespace
}  // namespace sim

namespace sim {
namespace {

// Two links that are not neighbours touching is a contact too (the base may touch what it
// stands on, neighbours always touch at their joint): somewhere among random configurations
// the wrist meets the upper arm or the base, and the report names both links.
TEST_F(Ur5e, LinksThatAreNotNeighboursTouchingIsReported) {
  World empty;
  BulletArm arm(model, Eigen::Isometry3d::Identity(), empty, {}, 0.002);
  std::mt19937_64 rng(4);
  int self = 0, free = 0;
  for (int n = 0; n < 200; ++n) {
    arm.reset(random_q(kin, rng, 0.9));
    const auto c = arm.contact();
    if (!c) {
      ++free;
      continue;
    }
    EXPECT_NE(c->find("link '"), std::string::npos) << *c;
    EXPECT_NE(c->find("touches link '"), std::string::npos) << *c;
    ++self;
  }
  EXPECT_GE(self, 3) << "no self-contact among the random configurations";
  EXPECT_GT(free, 10);
  arm.reset(home());
  EXPECT_FALSE(arm.contact()) << *arm.contact();
}

}  // namespace
}  // namespace sim
