#include "sim/scene/world.hpp"

#include <btBulletCollisionCommon.h>

#include <stdexcept>

namespace sim {

struct World::Bullet {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btCollisionWorld world{&dispatcher, &broadphase, &config};
  std::vector<std::unique_ptr<btTriangleMesh>> meshes;
  std::vector<std::unique_ptr<btBvhTriangleMeshShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> objects;
};

World::World() : bullet_(std::make_unique<Bullet>()) {}

World::~World() {
  for (auto& o : bullet_->objects) bullet_->world.removeCollisionObject(o.get());
}

int World::add_object(const TriangleMesh& mesh, const Eigen::Isometry3d& world_T_object, double albedo) {
  if (mesh.triangles.empty()) throw std::invalid_argument("World::add_object: mesh has no triangles");
  const int id = static_cast<int>(objects_.size());

  // Bullet holds the mesh in the object's frame; the object's transform places it
  auto tm = std::make_unique<btTriangleMesh>(/*32-bit indices*/ true, /*4 components*/ false);
  const auto bt = [](const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); };
  for (const auto& t : mesh.triangles)
    tm->addTriangle(bt(mesh.vertices[t[0]]), bt(mesh.vertices[t[1]]), bt(mesh.vertices[t[2]]), false);
  auto shape = std::make_unique<btBvhTriangleMeshShape>(tm.get(), /*quantized AABB compression*/ true);
  auto obj = std::make_unique<btCollisionObject>();
  obj->setCollisionShape(shape.get());
  btTransform tr;
  const Eigen::Matrix3d R = world_T_object.rotation();
  tr.setBasis(btMatrix3x3(btScalar(R(0, 0)), btScalar(R(0, 1)), btScalar(R(0, 2)), btScalar(R(1, 0)),
                          btScalar(R(1, 1)), btScalar(R(1, 2)), btScalar(R(2, 0)), btScalar(R(2, 1)),
                          btScalar(R(2, 2))));
  tr.setOrigin(bt(world_T_object.translation()));
  obj->setWorldTransform(tr);
  obj->setUserIndex(id);
  bullet_->world.addCollisionObject(obj.get());
  bullet_->world.updateAabbs();
  bullet_->meshes.push_back(std::move(tm));
  bullet_->shapes.push_back(std::move(shape));
  bullet_->objects.push_back(std::move(obj));

  Object o;
  o.albedo = albedo;
  o.triangles = mesh.triangles;
  o.vertices_w.reserve(mesh.vertices.size());
  for (const auto& v : mesh.vertices) o.vertices_w.push_back(world_T_object * v);
  objects_.push_back(std::move(o));
  return id;
}

std::optional<RayHit> World::ray_test(const Eigen::Vector3d& from_w, const Eigen::Vector3d& to_w) const {
  const btVector3 from(btScalar(from_w.x()), btScalar(from_w.y()), btScalar(from_w.z()));
  const btVector3 to(btScalar(to_w.x()), btScalar(to_w.y()), btScalar(to_w.z()));
  btCollisionWorld::ClosestRayResultCallback cb(from, to);
  bullet_->world.rayTest(from, to, cb);
  if (!cb.hasHit()) return std::nullopt;
  RayHit h;
  h.fraction = cb.m_closestHitFraction;
  // the hit point from the fraction in double precision: Bullet's float hit point would
  // cost ~0.1 um of accuracy at 1 m, this keeps the truth exact along the ray
  h.point_w = from_w + h.fraction * (to_w - from_w);
  h.normal_w = Eigen::Vector3d(cb.m_hitNormalWorld.x(), cb.m_hitNormalWorld.y(), cb.m_hitNormalWorld.z()).normalized();
  if (h.normal_w.dot(to_w - from_w) > 0) h.normal_w = -h.normal_w;
  h.object = cb.m_collisionObject->getUserIndex();
  return h;
}

}  // namespace sim
