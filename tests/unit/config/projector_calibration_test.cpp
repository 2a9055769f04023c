// The projector calibration file: what write_projector_calibration writes,
// load_projector_calibration reads back, and a broken file is one line naming it.
#include "servo/calibration/projector_calibration.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <unistd.h>

namespace {

std::string temp_file(const char* name) {
  return (std::filesystem::temp_directory_path() / (std::string(name) + "_" + std::to_string(::getpid()))).string();
}

TEST(ProjectorCalibration, WhatIsWrittenIsReadBack) {
  calibration::ProjectorModel m;
  m.fx = 1512.25, m.fy = 1498.5, m.cx = 510.75, m.cy = 384.125;
  m.spot_pitch_px = 14.5;
  m.rows = 20, m.cols = 20;
  m.world_T_projector = Eigen::Isometry3d::Identity();
  m.world_T_projector.translation() = Eigen::Vector3d(0.4, -0.2, 1.1);
  m.world_T_projector.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const std::string f = temp_file("projector_calibration.yaml");
  calibration::write_projector_calibration(m, f, "written by a test");
  const calibration::ProjectorModel r = calibration::load_projector_calibration(f);
  EXPECT_DOUBLE_EQ(r.fx, m.fx);
  EXPECT_DOUBLE_EQ(r.fy, m.fy);
  EXPECT_DOUBLE_EQ(r.cx, m.cx);
  EXPECT_DOUBLE_EQ(r.cy, m.cy);
  EXPECT_DOUBLE_EQ(r.spot_pitch_px, m.spot_pitch_px);
  EXPECT_EQ(r.rows, 20);
  EXPECT_EQ(r.cols, 20);
  EXPECT_TRUE(r.world_T_projector.isApprox(m.world_T_projector, 1e-10));
  std::ifstream in(f);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "# written by a test");
  std::remove(f.c_str());
}

// Issue 44: a projector on the camera is written with `mount: camera` and its pose in the
// camera's frame, read back as such (camera_T_projector the same wherever the camera stands);
// another mount is one line naming the key.
TEST(ProjectorCalibration, AProjectorOnTheCameraKeepsItsMount) {
  calibration::ProjectorModel m;
  Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();
  mount.translation() = Eigen::Vector3d(0.15, 0, 0);
  mount.linear() = Eigen::AngleAxisd(-0.165, Eigen::Vector3d::UnitY()).toRotationMatrix();
  m.on_camera = mount;
  const std::string f = temp_file("projector_on_camera.yaml");
  calibration::write_projector_calibration(m, f, "on the camera");
  const calibration::ProjectorModel r = calibration::load_projector_calibration(f);
  ASSERT_TRUE(r.on_camera.has_value());
  EXPECT_TRUE(r.on_camera->isApprox(mount, 1e-10));
  Eigen::Isometry3d somewhere = Eigen::Isometry3d::Identity();
  somewhere.translation() = Eigen::Vector3d(1, 2, 3);
  EXPECT_TRUE(r.camera_T_projector(somewhere).isApprox(mount, 1e-10));
  std::ifstream in(f);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(f) << std::regex_replace(text, std::regex("mount: camera"), "mount: wall");
  try {
    calibration::load_projector_calibration(f);
    ADD_FAILURE() << "a mount on the wall was read";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("mount: must be world or camera"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  std::remove(f.c_str());
}

TEST(ProjectorCalibration, AFolderThatCannotBeWrittenIsNamed) {
  try {
    calibration::write_projector_calibration({}, "/proc/no/such/folder/p.yaml", "x");
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/no/such/folder/p.yaml"), std::string::npos) << e.what();
  }
}

}  // namespace
