// The arm in Bullet: a btMultiBody built from the RobotModel (one body per moving joint,
// fixed links merged into the body that carries them), convex hulls of the link meshes as
// colliders, velocity motors with the URDF's effort limits, joint limit stops, gravity,
// stepped at a fixed physics period in a btMultiBodyDynamicsWorld that also holds the
// cell's static objects. Contacts are checked after every step: the arm touching an
// object, or two links that are not neighbours touching, is reported (the caller stops).
// Deterministic: reset() rebuilds the dynamics world, so the state after it depends only
// on the joint angles given.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim/arm/robot_model.hpp"
#include "sim/scene/world.hpp"

namespace sim {

class BulletArm {
 public:
  // `objects` and `object_names` must outlive the arm (the cell owns them).
  BulletArm(const RobotModel& model, const Eigen::Isometry3d& world_T_base, const World& objects,
            std::vector<std::string> object_names, double physics_period_s);
  ~BulletArm();
  BulletArm(const BulletArm&) = delete;
  BulletArm& operator=(const BulletArm&) = delete;

  double period() const { return h_; }
  void reset(const Eigen::VectorXd& q);
  // One physics period with the motors aiming at velocity qdot and position q_ref (the
  // integrated velocity reference, as a joint servo holds it: gravity does not make the
  // arm drift). Returns the first forbidden contact.
  std::optional<std::string> step(const Eigen::VectorXd& qdot, const Eigen::VectorXd& q_ref);
  // Forbidden contacts in the present state (after reset: is the start collision-free?).
  std::optional<std::string> contact();
  Eigen::VectorXd q() const;
  Eigen::VectorXd qdot() const;

 private:
  std::optional<std::string> first_contact() const;

  struct Bullet;
  std::unique_ptr<Bullet> b_;
  double h_;
};

}  // namespace sim
