#include "sim/messages/cell_messages.hpp"

#include "dds/topics.hpp"
#include "sim/arm/robot_model.hpp"

namespace sim::wire {
namespace {

namespace SST = cell_msgs::msg::dds_::SimStatus_Constants;

// A pose into the two shapes ROS gives it: (translation, rotation) of a transform, (position,
// orientation) of a pose; both hold x y z and x y z w.
template <typename Point, typename Quaternion>
void fill_pose(Point& p, Quaternion& r, const Eigen::Isometry3d& t) {
  const Eigen::Quaterniond q(t.rotation());
  p.x(t.translation().x());
  p.y(t.translation().y());
  p.z(t.translation().z());
  r.x(q.x());
  r.y(q.y());
  r.z(q.z());
  r.w(q.w());
}

// what every status carries: the session's counts, its latest refusals, why it ended
void with_counts(cell_msgs::msg::dds_::SimStatus_& st, const sim::CellStateMachine& cell,
                 const std::deque<std::string>& refusals) {
  const sim::CellCounters& c = cell.counters();
  st.twists_applied(static_cast<std::uint64_t>(c.applied));
  st.twists_rejected(static_cast<std::uint64_t>(c.rejected_nan + c.rejected_frame + c.rejected_stale + c.rejected_workspace));
  st.commands_refused(static_cast<std::uint32_t>(c.commands_refused));
  st.recent_refusals(std::vector<std::string>(refusals.begin(), refusals.end()));
  st.session_end(cell.session_end().reason);
}

geometry_msgs::msg::dds_::TransformStamped_ transform(const Stamp& stamp, const std::string& parent,
                                                      const std::string& child, const Eigen::Isometry3d& t) {
  geometry_msgs::msg::dds_::TransformStamped_ m;
  m.header().stamp(stamp);
  m.header().frame_id(parent);
  m.child_frame_id(child);
  fill_pose(m.transform().translation(), m.transform().rotation(), t);
  return m;
}

}  // namespace

cell_msgs::msg::dds_::SimStatus_ frame_status(const sim::FrameOrder& f, const sim::CellStateMachine& cell,
                                              const Stamp& stamp, const std::deque<std::string>& refusals) {
  cell_msgs::msg::dds_::SimStatus_ st;
  st.header().stamp(stamp);
  st.header().frame_id(cell_dds::kCameraFrame);
  st.state(f.teach ? SST::TEACHING : !f.applies_twist ? SST::IDLE : cell.running() ? SST::RUNNING : SST::STEPPING);
  st.applies_twist(f.applies_twist);
  st.frame(f.index);
  st.robot_limits(f.robot_limits);
  st.robot_limit_names(sim::limit_names(f.robot_limits));
  with_counts(st, cell, refusals);
  return st;
}

cell_msgs::msg::dds_::SimStatus_ status_between_frames(std::uint8_t state, const sim::CellStateMachine& cell,
                                                       const std::deque<std::string>& refusals) {
  cell_msgs::msg::dds_::SimStatus_ st;
  st.header().stamp(cell_dds::stamp_of(cell.next_frame(), cell.dt()));
  st.header().frame_id(cell_dds::kCameraFrame);
  st.state(state);
  st.applies_twist(false);
  st.frame(cell.next_frame());
  with_counts(st, cell, refusals);
  return st;
}

geometry_msgs::msg::dds_::PoseStamped_ camera_pose(const sim::FrameOrder& f, const Stamp& stamp) {
  geometry_msgs::msg::dds_::PoseStamped_ pose;
  pose.header().stamp(stamp);
  pose.header().frame_id(cell_dds::kWorldFrame);
  fill_pose(pose.pose().position(), pose.pose().orientation(), f.reported_world_T_camera);
  return pose;
}

bool has_joints(const sim::Scenario& s, const sim::FrameOrder& f) {
  return s.robot.model && f.world_T_links.size() == s.robot.model->chain.size() + 1;
}

tf2_msgs::msg::dds_::TFMessage_ transforms(const sim::Scenario& s, const sim::FrameOrder& f, const Stamp& stamp) {
  tf2_msgs::msg::dds_::TFMessage_ tf;
  if (!has_joints(s, f)) {
    tf.transforms().push_back(transform(stamp, cell_dds::kWorldFrame, cell_dds::kCameraFrame, f.reported_world_T_camera));
    return tf;
  }
  const auto& model = s.robot.model;
  tf.transforms().push_back(transform(stamp, cell_dds::kWorldFrame, model->root_link, f.world_T_links[0]));
  for (std::size_t i = 0; i < model->chain.size(); ++i)
    tf.transforms().push_back(transform(stamp, i == 0 ? model->root_link : model->chain[i - 1].link, model->chain[i].link,
                                        f.world_T_links[i].inverse() * f.world_T_links[i + 1]));
  return tf;
}

sensor_msgs::msg::dds_::JointState_ joint_state(const sim::FrameOrder& f, const Stamp& stamp) {
  sensor_msgs::msg::dds_::JointState_ js;
  js.header().stamp(stamp);
  js.name(f.joint_names);
  js.position(std::vector<double>(f.joint_positions.data(), f.joint_positions.data() + f.joint_positions.size()));
  js.velocity(std::vector<double>(f.joint_velocities.data(), f.joint_velocities.data() + f.joint_velocities.size()));
  return js;
}

cell_msgs::msg::dds_::SpotTruthArray_ spot_truth(const sim::Cell& cell, const sim::FrameOrder& f, const Stamp& stamp) {
  cell_msgs::msg::dds_::SpotTruthArray_ truth;
  truth.header().stamp(stamp);
  truth.header().frame_id(cell_dds::kCameraFrame);
  for (const auto& t : sim::compute_truth(cell, f.scene_world_T_camera, &f.scene_world_T_links)) {
    cell_msgs::msg::dds_::SpotTruth_ s;
    s.row(static_cast<int16_t>(t.row));
    s.col(static_cast<int16_t>(t.col));
    s.visible(t.visible);
    s.u(t.uv.x());
    s.v(t.uv.y());
    s.depth_m(t.depth_m);
    truth.spots().push_back(s);
  }
  return truth;
}

sensor_msgs::msg::dds_::Image_ image(const cv::Mat& rgb, const Stamp& stamp) {
  sensor_msgs::msg::dds_::Image_ img;
  img.header().stamp(stamp);
  img.header().frame_id(cell_dds::kCameraFrame);
  img.height(static_cast<uint32_t>(rgb.rows));
  img.width(static_cast<uint32_t>(rgb.cols));
  img.encoding("rgb8");
  img.is_bigendian(0);
  img.step(static_cast<uint32_t>(rgb.cols * 3));
  img.data().assign(rgb.data, rgb.data + rgb.total() * 3);
  return img;
}

rosgraph_msgs::msg::dds_::Clock_ clock(const Stamp& stamp) {
  rosgraph_msgs::msg::dds_::Clock_ clk;
  clk.clock(stamp);
  return clk;
}

sensor_msgs::msg::dds_::CameraInfo_ camera_info(const sim::Scenario& s, const Stamp& stamp) {
  const sim::CameraSpec believed = sim::believed_camera(s.camera, sim::scenario_errors(s));
  const sim::Intrinsics& k = believed.intrinsics;
  const auto& size = s.camera.intrinsics;
  sensor_msgs::msg::dds_::CameraInfo_ ci;
  ci.header().stamp(stamp);
  ci.header().frame_id(cell_dds::kCameraFrame);
  ci.height(static_cast<uint32_t>(size.height));
  ci.width(static_cast<uint32_t>(size.width));
  ci.distortion_model("plumb_bob");
  const auto& d = believed.distortion;
  ci.d(std::vector<double>(d.begin(), d.end()));
  ci.k({k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1});
  ci.r({1, 0, 0, 0, 1, 0, 0, 0, 1});
  ci.p({k.fx, 0, k.cx, 0, 0, k.fy, k.cy, 0, 0, 0, 1, 0});
  return ci;
}

std_msgs::msg::dds_::String_ description(const sim::Scenario& s) {
  std_msgs::msg::dds_::String_ d;
  if (s.robot.model) d.data(s.robot.model->urdf);
  return d;
}

cell_msgs::msg::dds_::SimControl_ control(const sim::CommandMsg& c) {
  cell_msgs::msg::dds_::SimControl_ m;
  m.command(static_cast<uint8_t>(c.command));
  m.argument(c.argument);
  m.steps(c.steps);
  return m;
}

}  // namespace sim::wire
