// A robot arm as robotics people describe it: a URDF file, read with urdfdom. What the sim
// needs of it is the serial chain from the root link to a named camera link (the camera's
// optical frame, z forward): each joint's placement, axis and limits, and each link's
// shape (meshes read with assimp after the same checks as the scene's) and inertia.
// Plain data, validated at load: a malformed URDF or mesh is refused in one line naming
// the file and what is wrong.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim/scene/triangle_mesh.hpp"

namespace sim {

class RobotModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Limits every URDF is checked against (docs/topics.md, Safety).
inline constexpr std::uintmax_t kMaxUrdfBytes = 1u << 20;
inline constexpr std::size_t kMaxChainSegments = 32;   // links from the root to the camera link
inline constexpr std::size_t kMaxArmTriangles = 400'000;
inline constexpr std::size_t kMaxUrdfDepth = 64;          // XML nesting (the parser recurses)
inline constexpr std::size_t kMaxUrdfElements = 100'000;

enum class JointType { kFixed, kRevolute, kPrismatic };

// A link's shape, in the link's frame (the URDF origin and scale applied).
struct LinkShape {
  TriangleMesh visual;     // drawn and hit by light
  TriangleMesh collision;  // its convex hull collides (Bullet); the visual when none is given
  float albedo = 0.45f;
};

// One step of the chain: a joint and the link it carries.
struct ChainSegment {
  std::string joint;
  std::string link;
  JointType type = JointType::kFixed;
  Eigen::Isometry3d parent_T_origin = Eigen::Isometry3d::Identity();  // URDF <origin>
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();                    // unit, in the origin frame
  bool continuous = false;
  double lower = 0, upper = 0;  // rad or m (continuous: -+2 pi, the sim's own wrap)
  double max_velocity = 0;      // rad/s or m/s
  double max_effort = 0;        // N m or N
  // inertia of the link it carries (URDF <inertial>; a light default when absent)
  double mass = 0.1;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();  // in the link frame
  Eigen::Vector3d inertia_diagonal = Eigen::Vector3d::Constant(1e-4);
  LinkShape shape;
  bool has_shape = false;
};

struct RobotModel {
  std::filesystem::path file;
  std::string name;
  std::string urdf;           // the file's text, for rt/robot_description
  std::string root_link;
  LinkShape root_shape;
  bool root_has_shape = false;
  std::vector<ChainSegment> chain;  // root -> camera link, in order
  std::string camera_link;

  int dof() const;
  std::vector<std::string> joint_names() const;  // the moving joints, in chain order
  Eigen::VectorXd lower_limits() const;
  Eigen::VectorXd upper_limits() const;
  Eigen::VectorXd velocity_limits() const;
  Eigen::VectorXd effort_limits() const;
};

// Reads the URDF and the chain to `camera_link`. Throws RobotModelError ("<file>: <what>")
// for unreadable XML, a missing camera link, a non-serial path, joints without limits, or
// values that are not finite or out of range; MeshError for an unusable mesh.
RobotModel load_robot_model(const std::filesystem::path& urdf_file, const std::string& camera_link);

}  // namespace sim
