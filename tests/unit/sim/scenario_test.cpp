#include "sim/cell/build_cell.hpp"
#include "sim/arm/robot_model.hpp"
#include "sim/scenario/scenario.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>

#include "sim/geometry/se3.hpp"

namespace sim {
namespace {

const std::string kScenarios = std::string(CELL_SOURCE_DIR) + "/sim/scenarios/";

std::string read(const std::string& path) {
  std::ifstream f(path);
  return {std::istreambuf_iterator<char>(f), {}};
}

// Writes a variant of plane.yaml to the temp folder, its relative paths made absolute.
std::string variant(const std::string& name, const std::string& from, const std::string& to) {
  std::string text = read(kScenarios + "plane.yaml");
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  for (std::size_t p; (p = text.find("../../")) != std::string::npos;) text.replace(p, 6, std::string(CELL_SOURCE_DIR) + "/");
  const std::string path = (std::filesystem::temp_directory_path() / ("_test_" + name + ".yaml")).string();
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& path) {
  std::string what;
  try {
    load_scenario(path);
  } catch (const ScenarioError& e) {
    what = e.what();
  }
  std::remove(path.c_str());
  return what;
}

TEST(Scenario, ShippedScenariosLoad) {
  for (const char* name : {"plane", "cylinder", "ham", "fig5"}) {
    const Scenario s = load_scenario(kScenarios + name + ".yaml");
    EXPECT_EQ(s.name, name);
    EXPECT_DOUBLE_EQ(s.dt_s, 0.04);
    EXPECT_EQ(s.camera.intrinsics.width, 640);
    EXPECT_EQ(s.camera.intrinsics.height, 480);
    EXPECT_FALSE(s.objects.empty());
  }
}

TEST(Scenario, PlaneMatchesThePapersSetUp) {
  const Scenario s = load_scenario(kScenarios + "plane.yaml");
  // camera parallel to the wall (normal -X) at 90 cm
  const Eigen::Vector3d optical_axis = s.world_T_desired.linear().col(2);
  EXPECT_NEAR(optical_axis.dot(Eigen::Vector3d::UnitX()), 1.0, 1e-9);
  EXPECT_NEAR(1.4 - s.world_T_desired.translation().x(), 0.9, 1e-9);
  // projector inside the 1.6-1.8 m focus range from the pattern's centre on the wall
  const double d = (s.projector.world_T_projector.translation() - Eigen::Vector3d(1.4, 0, 0.4)).norm();
  EXPECT_GT(d, 1.6);
  EXPECT_LT(d, 1.8);
  // the initial pose is the paper's displacement: 5 + 10 + 20 cm, 15 and 10 degrees
  const Eigen::Isometry3d delta = s.world_T_desired.inverse() * s.world_T_initial();
  EXPECT_NEAR(delta.translation().norm(), std::sqrt(0.05 * 0.05 + 0.1 * 0.1 + 0.2 * 0.2), 1e-9);
}

// The errors a real cell has (issue 13): read at load, checked, named in one line.
TEST(Scenario, ErrorsAndLatencyAreReadAndChecked) {
  const std::string ok = variant("errors", "seed: 1\n",
                                 "seed: 1\nerrors: {focal_pct: 1.5, hand_eye_rotation_deg: 0.5, seed: 4}\n"
                                 "latency: {processing_frames: 2, actuation_s: 0.01}\n");
  const Scenario s = load_scenario(ok);
  std::remove(ok.c_str());
  EXPECT_EQ(s.errors.focal_pct, 1.5);
  EXPECT_EQ(s.errors.hand_eye_rotation_deg, 0.5);
  EXPECT_EQ(s.errors.seed, 4u);
  EXPECT_EQ(s.latency.processing_frames, 2);
  EXPECT_EQ(s.latency.actuation_s, 0.01);
  EXPECT_FALSE(load_scenario(kScenarios + "plane.yaml").errors.any());

  std::string e = error_of(variant("errors_big", "seed: 1\n", "seed: 1\nerrors: {focal_pct: 1e300}\n"));
  EXPECT_NE(e.find("errors.focal_pct"), std::string::npos) << e;
  e = error_of(variant("errors_range", "seed: 1\n", "seed: 1\nerrors: {focal_pct: 60}\n"));
  EXPECT_NE(e.find("errors.focal_pct"), std::string::npos) << e;
  EXPECT_NE(e.find("outside [0, 50]"), std::string::npos) << e;
  e = error_of(variant("errors_key", "seed: 1\n", "seed: 1\nerrors: {lens: 1}\n"));
  EXPECT_NE(e.find("unknown key"), std::string::npos) << e;
  e = error_of(variant("latency_big", "seed: 1\n", "seed: 1\nlatency: {processing_frames: 100000000}\n"));
  EXPECT_NE(e.find("latency.processing_frames"), std::string::npos) << e;
  e = error_of(variant("scale", "albedo: 0.85", "albedo: 0.85\n    scale: [1, 0, 1]"));
  EXPECT_NE(e.find("scale"), std::string::npos) << e;
  EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 0) << e;
}

// Issue 41: an albedo is one grey number or [r, g, b], each in [0, 1]
TEST(Scenario, AlbedoIsGreyOrPerChannel) {
  const Scenario grey = load_scenario(variant("albedo_grey", "albedo: 0.85", "albedo: 0.5"));
  EXPECT_EQ(grey.objects[0].albedo, Eigen::Vector3d::Constant(0.5));
  const Scenario rgb = load_scenario(variant("albedo_rgb", "albedo: 0.85", "albedo: [0.8, 0.52, 0.48]"));
  EXPECT_EQ(rgb.objects[0].albedo, Eigen::Vector3d(0.8, 0.52, 0.48));
  for (const char* bad : {"albedo: [0.8, 0.5]", "albedo: [0.8, 0.5, 1.5]", "albedo: [0.8, .nan, 0.5]", "albedo: -0.1"}) {
    const std::string e = error_of(variant("albedo_bad", "albedo: 0.85", bad));
    EXPECT_NE(e.find("albedo"), std::string::npos) << bad << ": " << e;
  }
}

// Issue 44: `mount: camera` puts the projector on the camera, its pose in the camera's frame;
// the cell then stands it where the desired pose puts it and knows the plane it lights. Another
// mount, or a mount lighting nothing the camera sees, is one line naming the file.
TEST(Scenario, AProjectorOnTheCameraIsReadInTheCamerasFrame) {
  const Scenario s = load_scenario(kScenarios + "onboard_plane.yaml");
  ASSERT_TRUE(s.projector.on_camera.has_value());
  EXPECT_TRUE(s.projector.on_camera->translation().isApprox(Eigen::Vector3d(0.15, 0, 0)));
  EXPECT_TRUE(s.projector.world_T_projector.isApprox(s.world_T_desired * *s.projector.on_camera));
  EXPECT_FALSE(load_scenario(kScenarios + "plane.yaml").projector.on_camera.has_value());
  std::string e = error_of(variant("mount_bad", "projector:\n", "projector:\n  mount: ceiling\n"));
  EXPECT_NE(e.find("projector.mount: must be world or camera"), std::string::npos) << e;
  // on the camera, the plane.yaml projector's pose looks away from the wall: nothing lit is seen
  const std::string away = variant("mount_away", "projector:\n", "projector:\n  mount: camera\n");
  try {
    build_cell(load_scenario(away));
    ADD_FAILURE() << "a projector lighting nothing the camera sees was built";
  } catch (const ScenarioError& x) {
    e = x.what();
  }
  std::remove(away.c_str());
  EXPECT_NE(e.find("mounted on the camera, it lights 0 spots"), std::string::npos) << e;
  EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 0) << e;
}

TEST(Scenario, OffsetConventionIsTranslationThenIntrinsicXYZ) {
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d T = offset_pose(I, {10, 0, 0}, {0, 0, 90});
  EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(0.1, 0, 0)));
  EXPECT_TRUE((T.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));
  // a frame turned 180 deg about X flips the meaning of Y and Z translations
  const Eigen::Isometry3d F = offset_pose(I, {0, 10, 0}, {0, 0, 0}, {180, 0, 0});
  EXPECT_TRUE(F.translation().isApprox(Eigen::Vector3d(0, -0.1, 0)));
}

TEST(Scenario, ResolvePose) {
  const Scenario s = load_scenario(kScenarios + "plane.yaml");
  EXPECT_TRUE(resolve_pose(s, "desired").isApprox(s.world_T_desired));
  EXPECT_TRUE(resolve_pose(s, "initial").isApprox(s.world_T_initial()));
  EXPECT_TRUE(resolve_pose(s, "0 0 0 0 0 0").isApprox(s.world_T_desired));
  EXPECT_THROW(resolve_pose(s, "1 2 3"), std::invalid_argument);
  EXPECT_THROW(resolve_pose(s, "nan 0 0 0 0 0"), std::invalid_argument);
}

void expect_one_line(const std::string& e, const std::string& file_part, const std::string& key,
                     const std::string& what) {
  EXPECT_NE(e.find(file_part), std::string::npos) << e;
  EXPECT_NE(e.find(key), std::string::npos) << e;
  EXPECT_NE(e.find(what), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
}

TEST(Scenario, UnknownKey) {
  const std::string e = error_of(variant("unknown", "  noise_sigma: 1.5", "  noise_sigmaa: 1.5"));
  expect_one_line(e, "_test_unknown.yaml", "camera.noise_sigmaa", "unknown key");
}

TEST(Scenario, WrongType) {
  const std::string e = error_of(variant("type", "exposure: 0.9", "exposure: bright"));
  expect_one_line(e, "_test_type.yaml", "camera.exposure", "must be a number");
}

TEST(Scenario, MissingMesh) {
  const std::string e = error_of(variant("mesh", "meshes/plane.obj", "meshes/no_such.obj"));
  expect_one_line(e, "_test_mesh.yaml", "objects[0].mesh", "file not found");
}

TEST(Scenario, NonPositiveFocalLength) {
  const std::string e = error_of(variant("focal", "focal_px: [800, 800]", "focal_px: [800, -800]"));
  expect_one_line(e, "_test_focal.yaml", "camera.focal_px[1]", "must be in [1, 100000]");
}

TEST(Scenario, NaN) {
  const std::string e = error_of(variant("nan", "ambient: 0.05", "ambient: .nan"));
  expect_one_line(e, "_test_nan.yaml", "camera.ambient", "finite");
}

TEST(Scenario, MissingKeyAndBadYaml) {
  expect_one_line(error_of(variant("nokey", "seed: 1\n", "")), "_test_nokey.yaml", "seed", "missing");
  expect_one_line(error_of(variant("syntax", "name: plane", "name: [plane")), "_test_syntax.yaml", "line",
                  "YAML syntax error");
  EXPECT_NE(error_of("/nonexistent/s.yaml").find("scenario file not found"), std::string::npos);
}


// Issue 9, items 3-5 and 15-16: values that used to pass the reader and then divide by almost
// nothing, overflow, or allocate gigabytes are refused at load, naming file, key and value.
TEST(Scenario, RefusesValuesThatWouldBreakTheSimulation) {
  expect_one_line(error_of(variant("dt", "dt_s: 0.04", "dt_s: 1e-12")), "_test_dt.yaml", "timing.dt_s", "1e-12");
  expect_one_line(error_of(variant("huge", "resolution: [640, 480]", "resolution: [16384, 16384]")), "_test_huge.yaml",
                  "camera.resolution", "16384");
  expect_one_line(error_of(variant("tinyf", "focal_px: [800, 800]", "focal_px: [1e-300, 800]")), "_test_tinyf.yaml",
                  "camera.focal_px[0]", "1e-300");
  expect_one_line(error_of(variant("pp", "focal_px: [800, 800]", "focal_px: [800, 800]\n  principal_point_px: [1e300, 10]")),
                  "_test_pp.yaml", "camera.principal_point_px[0]", "1e300");
  expect_one_line(error_of(variant("dist", "distortion: [-0.08,", "distortion: [-1e300,")), "_test_dist.yaml",
                  "camera.distortion[0]", "-1e300");
}

TEST(Scenario, RefusesAliasBombsDuplicateKeysAndOddKeys) {
  // 5,000 objects aliased from one: a 36 kB file that used to build 5,000 Bullet bodies
  std::string text = read(kScenarios + "plane.yaml");
  const auto a = text.find("objects:");
  const auto b = text.find("projector:");
  std::string objs = "objects:\n";
  for (int i = 0; i < 5000; ++i) objs += "  - {mesh: ../../meshes/plane.obj, position_m: [1.4, 0.0, 0.4]}\n";
  text.replace(a, b - a, objs);
  for (std::size_t p; (p = text.find("../../")) != std::string::npos;) text.replace(p, 6, std::string(CELL_SOURCE_DIR) + "/");
  const std::string path = (std::filesystem::temp_directory_path() / "_test_many.yaml").string();
  std::ofstream(path) << text;
  expect_one_line(error_of(path), "_test_many.yaml", "objects", "limit of 64");
  expect_one_line(error_of(variant("dup", "seed: 1\n", "seed: 1\nseed: 2\n")), "_test_dup.yaml", "seed", "twice");
  expect_one_line(error_of(variant("listkey", "seed: 1\n", "seed: 1\n[a, b]: 3\n")), "_test_listkey.yaml", "key",
                  "plain word");
  // binary bytes in a value are shown escaped, never raw
  const std::string e = error_of(variant("bin", "seed: 1", "seed: \"\\x01\\x02\\xff\""));
  EXPECT_EQ(e.find('\x01'), std::string::npos) << e;
  EXPECT_NE(e.find("seed"), std::string::npos) << e;
}

TEST(Scenario, ResetPosesOutsideTheWorkspaceAreRefused) {
  const Scenario s = load_scenario(kScenarios + "plane.yaml");
  EXPECT_NO_THROW(resolve_pose(s, "10 0 0 0 0 5"));
  try {
    resolve_pose(s, "1e300 0 0 0 0 0");
    FAIL() << "accepted a pose 1e298 m away";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("beyond 100 m"), std::string::npos) << e.what();
  }
  try {
    resolve_pose(s, "500 0 0 0 0 0");
    FAIL() << "accepted a pose 5 m away";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("outside the workspace"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(s.workspace.contains(s.world_T_desired.translation()));
  EXPECT_TRUE(s.workspace.contains(s.world_T_initial().translation()));
}

}  // namespace
}  // namespace sim

namespace sim {
namespace {

// Issue 20: a scenario is a spec. read_scenario reads no URDF and runs no IK (its library
// links neither, checked at configure time); load_scenario resolves the arm and says which key
// fails, with the same words as before the split.
TEST(Scenario, TheSpecReadsNoUrdfAndTheArmIsResolvedByLoadScenario) {
  const Scenario spec = read_scenario(kScenarios + "plane.yaml");
  EXPECT_TRUE(spec.robot.arm_enabled);
  EXPECT_EQ(spec.robot.model, nullptr);
  EXPECT_EQ(spec.robot.desired_q.size(), 0);
  const Scenario full = load_scenario(kScenarios + "plane.yaml");
  ASSERT_NE(full.robot.model, nullptr);
  EXPECT_EQ(full.robot.desired_q.size(), 6);
  EXPECT_EQ(full.robot.chain_segments, full.robot.model->chain.size());
  // the spec's poses are the file's; resolving the arm keeps them when no joint angles are given
  EXPECT_TRUE(spec.world_T_desired.isApprox(full.world_T_desired, 0));
  // a URDF that is not one: the spec still reads, the resolution names robot.urdf
  const std::string broken = (std::filesystem::temp_directory_path() / "_test_broken.urdf").string();
  std::ofstream(broken) << "<robot name='x'><link name='a'/>";
  const std::string path = variant("broken_urdf", "urdf: ../../sim/robots/ur5e/ur5e.urdf", "urdf: " + broken);
  EXPECT_NO_THROW(read_scenario(path));
  const std::string e = error_of(path);
  EXPECT_NE(e.find(": robot.urdf: "), std::string::npos) << e;
  std::remove(broken.c_str());
}

}  // namespace
}  // namespace sim
