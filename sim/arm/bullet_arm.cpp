#include "sim/arm/bullet_arm.hpp"

#include <BulletCollision/CollisionShapes/btShapeHull.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointLimitConstraint.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointMotor.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>
#include <btBulletDynamicsCommon.h>

#include <stdexcept>

namespace sim {
namespace {

btVector3 bt(const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }

btTransform bt(const Eigen::Isometry3d& t) {
  const Eigen::Quaterniond q(t.rotation());
  return btTransform(btQuaternion(btScalar(q.x()), btScalar(q.y()), btScalar(q.z()), btScalar(q.w())), bt(t.translation()));
}

// collision groups: the base sits on the cell's table and may touch it
constexpr int kGroupBase = 1, kGroupLink = 2, kGroupObject = 4;
constexpr btScalar kMargin = btScalar(0.001);
// the joint servo's position correction: this fraction of the error per physics period
constexpr double kPositionGain = 0.05;
constexpr btScalar kTouch = 0;  // closer than the two margins (2 mm): a contact

// One Bullet body: a moving joint's link and the fixed links it carries.
struct Body {
  int segment = -1;  // chain index of its moving joint (-1: the base)
  std::string name;  // the moving link's name
  double mass = 0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();  // in the body (link) frame
  Eigen::Vector3d inertia = Eigen::Vector3d::Constant(1e-4);
  // its collision: the convex hulls of these parts (in the body frame), one per connected piece
  // of each mesh: a link built of several pieces (a joint housing and an offset tube) is not
  // one hull spanning the space between them
  std::vector<std::vector<Eigen::Vector3d>> parts;
  Eigen::Isometry3d parent_T_origin = Eigen::Isometry3d::Identity();  // parent body frame -> joint origin
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  bool prismatic = false;
  double lower = 0, upper = 0, effort = 0;
};

}  // namespace

struct BulletArm::Bullet {
  std::vector<Body> bodies;  // [0] = base
  Eigen::Isometry3d world_T_base;
  std::vector<std::unique_ptr<btCollisionShape>> hulls;  // per body, null when shapeless
  std::vector<std::unique_ptr<btConvexHullShape>> part_hulls;  // a compound body's children
  std::vector<std::unique_ptr<btTriangleMesh>> object_meshes;
  std::vector<std::unique_ptr<btBvhTriangleMeshShape>> object_shapes;
  std::vector<std::string> object_names;

  // rebuilt by reset()
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btMultiBodyConstraintSolver> solver;
  std::unique_ptr<btMultiBodyDynamicsWorld> world;
  std::unique_ptr<btMultiBody> mb;
  std::vector<std::unique_ptr<btMultiBodyLinkCollider>> colliders;
  std::vector<std::unique_ptr<btMultiBodyJointMotor>> motors;
  std::vector<std::unique_ptr<btMultiBodyJointLimitConstraint>> stops;
  std::vector<std::unique_ptr<btCollisionObject>> objects;

  void teardown() {
    if (world) {
      for (auto& m : motors) world->removeMultiBodyConstraint(m.get());
      for (auto& s : stops) world->removeMultiBodyConstraint(s.get());
      for (auto& c : colliders) world->removeCollisionObject(c.get());
      for (auto& o : objects) world->removeCollisionObject(o.get());
      if (mb) world->removeMultiBody(mb.get());
    }
    motors.clear();
    stops.clear();
    colliders.clear();
    objects.clear();
    mb.reset();
    world.reset();
    solver.reset();
    broadphase.reset();
    dispatcher.reset();
    config.reset();
  }
  ~Bullet() { teardown(); }
};

namespace {

// the most pieces one mesh may split into before it is taken as one hull: a mesh of many
// loose triangles (a scan) would otherwise become thousands of tiny shapes
constexpr std::size_t kMaxParts = 32;

// The mesh's connected pieces (triangles sharing vertices), each as its points in the body
// frame; appended to `parts`.
void add_parts(std::vector<std::vector<Eigen::Vector3d>>& parts, const TriangleMesh& mesh, const Eigen::Isometry3d& T) {
  const std::size_t n = mesh.vertices.size();
  std::vector<std::size_t> root(n);
  for (std::size_t i = 0; i < n; ++i) root[i] = i;
  const auto find = [&](std::size_t i) {
    while (root[i] != i) i = root[i] = root[root[i]];
    return i;
  };
  for (const auto& t : mesh.triangles)
    for (int k = 1; k < 3; ++k) root[find(static_cast<std::size_t>(t[0]))] = find(static_cast<std::size_t>(t[k]));
  std::vector<int> piece(n, -1);
  std::vector<std::vector<Eigen::Vector3d>> pieces;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t r = find(i);
    if (piece[r] < 0) {
      piece[r] = static_cast<int>(pieces.size());
      pieces.emplace_back();
    }
    pieces[static_cast<std::size_t>(piece[r])].push_back(T * mesh.vertices[i]);
  }
  if (pieces.size() > kMaxParts) {  // one hull of everything
    std::vector<Eigen::Vector3d> all;
    for (const auto& p : pieces) all.insert(all.end(), p.begin(), p.end());
    pieces = {all};
  }
  for (auto& p : pieces)
    if (p.size() >= 4) parts.push_back(std::move(p));  // fewer points span no volume
}

// The convex hull of the points (body frame) in the body's centre-of-mass frame (Bullet's link
// frame), simplified.
std::unique_ptr<btConvexHullShape> hull_of(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& com) {
  btConvexHullShape raw;
  for (const auto& p : points) raw.addPoint(bt(p - com), false);
  raw.recalcLocalAabb();
  raw.setMargin(0);
  btShapeHull simplified(&raw);
  simplified.buildHull(0);
  auto hull = std::make_unique<btConvexHullShape>();
  const btVector3* v = simplified.getVertexPointer();
  for (int k = 0; k < simplified.numVertices(); ++k) hull->addPoint(v[k], false);
  hull->recalcLocalAabb();
  hull->setMargin(kMargin);
  return hull;
}

}  // namespace

BulletArm::BulletArm(const RobotModel& model, const Eigen::Isometry3d& world_T_base, const World& objects,
                     std::vector<std::string> object_names, double physics_period_s)
    : b_(std::make_unique<Bullet>()), h_(physics_period_s) {
  if (!(h_ > 0 && h_ <= 0.004)) throw std::invalid_argument("BulletArm: the physics period must be in (0, 4 ms] (>= 250 Hz)");
  b_->world_T_base = world_T_base;
  b_->object_names = std::move(object_names);
  // bodies: fixed segments are merged into the body before them
  Body base;
  base.name = model.root_link;
  if (model.root_has_shape) add_parts(base.parts, model.root_shape.collision, Eigen::Isometry3d::Identity());
  b_->bodies.push_back(base);
  Eigen::Isometry3d body_T_link = Eigen::Isometry3d::Identity();  // last body's frame -> current link
  for (std::size_t i = 0; i < model.chain.size(); ++i) {
    const ChainSegment& s = model.chain[i];
    if (s.type == JointType::kFixed) {
      body_T_link = body_T_link * s.parent_T_origin;
      Body& b = b_->bodies.back();
      b.mass += b.segment >= 0 ? s.mass : 0.0;
      if (s.has_shape) add_parts(b.parts, s.shape.collision, body_T_link);
      continue;
    }
    Body b;
    b.segment = static_cast<int>(i);
    b.name = s.link;
    b.mass = s.mass;
    b.com = s.com;
    b.inertia = s.inertia_diagonal;
    b.parent_T_origin = body_T_link * s.parent_T_origin;
    b.axis = s.axis;
    b.prismatic = s.type == JointType::kPrismatic;
    b.lower = s.lower;
    b.upper = s.upper;
    b.effort = s.max_effort;
    if (s.has_shape) add_parts(b.parts, s.shape.collision, Eigen::Isometry3d::Identity());
    b_->bodies.push_back(std::move(b));
    body_T_link = Eigen::Isometry3d::Identity();
  }
  for (const Body& b : b_->bodies) {
    if (b.parts.empty()) {
      b_->hulls.emplace_back();
      continue;
    }
    if (b.parts.size() == 1) {
      b_->hulls.push_back(hull_of(b.parts.front(), b.com));
      continue;
    }
    auto compound = std::make_unique<btCompoundShape>();
    for (const auto& part : b.parts) {
      b_->part_hulls.push_back(hull_of(part, b.com));
      compound->addChildShape(btTransform::getIdentity(), b_->part_hulls.back().get());
    }
    compound->setMargin(kMargin);
    b_->hulls.push_back(std::move(compound));
  }
  for (const World::Object& o : objects.objects()) {
    auto tm = std::make_unique<btTriangleMesh>(true, false);
    for (const auto& t : o.triangles) tm->addTriangle(bt(o.vertices_w[t[0]]), bt(o.vertices_w[t[1]]), bt(o.vertices_w[t[2]]), false);
    auto shape = std::make_unique<btBvhTriangleMeshShape>(tm.get(), true);
    shape->setMargin(kMargin);
    b_->object_meshes.push_back(std::move(tm));
    b_->object_shapes.push_back(std::move(shape));
  }
  reset(Eigen::VectorXd::Zero(model.dof()));
}

BulletArm::~BulletArm() = default;

void BulletArm::reset(const Eigen::VectorXd& q) {
  Bullet& B = *b_;
  const int n = static_cast<int>(B.bodies.size()) - 1;
  if (q.size() != n || !q.allFinite()) throw std::invalid_argument("BulletArm::reset: wrong joint vector");
  B.teardown();
  B.config = std::make_unique<btDefaultCollisionConfiguration>();
  B.dispatcher = std::make_unique<btCollisionDispatcher>(B.config.get());
  B.broadphase = std::make_unique<btDbvtBroadphase>();
  B.solver = std::make_unique<btMultiBodyConstraintSolver>();
  B.world = std::make_unique<btMultiBodyDynamicsWorld>(B.dispatcher.get(), B.broadphase.get(), B.solver.get(), B.config.get());
  B.world->setGravity(btVector3(0, 0, btScalar(-9.81)));

  B.mb = std::make_unique<btMultiBody>(n, 0, btVector3(0, 0, 0), /*fixed base*/ true, /*can sleep*/ false);
  B.mb->setBaseWorldTransform(bt(B.world_T_base));
  for (int i = 0; i < n; ++i) {
    const Body& b = B.bodies[static_cast<std::size_t>(i) + 1];
    const Body& parent = B.bodies[static_cast<std::size_t>(i)];
    const Eigen::Quaterniond rot_parent_to_this(b.parent_T_origin.rotation().transpose());
    const btQuaternion r(btScalar(rot_parent_to_this.x()), btScalar(rot_parent_to_this.y()), btScalar(rot_parent_to_this.z()),
                         btScalar(rot_parent_to_this.w()));
    const btVector3 pivot = bt(b.parent_T_origin.translation() - parent.com);
    if (b.prismatic)
      B.mb->setupPrismatic(i, btScalar(b.mass), bt(b.inertia), i - 1, r, bt(b.axis), pivot, bt(b.com), true);
    else
      B.mb->setupRevolute(i, btScalar(b.mass), bt(b.inertia), i - 1, r, bt(b.axis), pivot, bt(b.com), true);
  }
  B.mb->finalizeMultiDof();
  B.mb->setHasSelfCollision(true);
  B.mb->setLinearDamping(0);
  B.mb->setAngularDamping(0);
  B.mb->setUseGyroTerm(true);
  for (int i = 0; i < n; ++i) {
    B.mb->setJointPos(i, btScalar(q[i]));
    B.mb->setJointVel(i, 0);
  }
  B.world->addMultiBody(B.mb.get());

  btAlignedObjectArray<btQuaternion> scratch_q;
  btAlignedObjectArray<btVector3> scratch_m;
  B.mb->forwardKinematics(scratch_q, scratch_m);
  B.mb->updateCollisionObjectWorldTransforms(scratch_q, scratch_m);
  for (int i = -1; i < n; ++i) {
    auto& hull = B.hulls[static_cast<std::size_t>(i + 1)];
    if (!hull) continue;
    auto c = std::make_unique<btMultiBodyLinkCollider>(B.mb.get(), i);
    c->setCollisionShape(hull.get());
    c->setUserIndex(i);
    if (i < 0) {
      c->setWorldTransform(B.mb->getBaseWorldTransform());
      B.mb->setBaseCollider(c.get());
      B.world->addCollisionObject(c.get(), kGroupBase, kGroupLink);
    } else {
      B.mb->getLink(i).m_collider = c.get();
      B.world->addCollisionObject(c.get(), kGroupLink, kGroupBase | kGroupLink | kGroupObject);
    }
    B.colliders.push_back(std::move(c));
  }
  B.mb->forwardKinematics(scratch_q, scratch_m);
  B.mb->updateCollisionObjectWorldTransforms(scratch_q, scratch_m);
  for (std::size_t k = 0; k < B.object_shapes.size(); ++k) {
    auto o = std::make_unique<btCollisionObject>();
    o->setCollisionShape(B.object_shapes[k].get());
    o->setUserIndex(-1000 - static_cast<int>(k));
    B.world->addCollisionObject(o.get(), kGroupObject, kGroupLink);
    B.objects.push_back(std::move(o));
  }
  for (int i = 0; i < n; ++i) {
    const Body& b = B.bodies[static_cast<std::size_t>(i) + 1];
    auto m = std::make_unique<btMultiBodyJointMotor>(B.mb.get(), i, 0, btScalar(b.effort * h_));
    B.world->addMultiBodyConstraint(m.get());
    B.motors.push_back(std::move(m));
    auto s = std::make_unique<btMultiBodyJointLimitConstraint>(B.mb.get(), i, btScalar(b.lower), btScalar(b.upper));
    B.world->addMultiBodyConstraint(s.get());
    B.stops.push_back(std::move(s));
  }
  B.world->updateAabbs();
}

std::optional<std::string> BulletArm::step(const Eigen::VectorXd& qdot, const Eigen::VectorXd& q_ref) {
  Bullet& B = *b_;
  const auto n = static_cast<Eigen::Index>(B.motors.size());
  if (qdot.size() != n || q_ref.size() != n || !qdot.allFinite() || !q_ref.allFinite())
    throw std::invalid_argument("BulletArm::step: joint vectors must be finite, one value per joint");
  for (Eigen::Index i = 0; i < n; ++i) {
    auto& m = *B.motors[static_cast<std::size_t>(i)];
    m.setVelocityTarget(btScalar(qdot[i]), 1);
    m.setPositionTarget(btScalar(q_ref[i]), btScalar(kPositionGain));
  }
  B.world->stepSimulation(btScalar(h_), 0, btScalar(h_));
  // the contacts the step itself found (at its start): a second detection would double the
  // cost of a step for one physics period's earlier warning
  return first_contact();
}

std::optional<std::string> BulletArm::contact() {
  b_->world->performDiscreteCollisionDetection();
  return first_contact();
}

std::optional<std::string> BulletArm::first_contact() const {
  const Bullet& B = *b_;
  const auto name_of = [&](const btCollisionObject* o) {
    const int id = o->getUserIndex();
    if (id <= -1000) return "object '" + B.object_names[static_cast<std::size_t>(-1000 - id)] + "'";
    return "link '" + B.bodies[static_cast<std::size_t>(id + 1)].name + "'";
  };
  for (int m = 0; m < B.dispatcher->getNumManifolds(); ++m) {
    const btPersistentManifold* pm = B.dispatcher->getManifoldByIndexInternal(m);
    for (int c = 0; c < pm->getNumContacts(); ++c) {
      if (pm->getContactPoint(c).getDistance() >= kTouch) continue;
      char depth[32];
      std::snprintf(depth, sizeof depth, "%.1f", -1e3 * pm->getContactPoint(c).getDistance());
      return name_of(pm->getBody0()) + " touches " + name_of(pm->getBody1()) + " (" + depth + " mm deep)";
    }
  }
  return std::nullopt;
}

Eigen::VectorXd BulletArm::q() const {
  const int n = b_->mb->getNumLinks();
  Eigen::VectorXd q(n);
  for (int i = 0; i < n; ++i) q[i] = b_->mb->getJointPos(i);
  return q;
}

Eigen::VectorXd BulletArm::qdot() const {
  const int n = b_->mb->getNumLinks();
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v[i] = b_->mb->getJointVel(i);
  return v;
}

}  // namespace sim
