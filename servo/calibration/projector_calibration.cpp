#include "servo/calibration/projector_calibration.hpp"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <string>

#include "common/output_file.hpp"
#include "common/strict_yaml.hpp"
#include "servo/pattern/pattern_file.hpp"

namespace calibration {

calibration::ProjectorModel load_projector_calibration(const std::filesystem::path& file) {
  using common::Reader;
  try {
    const Reader top(file, common::load_yaml_file(file, "projector calibration"));
    top.only_keys({"fx", "fy", "cx", "cy", "spot_pitch_px", "rows", "cols", "mount", "position_m", "orientation_xyzw"});
    calibration::ProjectorModel m;
    m.fx = top.at("fx").in_range(1, 1e5);
    m.fy = top.at("fy").in_range(1, 1e5);
    m.cx = top.at("cx").in_range(-1e5, 1e5);
    m.cy = top.at("cy").in_range(-1e5, 1e5);
    m.spot_pitch_px = top.at("spot_pitch_px").in_range(1e-3, 1e4);
    m.rows = top.at("rows").integer_in(3, pattern::kMaxPatternSide);
    m.cols = top.at("cols").integer_in(3, pattern::kMaxPatternSide);
    const auto p = top.at("position_m").numbers_in<3>(-100, 100);
    const Reader qr = top.at("orientation_xyzw");
    const auto q = qr.numbers_in<4>(-1.001, 1.001);
    const Eigen::Quaterniond quat(q[3], q[0], q[1], q[2]);
    // a rotation is a unit quaternion: a zero or scaled one is a broken file, not a rotation
    if (std::abs(quat.norm() - 1.0) > 1e-3) {
      char norm[32];
      std::snprintf(norm, sizeof norm, "%.6g", quat.norm());
      qr.fail(std::string("must be a unit quaternion [x, y, z, w], its norm is ") + norm);
    }
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
    pose.linear() = quat.normalized().toRotationMatrix();
    // mount: world (the default) or camera, whose frame the pose is then given in
    const std::string mount = top.has("mount") ? top.at("mount").text(16) : "world";
    if (mount == "camera")
      m.on_camera = pose;
    else if (mount == "world")
      m.world_T_projector = pose;
    else
      top.at("mount").fail("must be world or camera");
    return m;
  } catch (const common::ConfigError& e) {
    throw std::runtime_error(e.what());
  }
}

void write_projector_calibration(const calibration::ProjectorModel& m, const std::filesystem::path& file,
                                 const std::string& comment) {
  const Eigen::Isometry3d& pose = m.on_camera ? *m.on_camera : m.world_T_projector;
  const Eigen::Quaterniond q(pose.rotation());
  const Eigen::Vector3d t = pose.translation();
  std::ostringstream f;
  f << std::setprecision(12) << "# " << comment << "\n"
    << "fx: " << m.fx << "\nfy: " << m.fy << "\ncx: " << m.cx << "\ncy: " << m.cy
    << "\nspot_pitch_px: " << m.spot_pitch_px << "\nrows: " << m.rows << "\ncols: " << m.cols
    << (m.on_camera ? "\nmount: camera  # the pose below is the camera's frame's" : "") << "\nposition_m: ["
    << t.x() << ", " << t.y() << ", " << t.z() << "]\norientation_xyzw: [" << q.x() << ", " << q.y() << ", " << q.z()
    << ", " << q.w() << "]\n";
  common::write_output_file(file, f.str(), "projector calibration");
}

void check_projector_against_pattern(const calibration::ProjectorModel& m, const pattern::MArray& marray,
                                     const std::filesystem::path& pattern_file) {
  if (m.rows != marray.rows || m.cols != marray.cols)
    throw std::runtime_error("projector calibration: " + std::to_string(m.rows) + " x " + std::to_string(m.cols) +
                             " spots, but the pattern " + pattern_file.string() + " is " + std::to_string(marray.rows) +
                             " x " + std::to_string(marray.cols));
}

}  // namespace calibration
