// The arm's cost. Controller step (camera Jacobian, damped least squares, singularity and
// limit checks) against KDL's own velocity IK (ChainIkSolverVel_pinv: the Jacobian and an
// SVD pseudo-inverse, no limits) in the same run; and one 40 ms camera frame of motion
// (40 physics steps of the Bullet arm, the controller at each) against the free-flying
// camera's exact exponential map.
#include <benchmark/benchmark.h>

#include <kdl/chain.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>

#include "sim/arm/arm_controller.hpp"
#include "sim/arm/arm_robot.hpp"
#include "sim/arm/kinematics.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/render/cell.hpp"
#include "sim/scenario/scenario.hpp"

namespace {

const std::string kSrc = CELL_SOURCE_DIR;

Eigen::VectorXd home() {
  Eigen::VectorXd q(6);
  q << 2.9093, -1.49006, 2.30655, 2.3251, -1.3385, 1.5708;
  return q;
}

sim::Vector6d twist() {
  sim::Vector6d v;
  v << 0.05, -0.02, 0.03, 0.1, 0.05, -0.2;
  return v;
}

void BM_ControllerStep(benchmark::State& state) {
  const sim::RobotModel m = sim::load_robot_model(kSrc + "/sim/robots/ur5e/ur5e.urdf", "camera_optical");
  const sim::ArmKinematics kin(m);
  const sim::ArmController c;
  const Eigen::VectorXd q = home();
  for (auto _ : state) benchmark::DoNotOptimize(c.step(kin, q, twist(), 0.001).qdot.data());
}

void BM_KdlPinv(benchmark::State& state) {
  const sim::RobotModel m = sim::load_robot_model(kSrc + "/sim/robots/ur5e/ur5e.urdf", "camera_optical");
  // the same chain as ArmKinematics builds (here through its public pieces: one Jacobian)
  const sim::ArmKinematics kin(m);
  const Eigen::VectorXd q = home();
  for (auto _ : state) {
    const sim::Matrix6Xd J = kin.jacobian_camera(q);
    const Eigen::JacobiSVD<sim::Matrix6Xd> svd(J, Eigen::ComputeThinU | Eigen::ComputeThinV);
    benchmark::DoNotOptimize(svd.solve(twist()).eval().data());
  }
}

void BM_FrameFreeFlying(benchmark::State& state) {
  sim::FreeFlyingCamera cam(Eigen::Isometry3d::Identity(), 0.5, 1.0);
  const sim::Workspace ws;
  for (auto _ : state) benchmark::DoNotOptimize(cam.move(twist() * 0.01, 0.04, ws).applied.data());
}

void BM_FrameArm(benchmark::State& state) {
  const auto cell = sim::build_cell(sim::load_scenario(kSrc + "/sim/scenarios/plane.yaml"));
  const auto robot = sim::make_robot(*cell);
  const sim::Workspace ws;
  int k = 0;
  for (auto _ : state) {
    // back and forth: the arm stays where it is on average
    benchmark::DoNotOptimize(robot->move((k++ % 20 < 10 ? 0.1 : -0.1) * twist(), 0.04, ws).applied.data());
  }
}

}  // namespace

BENCHMARK(BM_KdlPinv)->Name("arm_controller_step/baseline_jacobian_svd_pinv")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ControllerStep)->Name("arm_controller_step/ours_dls_limits")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrameFreeFlying)->Name("robot_frame_40ms/baseline_free_flying")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrameArm)->Name("robot_frame_40ms/ur5e_bullet")->Unit(benchmark::kMicrosecond);
