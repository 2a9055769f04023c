#include "sim/scene/world.hpp"

#include <BulletCollision/NarrowPhaseCollision/btRaycastCallback.h>
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

int World::add_object(const TriangleMesh& mesh, const Eigen::Isometry3d& world_T_object, const Eigen::Vector3d& albedo) {
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
  o.albedo = albedo.maxCoeff();
  if (o.albedo > 0) o.tint = albedo / o.albedo;  // exactly 1 per channel where grey
  o.triangles = mesh.triangles;
  o.texture = mesh.texture;
  o.corner_uv = mesh.corner_uv;
  o.textured = mesh.textured;
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

struct MovingMeshes::Bullet {
  std::vector<std::unique_ptr<btTriangleMesh>> meshes;
  std::vector<std::unique_ptr<btBvhTriangleMeshShape>> shapes;
};

MovingMeshes::MovingMeshes() : bullet_(std::make_unique<Bullet>()) {}
MovingMeshes::~MovingMeshes() = default;

int MovingMeshes::add(const TriangleMesh& mesh, int link, double albedo) {
  if (mesh.triangles.empty()) throw std::invalid_argument("MovingMeshes::add: mesh has no triangles");
  auto tm = std::make_unique<btTriangleMesh>(true, false);
  const auto bt = [](const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); };
  Eigen::AlignedBox3d box;
  for (const auto& t : mesh.triangles) {
    tm->addTriangle(bt(mesh.vertices[t[0]]), bt(mesh.vertices[t[1]]), bt(mesh.vertices[t[2]]), false);
    for (int k = 0; k < 3; ++k) box.extend(mesh.vertices[t[k]]);
  }
  bullet_->shapes.push_back(std::make_unique<btBvhTriangleMeshShape>(tm.get(), true));
  bullet_->meshes.push_back(std::move(tm));
  meshes_.push_back(mesh);
  links_.push_back(link);
  albedo_.push_back(static_cast<float>(albedo));
  boxes_.push_back(box);
  return static_cast<int>(meshes_.size()) - 1;
}

namespace {
struct ClosestTriangle : btTriangleRaycastCallback {
  ClosestTriangle(const btVector3& from, const btVector3& to) : btTriangleRaycastCallback(from, to) {}
  btScalar reportHit(const btVector3& normal, btScalar fraction, int, int) override {
    if (fraction < best) {
      best = fraction;
      n = normal;
    }
    return fraction;
  }
  btScalar best = 2;
  btVector3 n{0, 0, 1};
};

// the segment meets the box (slabs), a cheap test before the BVH
bool segment_hits_box(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::AlignedBox3d& box) {
  double t0 = 0, t1 = 1;
  const Eigen::Vector3d d = b - a;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-15) {
      if (a[i] < box.min()[i] || a[i] > box.max()[i]) return false;
      continue;
    }
    double u = (box.min()[i] - a[i]) / d[i], v = (box.max()[i] - a[i]) / d[i];
    if (u > v) std::swap(u, v);
    t0 = std::max(t0, u);
    t1 = std::min(t1, v);
    if (t0 > t1) return false;
  }
  return true;
}
}  // namespace

std::optional<RayHit> MovingMeshes::ray_test(const std::vector<Eigen::Isometry3d>& world_T_link,
                                             const Eigen::Vector3d& from_w, const Eigen::Vector3d& to_w) const {
  std::optional<RayHit> best;
  for (std::size_t i = 0; i < meshes_.size(); ++i) {
    const auto l = static_cast<std::size_t>(links_[i]);
    if (l >= world_T_link.size()) continue;
    const Eigen::Isometry3d link_T_world = world_T_link[l].inverse();
    const Eigen::Vector3d a = link_T_world * from_w, b = link_T_world * to_w;
    if (!segment_hits_box(a, b, boxes_[i])) continue;
    const btVector3 from(btScalar(a.x()), btScalar(a.y()), btScalar(a.z())), to(btScalar(b.x()), btScalar(b.y()), btScalar(b.z()));
    ClosestTriangle cb(from, to);
    bullet_->shapes[i]->performRaycast(&cb, from, to);
    if (cb.best > 1) continue;
    if (best && cb.best >= best->fraction) continue;
    RayHit h;
    h.fraction = cb.best;
    h.point_w = from_w + h.fraction * (to_w - from_w);
    h.normal_w = (world_T_link[l].linear() * Eigen::Vector3d(cb.n.x(), cb.n.y(), cb.n.z())).normalized();
    if (h.normal_w.dot(to_w - from_w) > 0) h.normal_w = -h.normal_w;
    h.object = static_cast<int>(i);
    best = h;
  }
  return best;
}

}  // namespace sim
