// Bullet soft-body cloth behind the SurfaceMotion interface.
//
// Design note: docs/design-notes.md, "cloth/src/bullet_cloth.cpp".
#include <blot/cloth/bullet_cloth.h>

#include "bullet_cloth_impl.h"

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionShapes/btBoxShape.h>
#include <BulletCollision/CollisionShapes/btSphereShape.h>
#include <BulletSoftBody/btSoftBodyInternals.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace blot::cloth {

using detail::automaticVoxelSize;
using detail::buildNodeTree;
using detail::nearestPins;
using detail::require;
using detail::toBullet;
using detail::toEigen;
using detail::validate;

namespace {

btMatrix3x3 toBulletBasis(const Eigen::Matrix3d& m) {
  return btMatrix3x3(static_cast<btScalar>(m(0, 0)), static_cast<btScalar>(m(0, 1)), static_cast<btScalar>(m(0, 2)),
                     static_cast<btScalar>(m(1, 0)), static_cast<btScalar>(m(1, 1)), static_cast<btScalar>(m(1, 2)),
                     static_cast<btScalar>(m(2, 0)), static_cast<btScalar>(m(2, 1)), static_cast<btScalar>(m(2, 2)));
}

btSoftBody::eAeroModel::_ bulletAeroModel(AeroModel model) {
  switch (model) {
    case AeroModel::VertexPoint: return btSoftBody::eAeroModel::V_Point;
    case AeroModel::VertexTwoSided: return btSoftBody::eAeroModel::V_TwoSided;
    case AeroModel::VertexTwoSidedLiftDrag: return btSoftBody::eAeroModel::V_TwoSidedLiftDrag;
    case AeroModel::VertexOneSided: return btSoftBody::eAeroModel::V_OneSided;
    case AeroModel::FaceTwoSided: return btSoftBody::eAeroModel::F_TwoSided;
    case AeroModel::FaceTwoSidedLiftDrag: return btSoftBody::eAeroModel::F_TwoSidedLiftDrag;
    case AeroModel::FaceOneSided: return btSoftBody::eAeroModel::F_OneSided;
  }
  return btSoftBody::eAeroModel::F_TwoSided;
}

// Edge (i, j) is structural when it is axis-aligned in UV space (warp or weft
// thread), shear when diagonal. Without UVs every edge is structural.
bool isShearEdge(const Eigen::MatrixX2d& uv, int i, int j) {
  if (uv.rows() == 0) return false;
  const double du = std::abs(uv(j, 0) - uv(i, 0)), dv = std::abs(uv(j, 1) - uv(i, 1));
  return std::min(du, dv) > 1e-6 * (du + dv);
}

}  // namespace

Eigen::Vector3d PinMotion::position(const Eigen::Vector3d& rest, double t) const {
  const double w = 2 * M_PI * frequency;
  return rest + velocity * t + amplitude * (std::sin(w * t + phase) - std::sin(phase));
}

Eigen::Vector3d PinMotion::velocityAt(double t) const {
  const double w = 2 * M_PI * frequency;
  return velocity + amplitude * (w * std::cos(w * t + phase));
}

ClothCollider ClothCollider::plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) {
  ClothCollider c;
  c.shape = Shape::Plane;
  c.center = point;
  c.normal = normal;
  return c;
}

ClothCollider ClothCollider::box(const Eigen::Vector3d& center, const Eigen::Vector3d& halfExtents,
                                 const Eigen::Matrix3d& orientation) {
  ClothCollider c;
  c.shape = Shape::Box;
  c.center = center;
  c.halfExtents = halfExtents;
  c.orientation = orientation;
  return c;
}

ClothCollider ClothCollider::sphere(const Eigen::Vector3d& center, double radius) {
  ClothCollider c;
  c.shape = Shape::Sphere;
  c.center = center;
  c.radius = radius;
  return c;
}

BulletCloth::BulletCloth(const ClothDef& def) : def_(def), bullet_(std::make_unique<Bullet>()) {
  if (def.recycleBulletAllocations) detail::installRecyclingBulletAllocator();
  validate(def_);
  const Eigen::MatrixX3d& rest = def_.restPositions;
  const int n = static_cast<int>(rest.rows());
  faces_ = def_.faces;

  // Lumped masses from the given node areas.
  lumpedMasses_ = def_.nodeAreas * (def_.totalMass / def_.nodeAreas.sum());
  nodeMasses_ = lumpedMasses_;
  pendingExtraMasses_ = Eigen::VectorXd::Zero(n);
  pendingImpulses_ = Eigen::MatrixX3d::Zero(n, 3);
  double edgeLengthSum = 0;
  for (Eigen::Index e = 0; e < def_.edges.rows(); ++e)
    edgeLengthSum += (rest.row(def_.edges(e, 1)) - rest.row(def_.edges(e, 0))).norm();
  collisionMargin_ =
      def_.collisionMargin > 0 ? def_.collisionMargin : 0.25 * edgeLengthSum / static_cast<double>(def_.edges.rows());

  pinSlot_.assign(static_cast<size_t>(n), -1);
  released_.assign(def_.pins.size(), 0);
  moved_.assign(def_.pins.size(), 0);
  pinTargets_ = Eigen::MatrixX3d::Zero(static_cast<Eigen::Index>(def_.pins.size()), 3);
  moveStarts_ = pinTargets_;
  heldByCaller_.assign(static_cast<size_t>(n), 0);
  for (size_t p = 0; p < def_.pins.size(); ++p) pinSlot_[static_cast<size_t>(def_.pins[p].vertex)] = static_cast<int>(p);
  if (def_.tethers) {
    nearestPins(faces_, rest, def_.pins, tetherPin_, tetherLengths_);
    tetherLengths_ *= 1 + def_.tetherSlack;
  } else {
    tetherPin_.assign(static_cast<size_t>(n), -1);
  }

  // World: a private one, or the caller's. Gravity is set once into a
  // private world, into both places Bullet reads it: the world (rigid bodies)
  // and the soft-body world info (predictMotion). A shared world keeps the
  // caller's settings; its soft-body gravity must be the def's (the stain
  // feels the same gravity as the cloth).
  Bullet& b = *bullet_;
  const btVector3 gravity = toBullet(def_.gravity);
  if (def_.world) {
    b.world = def_.world;
    b.shared = true;
    const Eigen::Vector3d worldGravity = toEigen(b.world->getWorldInfo().m_gravity);
    require((worldGravity - def_.gravity).norm() <= 1e-6 * std::max(1.0, def_.gravity.norm()),
            "gravity (" + std::to_string(def_.gravity.x()) + ", " + std::to_string(def_.gravity.y()) + ", " +
                std::to_string(def_.gravity.z()) + ") differs from the shared world's soft-body gravity (" +
                std::to_string(worldGravity.x()) + ", " + std::to_string(worldGravity.y()) + ", " +
                std::to_string(worldGravity.z()) + "); set world->getWorldInfo().m_gravity or ClothDef.gravity");
  } else {
    b.configuration = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
    b.dispatcher = std::make_unique<btCollisionDispatcher>(b.configuration.get());
    b.broadphase = std::make_unique<btDbvtBroadphase>();
    b.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
    b.ownedWorld = std::make_unique<btSoftRigidDynamicsWorld>(b.dispatcher.get(), b.broadphase.get(), b.solver.get(),
                                                              b.configuration.get());
    b.world = b.ownedWorld.get();
    b.world->setGravity(gravity);
    btSoftBodyWorldInfo& info = b.world->getWorldInfo();
    info.m_gravity = gravity;
    info.air_density = static_cast<btScalar>(def_.wind.airDensity);
    info.m_sparsesdf.setDefaultVoxelsz(
        static_cast<btScalar>(def_.collisionVoxelSize > 0 ? def_.collisionVoxelSize : automaticVoxelSize(def_)));
    info.m_sparsesdf.Reset();
  }
  btSoftBodyWorldInfo& info = b.world->getWorldInfo();

  // Static colliders.
  const Eigen::Vector3d restMin = rest.colwise().minCoeff();
  const Eigen::Vector3d restMax = rest.colwise().maxCoeff();
  restDiagonal_ = (restMax - restMin).norm();
  for (const ClothCollider& col : def_.colliders) {
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    Eigen::Vector3d center = col.center;
    std::unique_ptr<btCollisionShape> shape;
    switch (col.shape) {
      case ClothCollider::Shape::Plane: {
        // A slab whose top face is the plane: its half size dwarfs the cloth
        // (and anything it can reach by sliding), its thickness is 1 m.
        const Eigen::Vector3d normal = col.normal.normalized();
        rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), normal).toRotationMatrix();
        const double half = std::max(100.0, 100 * restDiagonal_);
        const double thickness = 1.0;
        center = col.center - normal * thickness;
        shape = std::make_unique<btBoxShape>(btVector3(static_cast<btScalar>(half), static_cast<btScalar>(half),
                                                       static_cast<btScalar>(thickness)));
        break;
      }
      case ClothCollider::Shape::Box:
        rotation = col.orientation;
        shape = std::make_unique<btBoxShape>(toBullet(col.halfExtents));
        break;
      case ClothCollider::Shape::Sphere:
        shape = std::make_unique<btSphereShape>(static_cast<btScalar>(col.radius));
        break;
    }
    auto object = std::make_unique<btCollisionObject>();
    object->setCollisionShape(shape.get());
    object->setWorldTransform(btTransform(toBulletBasis(rotation), toBullet(center)));
    object->setFriction(static_cast<btScalar>(col.friction));
    object->setCollisionFlags(object->getCollisionFlags() | btCollisionObject::CF_STATIC_OBJECT);
    b.world->addCollisionObject(object.get());
    b.shapes.push_back(std::move(shape));
    b.colliders.push_back(std::move(object));
  }
  b.collides = !def_.colliders.empty();

  if (def_.body) {
    adoptBody();
  } else {
    // The body: nodes, links, faces, in mesh order. The margin must be set before
    // the nodes are appended (it sizes their bounding volumes).
    b.ownedBody = std::make_unique<btSoftBody>(&info, 0, nullptr, nullptr);
    b.body = b.ownedBody.get();
    btSoftBody& body = *b.body;
    body.getCollisionShape()->setMargin(static_cast<btScalar>(collisionMargin_));
    // Nodes as btSoftBody::appendNode makes them, except for the tree of their
    // bounding volumes: appendNode inserts one leaf at a time, and Bullet's
    // unbalanced insertion turns a raster-ordered grid into a near-linear tree
    // (1.0 s at 140K nodes, 0.3 s even in scrambled order). We build the same
    // btDbvt balanced, by median splits, in O(#V log #V).
    body.m_nodes.reserve(n);
    const btSoftBody::Node blank = [] {
      btSoftBody::Node node;
      ZeroInitialize(node);
      return node;
    }();
    for (int i = 0; i < n; ++i) {
      body.m_nodes.push_back(blank);
      btSoftBody::Node& node = body.m_nodes[i];
      node.m_x = toBullet(rest.row(i).transpose());
      node.m_q = node.m_x;
      // Pinned: m_im = 0, infinite mass.
      node.m_im = pinSlot_[static_cast<size_t>(i)] >= 0 ? btScalar(0) : static_cast<btScalar>(1.0 / lumpedMasses_[i]);
      node.m_material = body.m_materials[0];
      node.index = i;
    }
    std::vector<int> order(static_cast<size_t>(n));
    std::iota(order.begin(), order.end(), 0);
    body.m_ndbvt.m_root = buildNodeTree(body, order.begin(), order.end(), nullptr, static_cast<btScalar>(collisionMargin_));
    body.m_ndbvt.m_leaves = n;
    body.updateBounds();

    btSoftBody::Material* structural = body.m_materials[0];
    structural->m_kLST = static_cast<btScalar>(def_.stretchStiffness);
    btSoftBody::Material* shear = body.appendMaterial();
    shear->m_kLST = static_cast<btScalar>(def_.shearStiffness);
    btSoftBody::Material* bending = body.appendMaterial();
    bending->m_kLST = static_cast<btScalar>(def_.bendStiffness);

    const int edgeCount = static_cast<int>(def_.edges.rows());
    const int bendCount = def_.bendStiffness > 0 ? static_cast<int>(def_.bendingPairs.rows()) : 0;
    const int linkCount = edgeCount + bendCount;
    linkVertices_.resize(linkCount, 2);
    linkIsEdge_.assign(static_cast<size_t>(linkCount), false);
    body.m_links.reserve(linkCount);
    for (int e = 0; e < edgeCount; ++e) {
      const int i = def_.edges(e, 0), j = def_.edges(e, 1);
      body.appendLink(i, j, isShearEdge(def_.uvs, i, j) ? shear : structural);
      linkVertices_.row(e) << i, j;
      linkIsEdge_[static_cast<size_t>(e)] = true;
    }
    for (int k = 0; k < bendCount; ++k) {
      const int p = def_.bendingPairs(k, 0), q = def_.bendingPairs(k, 1);
      body.appendLink(p, q, bending);
      body.m_links[body.m_links.size() - 1].m_bbending = -1;  // a signed 1-bit field: -1 is "set"
      linkVertices_.row(edgeCount + k) << p, q;
    }
    body.m_faces.reserve(static_cast<int>(faces_.rows()));
    for (int f = 0; f < faces_.rows(); ++f) body.appendFace(faces_(f, 0), faces_(f, 1), faces_(f, 2));
    require(body.m_faces.size() == faces_.rows(), "mesh has a degenerate face (repeated vertex)");

    btSoftBody::Config& cfg = body.m_cfg;
    cfg.collisions = btSoftBody::fCollision::SDF_RS;  // soft–rigid contacts only, no self-collision
    cfg.piterations = def_.positionIterations;
    cfg.viterations = def_.velocityIterations;
    cfg.diterations = def_.driftIterations;
    cfg.kDF = 1;  // friction is the collider's coefficient itself
    cfg.kKHR = static_cast<btScalar>(def_.contactHardness);
    cfg.kDG = static_cast<btScalar>(def_.wind.dragCoefficient);
    cfg.kLF = static_cast<btScalar>(def_.wind.liftCoefficient);
    cfg.aeromodel = bulletAeroModel(def_.wind.model);
    if (def_.solver == ClothSolver::Velocities) body.setSolver(btSoftBody::eSolverPresets::Velocities);
    body.setWindVelocity(toBullet(def_.wind.velocity));

    // Rest lengths, link constants and areas now, from the rest positions, and
    // the flag lowered: nothing may recompute rest lengths during a step.
    body.updateConstants();
    body.m_bUpdateRtCst = false;
    b.world->addSoftBody(&body);
    b.bodyAdded = true;
  }
  btSoftBody& body = *b.body;

  restLinkLengths_.resize(body.m_links.size());
  for (int l = 0; l < body.m_links.size(); ++l) restLinkLengths_[l] = body.m_links[l].m_rl;

  positions_.resize(n, 3);
  velocities_.resize(n, 3);
  copyOut();
  captureState(rollbackState_);  // rollBack() before any step returns here
  if (b.shared) captureState(sharedNext_);  // sized now: a step captures into it without allocating
}

BulletCloth::~BulletCloth() = default;
BulletCloth::BulletCloth(BulletCloth&&) noexcept = default;
BulletCloth& BulletCloth::operator=(BulletCloth&&) noexcept = default;

bool BulletCloth::isPinned(int vertex) const {
  const int slot = pinSlot_.at(static_cast<size_t>(vertex));
  return slot >= 0 && !released_[static_cast<size_t>(slot)];
}

void BulletCloth::setLiquidLoads(const Eigen::VectorXd& extraNodeMasses, const Eigen::MatrixX3d& nodeImpulses) {
  const int n = vertexCount();
  if (extraNodeMasses.size() != n || nodeImpulses.rows() != n)
    throw std::invalid_argument("BulletCloth::setLiquidLoads: expected " + std::to_string(n) + " rows");
  // The limit keeps every value inside the float range of Bullet's nodes (and
  // of the rollback point, which restoreState checks against that range).
  if (!massesWithinLoadLimit(extraNodeMasses))
    throw std::invalid_argument("BulletCloth::setLiquidLoads: masses must lie in [0, 1e30] kg");
  if (!impulsesWithinLoadLimit(nodeImpulses))
    throw std::invalid_argument("BulletCloth::setLiquidLoads: impulses must be finite, each component within 1e30 N s");
  pendingExtraMasses_ = extraNodeMasses;  // same size: no allocation
  pendingImpulses_ = nodeImpulses;
  loadsPending_ = true;
  // A shared world is stepped by its owner before the next advance(): the
  // loads go into the body now.
  if (bullet_->shared) applyLiquidLoads();
}

void BulletCloth::applyLiquidLoads() {
  btSoftBody& body = *bullet_->body;
  nodeMasses_ = lumpedMasses_ + pendingExtraMasses_;
  for (int i = 0; i < vertexCount(); ++i)
    if (!isPinned(i) && !heldByCaller_[static_cast<size_t>(i)])
      body.m_nodes[i].m_im = static_cast<btScalar>(1.0 / nodeMasses_[i]);
  body.updateLinkConstants();
  for (int i = 0; i < vertexCount(); ++i) {
    btSoftBody::Node& node = body.m_nodes[i];
    body.addVelocity(toBullet(pendingImpulses_.row(i).transpose()) * node.m_im, i);  // no-op when pinned
  }
  loadsPending_ = false;
}

void BulletCloth::adoptBody() {
  Bullet& b = *bullet_;
  btSoftBody& body = *def_.body;
  const int n = static_cast<int>(def_.restPositions.rows());  // positions_ is not sized yet
  require(body.m_nodes.size() == n, "body has " + std::to_string(body.m_nodes.size()) + " nodes; restPositions has " +
                                        std::to_string(n) + " rows (node i must be vertex i)");
  require(body.m_faces.size() == 0 || body.m_faces.size() == faces_.rows(),
          "body has " + std::to_string(body.m_faces.size()) + " faces; faces has " + std::to_string(faces_.rows()) +
              " rows");
  const btSoftBody::Node* first = &body.m_nodes[0];
  for (int f = 0; f < body.m_faces.size(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int node = static_cast<int>(body.m_faces[f].m_n[c] - first);
      require(node == faces_(f, c), "body face " + std::to_string(f) + " corner " + std::to_string(c) + " is node " +
                                        std::to_string(node) + "; faces(" + std::to_string(f) + ", " +
                                        std::to_string(c) + ") is " + std::to_string(faces_(f, c)));
    }
  require(body.getWorldInfo() == &b.world->getWorldInfo(),
          "body was built with another world's btSoftBodyWorldInfo than ClothDef.world's");
  b.body = &body;
  b.adopted = true;
  // The caller's masses are the cloth's own; nodes it holds keep m_im = 0.
  for (int i = 0; i < n; ++i) {
    const btScalar im = body.m_nodes[i].m_im;
    heldByCaller_[static_cast<size_t>(i)] = im == 0 ? 1 : 0;
    lumpedMasses_[i] = im > 0 ? 1.0 / static_cast<double>(im) : 0.0;
  }
  nodeMasses_ = lumpedMasses_;
  for (const ClothPin& pin : def_.pins) body.m_nodes[pin.vertex].m_im = 0;
  body.updateLinkConstants();
  linkVertices_.resize(body.m_links.size(), 2);
  linkIsEdge_.assign(static_cast<size_t>(body.m_links.size()), true);
  for (int l = 0; l < body.m_links.size(); ++l) {
    linkVertices_(l, 0) = static_cast<int>(body.m_links[l].m_n[0] - first);
    linkVertices_(l, 1) = static_cast<int>(body.m_links[l].m_n[1] - first);
    linkIsEdge_[static_cast<size_t>(l)] = !body.m_links[l].m_bbending;
  }
  collisionMargin_ = body.getCollisionShape()->getMargin();
  btSoftBodyArray& bodies = b.world->getSoftBodyArray();
  if (bodies.findLinearSearch(&body) == bodies.size()) {
    b.world->addSoftBody(&body);
    b.bodyAdded = true;
  }
}

bool BulletCloth::sharesWorld() const { return bullet_->shared; }

void BulletCloth::setPinTarget(int vertex, const Eigen::Vector3d& position) {
  if (vertex < 0 || vertex >= vertexCount() || pinSlot_[static_cast<size_t>(vertex)] < 0)
    throw std::invalid_argument("BulletCloth::setPinTarget: vertex " + std::to_string(vertex) + " is not a pin");
  const auto p = static_cast<std::size_t>(pinSlot_[static_cast<size_t>(vertex)]);
  if (released_[p])
    throw std::invalid_argument("BulletCloth::setPinTarget: the pin at vertex " + std::to_string(vertex) +
                                " was released");
  // Bounded as a scene's magnitudes are: a target past float's range (1e39)
  // became infinite in Bullet, and the failed step's rollback, which restores
  // the target with the rest, refused it and left the cloth half restored.
  if (!position.allFinite() || !(position.cwiseAbs().maxCoeff() <= kMaxPinTarget)) {
    std::ostringstream message;
    message << std::setprecision(12) << "BulletCloth::setPinTarget: position (" << position.x() << ", "
            << position.y() << ", " << position.z() << ") must be finite, each coordinate within "
            << std::setprecision(3) << kMaxPinTarget << " m";
    throw std::invalid_argument(message.str());
  }
  moved_[p] = 1;
  pinTargets_.row(static_cast<Eigen::Index>(p)) = position.transpose();
  // A shared world steps before the next advance(): the pin gets the
  // velocity that carries it there during that step.
  if (bullet_->shared && lastStep_ > 0) {
    btSoftBody::Node& node = bullet_->body->m_nodes[vertex];
    node.m_v = toBullet((position - toEigen(node.m_x)) / lastStep_);
  }
  // A shared world's rollback point was taken before this call (the end of
  // the last advance): the new target goes into it too, so a failed step
  // does not take it back.
  if (bullet_->shared) {
    BulletClothState& next = sharedNextValid_ ? sharedNext_ : rollbackState_;
    next.movedPins[p] = 1;
    next.pinTargets.row(static_cast<Eigen::Index>(p)) = position.transpose();
    if (lastStep_ > 0) next.velocities.row(vertex) = (position.transpose() - next.positions.row(vertex)) / lastStep_;
  }
}

Eigen::Vector3d BulletCloth::pinTarget(std::size_t p, double t) const {
  if (moved_[p]) return pinTargets_.row(static_cast<Eigen::Index>(p)).transpose();
  const ClothPin& pin = def_.pins[p];
  return pin.motion.position(def_.restPositions.row(pin.vertex).transpose(), t);
}

// fraction: how far through this advance() the substep ends, for the straight
// path of a pin moved by setPinTarget.
void BulletCloth::movePins(double targetTime, double substep, double fraction) {
  btSoftBody& body = *bullet_->body;
  bool released = false;
  for (size_t p = 0; p < def_.pins.size(); ++p) {
    if (released_[p]) continue;
    const ClothPin& pin = def_.pins[p];
    btSoftBody::Node& node = body.m_nodes[pin.vertex];
    if (moved_[p]) {
      const Eigen::Vector3d start = moveStarts_.row(static_cast<Eigen::Index>(p)).transpose();
      const Eigen::Vector3d target =
          start + fraction * (pinTargets_.row(static_cast<Eigen::Index>(p)).transpose() - start);
      node.m_v = toBullet((target - toEigen(node.m_x)) / substep);
      continue;
    }
    if (targetTime > pin.motion.releaseTime) {
      // Free from this substep on, with the pin's velocity at release.
      released_[p] = 1;
      released = true;
      node.m_im = static_cast<btScalar>(1.0 / nodeMasses_[pin.vertex]);
      node.m_v = toBullet(pin.motion.velocityAt(pin.motion.releaseTime));
      continue;
    }
    const Eigen::Vector3d target = pin.motion.position(def_.restPositions.row(pin.vertex).transpose(), targetTime);
    node.m_v = toBullet((target - toEigen(node.m_x)) / substep);
  }
  if (released) body.updateLinkConstants();
}

void BulletCloth::advance(double h) {
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("BulletCloth::advance: time step must be positive");
  Bullet& b = *bullet_;
  if (b.shared) {
    advanceSharedWorld(h);
    return;
  }
  if (loadsPending_) applyLiquidLoads();
  const double substep = h / def_.substeps;
  b.body->m_cfg.kDP = static_cast<btScalar>(1 - std::exp(-def_.dampingRate * substep));
  for (size_t p = 0; p < def_.pins.size(); ++p)
    if (moved_[p]) moveStarts_.row(static_cast<Eigen::Index>(p)) = toEigen(b.body->m_nodes[def_.pins[p].vertex].m_x).transpose();
  for (int s = 0; s < def_.substeps; ++s) {
    movePins(time_ + (s + 1) * substep, substep, static_cast<double>(s + 1) / def_.substeps);
    // maxSubSteps = 0: exactly one Bullet step of this length, no accumulator.
    b.world->stepSimulation(static_cast<btScalar>(substep), 0, static_cast<btScalar>(substep));
    if (def_.tethers) enforceTethers(substep);
  }
  time_ += h;
  lastStep_ = h;
  // Drop distance-cache cells no node has touched for a while (Bullet's demos
  // do this once per frame; otherwise the cache only grows).
  if (b.collides) b.world->getWorldInfo().m_sparsesdf.GarbageCollect();
  copyOut();
}

// The caller has stepped its world by h. Held pins are put exactly where they
// belong at the new time (Bullet damps even an infinite-mass node's velocity a
// little each substep), released pins let go, tethers pulled taut; then the
// held pins get the velocity of their path over the next h, which the
// caller's next world step follows.
void BulletCloth::advanceSharedWorld(double h) {
  Bullet& b = *bullet_;
  btSoftBody& body = *b.body;
  time_ += h;
  lastStep_ = h;
  bool released = false;
  for (size_t p = 0; p < def_.pins.size(); ++p) {
    if (released_[p]) continue;
    const ClothPin& pin = def_.pins[p];
    btSoftBody::Node& node = body.m_nodes[pin.vertex];
    if (!moved_[p] && time_ > pin.motion.releaseTime) {
      released_[p] = 1;
      released = true;
      node.m_im = static_cast<btScalar>(1.0 / nodeMasses_[pin.vertex]);
      node.m_v = toBullet(pin.motion.velocityAt(pin.motion.releaseTime));
      continue;
    }
    node.m_x = toBullet(pinTarget(p, time_));
  }
  if (released) body.updateLinkConstants();
  if (def_.tethers) enforceTethers(h);
  copyOut();
  for (size_t p = 0; p < def_.pins.size(); ++p) {
    if (released_[p]) continue;
    btSoftBody::Node& node = body.m_nodes[def_.pins[p].vertex];
    node.m_v = toBullet((pinTarget(p, time_ + h) - toEigen(node.m_x)) / h);
  }
  if (!b.adopted) body.m_cfg.kDP = static_cast<btScalar>(1 - std::exp(-def_.dampingRate * h / def_.substeps));
  captureState(sharedNext_);  // the next step's rollback point, if this one succeeds
  sharedNextValid_ = true;
}

void BulletCloth::copyOut() {
  const btSoftBody& body = *bullet_->body;
  boundingBox_.setEmpty();
  for (int i = 0; i < vertexCount(); ++i) {
    const btSoftBody::Node& node = body.m_nodes[i];
    positions_.row(i) << node.m_x.x(), node.m_x.y(), node.m_x.z();
    velocities_.row(i) << node.m_v.x(), node.m_v.y(), node.m_v.z();
    boundingBox_.extend(positions_.row(i).transpose());
  }
  // Bullet's velocity of an infinite-mass node is damped like the others;
  // report the trajectory's exact one. A pin moved by setPinTarget reports
  // Bullet's (the velocity it last moved with).
  for (size_t p = 0; p < def_.pins.size(); ++p)
    if (!released_[p] && !moved_[p])
      velocities_.row(def_.pins[p].vertex) = def_.pins[p].motion.velocityAt(time_).transpose();
}

void BulletCloth::saveDynamicState(MotionStateVisitor& visitor) const {
  BulletClothState state;
  captureState(state);
  state.visit(visitor);
}

void BulletCloth::loadDynamicState(MotionStateVisitor& visitor) {
  BulletClothState state;
  state.visit(visitor);
  restoreState(state);
}

BulletClothState BulletCloth::captureState() const {
  BulletClothState state;
  captureState(state);
  return state;
}

void BulletCloth::keepRollbackPoint() {
  // A shared world has been stepped by its owner before this call, so the
  // nodes now are already the step's: the point to come back to is what the
  // last advance() left (sharedNext_), or, after a rollback, the same point
  // again. (Capturing the nodes here made a failed step "restore" the
  // exploded cloth, and every later step fail.)
  if (bullet_->shared) {
    if (sharedNextValid_) std::swap(rollbackState_, sharedNext_);
    sharedNextValid_ = false;
    return;
  }
  captureState(rollbackState_);
}

void BulletCloth::rollBack() {
  restoreState(rollbackState_);
  sharedNextValid_ = false;
}

void BulletCloth::captureState(BulletClothState& state) const {
  const btSoftBody& body = *bullet_->body;
  const int n = vertexCount();
  state.time = time_;
  state.positions.resize(n, 3);
  state.previousPositions.resize(n, 3);
  state.velocities.resize(n, 3);
  state.previousVelocities.resize(n, 3);
  state.forces.resize(n, 3);
  state.nodeNormals.resize(n, 3);
  state.nodeAreas.resize(n);
  state.inverseMasses.resize(n);
  for (int i = 0; i < n; ++i) {
    const btSoftBody::Node& node = body.m_nodes[i];
    state.positions.row(i) = toEigen(node.m_x).transpose();
    state.previousPositions.row(i) = toEigen(node.m_q).transpose();
    state.velocities.row(i) = toEigen(node.m_v).transpose();
    state.previousVelocities.row(i) = toEigen(node.m_vn).transpose();
    state.forces.row(i) = toEigen(node.m_f).transpose();
    state.nodeNormals.row(i) = toEigen(node.m_n).transpose();
    state.nodeAreas[i] = node.m_area;
    state.inverseMasses[i] = node.m_im;
  }
  state.faceNormals.resize(body.m_faces.size(), 3);
  for (int f = 0; f < body.m_faces.size(); ++f) state.faceNormals.row(f) = toEigen(body.m_faces[f].m_normal).transpose();
  state.nodeMasses = nodeMasses_;
  state.pendingExtraMasses = pendingExtraMasses_;
  state.pendingImpulses = pendingImpulses_;
  state.loadsPending = loadsPending_;
  state.releasedPins = released_;
  state.movedPins = moved_;
  state.pinTargets = pinTargets_;
}

void BulletCloth::restoreState(const BulletClothState& state) {
  const Eigen::Index n = vertexCount(), f = faces_.rows();
  auto rows = [](const char* field, Eigen::Index got, Eigen::Index expected) {
    if (got != expected)
      throw std::invalid_argument(std::string("BulletCloth::restoreState: ") + field + " has " + std::to_string(got) +
                                  " rows; expected " + std::to_string(expected));
  };
  rows("positions", state.positions.rows(), n);
  rows("previousPositions", state.previousPositions.rows(), n);
  rows("velocities", state.velocities.rows(), n);
  rows("previousVelocities", state.previousVelocities.rows(), n);
  rows("forces", state.forces.rows(), n);
  rows("nodeNormals", state.nodeNormals.rows(), n);
  rows("nodeAreas", state.nodeAreas.size(), n);
  rows("faceNormals", state.faceNormals.rows(), f);
  rows("inverseMasses", state.inverseMasses.size(), n);
  rows("nodeMasses", state.nodeMasses.size(), n);
  rows("pendingExtraMasses", state.pendingExtraMasses.size(), n);
  rows("pendingImpulses", state.pendingImpulses.rows(), n);
  rows("releasedPins", static_cast<Eigen::Index>(state.releasedPins.size()), static_cast<Eigen::Index>(def_.pins.size()));
  rows("movedPins", static_cast<Eigen::Index>(state.movedPins.size()), static_cast<Eigen::Index>(def_.pins.size()));
  rows("pinTargets", state.pinTargets.rows(), static_cast<Eigen::Index>(def_.pins.size()));
  if (!state.pinTargets.allFinite()) throw std::invalid_argument("BulletClothState: pinTargets must be finite");
  if (!std::isfinite(state.time) || !state.positions.allFinite() || !state.velocities.allFinite())
    throw std::invalid_argument("BulletCloth::restoreState: time, positions and velocities must be finite");
  // Every value below goes into a btScalar (float in Debian's Bullet): one
  // beyond its range would become infinite there and be saved as such, so a
  // state that loads could not be loaded again (fuzz_state found it).
  const double limit = static_cast<double>(std::numeric_limits<btScalar>::max());
  auto representable = [limit](const char* field, const auto& values) {
    const auto* v = values.data();
    for (Eigen::Index k = 0; k < values.size(); ++k)
      if (!(std::abs(v[k]) <= limit)) {
        std::ostringstream message;
        message << std::setprecision(17) << "BulletCloth::restoreState: " << field << " entry " << k << " is " << v[k]
                << std::setprecision(3) << "; Bullet's values must lie in [-" << limit << ", " << limit << "]";
        throw std::invalid_argument(message.str());
      }
  };
  representable("positions", state.positions);
  representable("previousPositions", state.previousPositions);
  representable("velocities", state.velocities);
  representable("previousVelocities", state.previousVelocities);
  representable("forces", state.forces);
  representable("nodeNormals", state.nodeNormals);
  representable("nodeAreas", state.nodeAreas);
  representable("faceNormals", state.faceNormals);
  representable("inverseMasses", state.inverseMasses);
  representable("nodeMasses", state.nodeMasses);
  representable("pendingExtraMasses", state.pendingExtraMasses);
  representable("pendingImpulses", state.pendingImpulses);
  representable("pinTargets", state.pinTargets);

  Bullet& b = *bullet_;
  btSoftBody& body = *b.body;
  for (int i = 0; i < n; ++i) {
    btSoftBody::Node& node = body.m_nodes[i];
    node.m_x = toBullet(state.positions.row(i).transpose());
    node.m_q = toBullet(state.previousPositions.row(i).transpose());
    node.m_v = toBullet(state.velocities.row(i).transpose());
    node.m_vn = toBullet(state.previousVelocities.row(i).transpose());
    node.m_f = toBullet(state.forces.row(i).transpose());
    node.m_n = toBullet(state.nodeNormals.row(i).transpose());
    node.m_area = static_cast<btScalar>(state.nodeAreas[i]);
    node.m_im = static_cast<btScalar>(state.inverseMasses[i]);
  }
  for (int k = 0; k < f; ++k) body.m_faces[k].m_normal = toBullet(state.faceNormals.row(k).transpose());
  body.updateLinkConstants();
  // The node tree's volumes belong to the positions they were last updated
  // at: rebuild it (balanced, as at construction) around the restored ones.
  body.m_ndbvt.clear();
  std::vector<int> order(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  body.m_ndbvt.m_root = buildNodeTree(body, order.begin(), order.end(), nullptr, static_cast<btScalar>(collisionMargin_));
  body.m_ndbvt.m_leaves = static_cast<int>(n);
  body.updateBounds();
  if (body.getActivationState() == DISABLE_SIMULATION) body.forceActivationState(ACTIVE_TAG);

  time_ = state.time;
  nodeMasses_ = state.nodeMasses;
  pendingExtraMasses_ = state.pendingExtraMasses;
  pendingImpulses_ = state.pendingImpulses;
  loadsPending_ = state.loadsPending;
  released_ = state.releasedPins;
  moved_ = state.movedPins;
  pinTargets_ = state.pinTargets;
  copyOut();
}

Eigen::VectorXd BulletCloth::currentLinkRestLengths() const {
  const btSoftBody& body = *bullet_->body;
  Eigen::VectorXd lengths(body.m_links.size());
  for (int l = 0; l < body.m_links.size(); ++l) lengths[l] = body.m_links[l].m_rl;
  return lengths;
}

double BulletCloth::maxEdgeStrain() const {
  double strain = 0;
  for (int l = 0; l < linkVertices_.rows(); ++l) {
    if (!linkIsEdge_[static_cast<size_t>(l)]) continue;
    const double length = (positions_.row(linkVertices_(l, 0)) - positions_.row(linkVertices_(l, 1))).norm();
    strain = std::max(strain, std::abs(length / restLinkLengths_[l] - 1));
  }
  return strain;
}

double BulletCloth::kineticEnergy() const {
  double energy = 0;
  for (int i = 0; i < vertexCount(); ++i) energy += 0.5 * nodeMasses_[i] * velocities_.row(i).squaredNorm();
  return energy;
}

double BulletCloth::gravitationalEnergy() const {
  double energy = 0;
  for (int i = 0; i < vertexCount(); ++i) energy -= nodeMasses_[i] * positions_.row(i).dot(def_.gravity.transpose());
  return energy;
}

bool BulletCloth::isHealthy() const {
  if (!positions_.allFinite() || !velocities_.allFinite()) return false;
  if (boundingBox_.diagonal().norm() > 10 * restDiagonal_) return false;
  if (maxEdgeStrain() > 9) return false;
  return bullet_->body->getActivationState() != DISABLE_SIMULATION;
}

}  // namespace blot::cloth
