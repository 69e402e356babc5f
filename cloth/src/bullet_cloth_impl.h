#pragma once
/// The pieces of BulletCloth shared by its source files (private header: only
/// blot_cloth sees cloth/src): the Bullet objects it owns and internal helpers.
#include <blot/cloth/bullet_cloth.h>

#include <BulletCollision/BroadphaseCollision/btBroadphaseInterface.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace blot::cloth {

// Every Bullet object the cloth owns, and the world and body it uses (its
// own, or the caller's in a shared world). The destructor takes out of the
// world what the cloth put in (its body or an adopted one it added, the
// colliders); members are then destroyed in reverse order (body, colliders,
// shapes, world, ...).
struct BulletCloth::Bullet {
  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> configuration;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btBroadphaseInterface> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btSoftRigidDynamicsWorld> ownedWorld;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> colliders;
  std::unique_ptr<btSoftBody> ownedBody;
  btSoftRigidDynamicsWorld* world = nullptr;  // ownedWorld or the caller's
  btSoftBody* body = nullptr;                 // ownedBody or the caller's
  bool shared = false;     // world is the caller's
  bool adopted = false;    // body is the caller's
  bool bodyAdded = false;  // the cloth added body to world
  bool collides = false;

  ~Bullet() {
    if (!world) return;
    if (body && bodyAdded) world->removeSoftBody(body);
    for (auto& collider : colliders) world->removeCollisionObject(collider.get());
  }
};

namespace detail {

inline btVector3 toBullet(const Eigen::Ref<const Eigen::Vector3d>& v) {
  return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
}

inline Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

// bullet_allocator.cpp: installs the recycling allocator for Bullet's raw
// allocations (once per process; see ClothDef::recycleBulletAllocations).
void installRecyclingBulletAllocator();

// bullet_cloth_validation.cpp: throw std::invalid_argument("ClothDef: " + what).
void require(bool ok, const std::string& what);
void validate(const ClothDef& def);

// bullet_tethers.cpp: each vertex's nearest pin and rest geodesic distance to it.
void nearestPins(const Eigen::MatrixX3i& faces, const Eigen::MatrixX3d& rest, const std::vector<ClothPin>& pins,
                 std::vector<int>& pinOf, Eigen::VectorXd& distance);

// bullet_body_build.cpp: the balanced node tree and the collision voxel size.
btDbvtNode* buildNodeTree(btSoftBody& body, std::vector<int>::iterator begin, std::vector<int>::iterator end,
                          btDbvtNode* parent, btScalar margin);
double automaticVoxelSize(const ClothDef& def);

}  // namespace detail
}  // namespace blot::cloth
