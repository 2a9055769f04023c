#include "servo/messages/servo_messages.hpp"

#include <cmath>

#include "dds/topics.hpp"

namespace servo {

Stamp to_stamp(const builtin_interfaces::msg::dds_::Time_& t) { return {t.sec(), t.nanosec()}; }

builtin_interfaces::msg::dds_::Time_ to_time(const Stamp& s) {
  builtin_interfaces::msg::dds_::Time_ t;
  t.sec(s.sec);
  t.nanosec(s.nanosec);
  return t;
}

std::optional<SimFrameStatus> frame_status(const cell_msgs::msg::dds_::SimStatus_& s) {
  namespace SST = cell_msgs::msg::dds_::SimStatus_Constants;
  if (s.state() == SST::LOADING || s.state() == SST::NOTICE || s.state() == SST::ENDED) return std::nullopt;
  return SimFrameStatus{to_stamp(s.header().stamp()), s.applies_twist(), s.state() == SST::TEACHING,
                        s.state() == SST::RUNNING};
}

std::optional<Eigen::Isometry3d> camera_pose(const geometry_msgs::msg::dds_::PoseStamped_& p) {
  const auto& q = p.pose().orientation();
  const Eigen::Quaterniond quat(q.w(), q.x(), q.y(), q.z());
  if (!(std::isfinite(quat.norm()) && std::abs(quat.norm() - 1.0) < 1e-3)) return std::nullopt;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(p.pose().position().x(), p.pose().position().y(), p.pose().position().z());
  T.linear() = quat.normalized().toRotationMatrix();
  return T;
}

CameraInfoMsg to_info(const sensor_msgs::msg::dds_::CameraInfo_& c) {
  CameraInfoMsg m;
  m.width = c.width();
  m.height = c.height();
  m.k.assign(c.k().begin(), c.k().end());
  m.d = c.d();
  return m;
}

ImageView image_view(const sensor_msgs::msg::dds_::Image_& img) {
  return ImageView{to_stamp(img.header().stamp()), img.encoding(), img.width(), img.height(), img.step(),
                   img.is_bigendian(), img.data().data(), img.data().size()};
}

geometry_msgs::msg::dds_::TwistStamped_ twist_message(const ServoReply& r) {
  geometry_msgs::msg::dds_::TwistStamped_ t;
  t.header().stamp(to_time(r.stamp));
  t.header().frame_id(cell_dds::kCameraFrame);
  t.twist().linear().x(r.twist[0]);
  t.twist().linear().y(r.twist[1]);
  t.twist().linear().z(r.twist[2]);
  t.twist().angular().x(r.twist[3]);
  t.twist().angular().y(r.twist[4]);
  t.twist().angular().z(r.twist[5]);
  return t;
}

cell_msgs::msg::dds_::ServoStatus_ status_message(const ServoReply& r) {
  cell_msgs::msg::dds_::ServoStatus_ s;
  s.header().stamp(to_time(r.stamp));
  s.header().frame_id(cell_dds::kCameraFrame);
  s.state(static_cast<uint8_t>(r.state));
  s.iteration(r.iteration);
  s.error_norm(r.error_norm);
  s.decoded(r.decoded);
  s.matched(r.matched);
  s.reason(r.reason);
  return s;
}

cell_msgs::msg::dds_::DecodedSpots_ spots_message(const ServoReply& r) {
  cell_msgs::msg::dds_::DecodedSpots_ m;
  m.header().stamp(to_time(r.stamp));
  m.header().frame_id(cell_dds::kCameraFrame);
  m.detected(static_cast<uint32_t>(r.detected));
  for (const auto& s : *r.spots) {
    cell_msgs::msg::dds_::Spot_ x;
    x.row(static_cast<int16_t>(s.row));
    x.col(static_cast<int16_t>(s.col));
    x.u(s.u);
    x.v(s.v);
    m.spots().push_back(x);
  }
  return m;
}

}  // namespace servo
