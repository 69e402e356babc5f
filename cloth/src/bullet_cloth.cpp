// Bullet soft-body cloth behind the SurfaceMotion interface.
//
// Design note: docs/design-notes.md, "cloth/src/bullet_cloth.cpp".
#include <blot/cloth/bullet_cloth.h>

#include "bullet_cloth_testing.h"

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletCollision/CollisionShapes/btBoxShape.h>
#include <BulletCollision/CollisionShapes/btSphereShape.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyInternals.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <LinearMath/btAlignedAllocator.h>
#include <malloc.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <mutex>
#include <new>
#include <numeric>
#include <queue>
#include <stdexcept>
#include <string>
#include <utility>

namespace blot::cloth {

// Every Bullet object the cloth owns. Members are destroyed in reverse order
// (body, colliders, shapes, world, ...) after the destructor has taken the body
// and the colliders out of the world.
struct BulletCloth::Bullet {
  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> configuration;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btBroadphaseInterface> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btSoftRigidDynamicsWorld> world;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> colliders;
  std::unique_ptr<btSoftBody> body;
  bool collides = false;

  ~Bullet() {
    if (!world) return;
    if (body) world->removeSoftBody(body.get());
    for (auto& collider : colliders) world->removeCollisionObject(collider.get());
  }
};

namespace {

// Bullet 3.24's btSoftBody::solveConstraints calls applyClusters twice per
// substep, and each call allocates and frees two node-sized scratch arrays
// even when the body has no clusters (4 mallocs per substep, measured). A
// game-loop step must not allocate, so Bullet's raw allocations go through a
// small recycling cache: a freed block is kept (up to kSlots of them) and
// handed out again for a request it fits without wasting more than half of
// it. Every block still comes from malloc and goes back to free, so blocks
// Bullet allocated before the cache was installed are handled too
// (malloc_usable_size tells their size). Installed once per process, on the
// first BulletCloth; process-wide, since Bullet's allocator is.
// Rejected: patching Bullet or giving the body cluster scratch of its own
// (applyClusters is not virtual).
class RecyclingBulletAllocator {
 public:
  static void install() {
    static std::once_flag once;
    std::call_once(once, [] { btAlignedAllocSetCustom(&allocate, &release); });
  }

 private:
  static constexpr int kSlots = 16;
  struct Slot {
    void* block = nullptr;
    size_t size = 0;
  };
  static std::mutex& lock() {
    static std::mutex m;
    return m;
  }
  static std::array<Slot, kSlots>& slots() {
    static std::array<Slot, kSlots> s;
    return s;
  }
  static void* allocate(size_t size) {
    {
      std::lock_guard<std::mutex> guard(lock());
      for (Slot& slot : slots()) {
        if (slot.block != nullptr && slot.size >= size && slot.size <= 2 * size) {
          void* block = slot.block;
          slot.block = nullptr;
          return block;
        }
      }
    }
    return std::malloc(size);
  }
  static void release(void* block) {
    if (block == nullptr) return;
    {
      std::lock_guard<std::mutex> guard(lock());
      for (Slot& slot : slots()) {
        if (slot.block == nullptr) {
          slot.block = block;
          slot.size = malloc_usable_size(block);
          return;
        }
      }
    }
    std::free(block);
  }
};

btVector3 toBullet(const Eigen::Ref<const Eigen::Vector3d>& v) {
  return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
}

Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

btMatrix3x3 toBulletBasis(const Eigen::Matrix3d& m) {
  return btMatrix3x3(static_cast<btScalar>(m(0, 0)), static_cast<btScalar>(m(0, 1)), static_cast<btScalar>(m(0, 2)),
                     static_cast<btScalar>(m(1, 0)), static_cast<btScalar>(m(1, 1)), static_cast<btScalar>(m(1, 2)),
                     static_cast<btScalar>(m(2, 0)), static_cast<btScalar>(m(2, 1)), static_cast<btScalar>(m(2, 2)));
}

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("ClothDef: " + what);
}

// The same for checks inside per-row loops: the message is built only on
// failure (building it for every row was a quarter of a 140K cloth's load).
template <class Message>
void requireEach(bool ok, const Message& message) {
  if (!ok) require(false, message());
}

bool inUnitInterval(double x) { return x >= 0 && x <= 1; }

std::string at(const char* field, Eigen::Index row) { return std::string(field) + "[" + std::to_string(row) + "]"; }

// The mesh arrays: shapes, finiteness, index ranges, each error naming the
// field and row. Manifoldness is the describer's job (coupling::describeClothMesh
// builds them through stain::SurfaceTopology, which rejects non-manifold meshes).
void validateMesh(const ClothDef& def) {
  const Eigen::Index n = def.restPositions.rows();
  require(n > 0, "restPositions is empty (#V by 3 expected)");
  require(def.faces.rows() > 0, "faces is empty (#F by 3 expected)");
  for (Eigen::Index i = 0; i < n; ++i)
    requireEach(def.restPositions.row(i).allFinite(), [&] { return at("restPositions", i) + " is not finite"; });
  for (Eigen::Index f = 0; f < def.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k)
      requireEach(def.faces(f, k) >= 0 && def.faces(f, k) < n, [&] {
        return at("faces", f) + " has vertex " + std::to_string(def.faces(f, k)) + " outside [0, " + std::to_string(n) + ")";
      });
    requireEach(def.faces(f, 0) != def.faces(f, 1) && def.faces(f, 1) != def.faces(f, 2) && def.faces(f, 2) != def.faces(f, 0),
                [&] { return at("faces", f) + " repeats a vertex (degenerate face)"; });
  }
  require(def.uvs.rows() == 0 || def.uvs.rows() == n,
          "uvs has " + std::to_string(def.uvs.rows()) + " rows; expected " + std::to_string(n) + " (one per vertex) or 0");
  for (Eigen::Index i = 0; i < def.uvs.rows(); ++i)
    requireEach(def.uvs.row(i).allFinite(), [&] { return at("uvs", i) + " is not finite"; });
  require(def.edges.rows() > 0, "edges is empty (#E by 2 expected)");
  auto checkPairs = [n](const Eigen::MatrixX2i& pairs, const char* field) {
    for (Eigen::Index e = 0; e < pairs.rows(); ++e) {
      requireEach(pairs(e, 0) >= 0 && pairs(e, 0) < n && pairs(e, 1) >= 0 && pairs(e, 1) < n, [&] {
        return at(field, e) + " = (" + std::to_string(pairs(e, 0)) + ", " + std::to_string(pairs(e, 1)) +
               ") has a vertex outside [0, " + std::to_string(n) + ")";
      });
      requireEach(pairs(e, 0) != pairs(e, 1),
                  [&] { return at(field, e) + " joins vertex " + std::to_string(pairs(e, 0)) + " to itself"; });
    }
  };
  checkPairs(def.edges, "edges");
  checkPairs(def.bendingPairs, "bendingPairs");
  require(def.nodeAreas.size() == n,
          "nodeAreas has " + std::to_string(def.nodeAreas.size()) + " entries; expected " + std::to_string(n));
  for (Eigen::Index i = 0; i < n; ++i)
    requireEach(std::isfinite(def.nodeAreas[i]) && def.nodeAreas[i] >= 0, [&] {
      return at("nodeAreas", i) + " = " + std::to_string(def.nodeAreas[i]) + " (expected finite and >= 0, m²)";
    });
  require(def.nodeAreas.sum() > 0, "nodeAreas sum to zero (the mesh has no area)");
}

void validate(const ClothDef& def) {
  validateMesh(def);
  require(std::isfinite(def.totalMass) && def.totalMass > 0, "totalMass must be positive (kg)");
  require(def.stretchStiffness > 0 && def.stretchStiffness <= 1, "stretchStiffness must be in (0, 1]");
  require(def.shearStiffness > 0 && def.shearStiffness <= 1, "shearStiffness must be in (0, 1]");
  require(inUnitInterval(def.bendStiffness), "bendStiffness must be in [0, 1]");
  require(std::isfinite(def.dampingRate) && def.dampingRate >= 0, "dampingRate must be >= 0 (1/s)");
  require(def.positionIterations >= 1, "positionIterations must be >= 1");
  require(def.velocityIterations >= 0, "velocityIterations must be >= 0");
  require(def.driftIterations >= 0, "driftIterations must be >= 0");
  require(def.substeps >= 1, "substeps must be >= 1");
  require(std::isfinite(def.tetherSlack) && def.tetherSlack >= 0, "tetherSlack must be >= 0");
  require(def.gravity.allFinite(), "gravity must be finite");
  require(def.wind.velocity.allFinite(), "wind.velocity must be finite");
  require(std::isfinite(def.wind.dragCoefficient) && def.wind.dragCoefficient >= 0, "wind.dragCoefficient must be >= 0");
  require(std::isfinite(def.wind.liftCoefficient) && def.wind.liftCoefficient >= 0, "wind.liftCoefficient must be >= 0");
  require(std::isfinite(def.wind.airDensity) && def.wind.airDensity >= 0, "wind.airDensity must be >= 0 (kg/m³)");
  require(def.contactHardness > 0 && def.contactHardness <= 1, "contactHardness must be in (0, 1]");
  require(std::isfinite(def.collisionMargin) && def.collisionMargin >= 0, "collisionMargin must be >= 0 (m)");
  require(std::isfinite(def.collisionVoxelSize) && def.collisionVoxelSize >= 0, "collisionVoxelSize must be >= 0 (m)");
  const auto vertexCount = def.restPositions.rows();
  std::vector<char> seen(static_cast<size_t>(vertexCount), 0);
  for (size_t p = 0; p < def.pins.size(); ++p) {
    const ClothPin& pin = def.pins[p];
    const std::string name = "pins[" + std::to_string(p) + "]";
    require(pin.vertex >= 0 && pin.vertex < vertexCount, name + ".vertex out of range");
    require(!seen[static_cast<size_t>(pin.vertex)], name + ".vertex pinned twice");
    seen[static_cast<size_t>(pin.vertex)] = 1;
    const PinMotion& m = pin.motion;
    require(m.velocity.allFinite() && m.amplitude.allFinite() && std::isfinite(m.frequency) &&
                std::isfinite(m.phase) && !std::isnan(m.releaseTime),
            name + ".motion must be finite (releaseTime may be +inf)");
  }
  for (size_t c = 0; c < def.colliders.size(); ++c) {
    const ClothCollider& col = def.colliders[c];
    const std::string name = "colliders[" + std::to_string(c) + "]";
    require(col.center.allFinite(), name + ".center must be finite");
    require(inUnitInterval(col.friction), name + ".friction must be in [0, 1]");
    switch (col.shape) {
      case ClothCollider::Shape::Plane:
        require(col.normal.allFinite() && col.normal.norm() > 0, name + ".normal must be a nonzero vector");
        break;
      case ClothCollider::Shape::Box:
        require(col.halfExtents.allFinite() && col.halfExtents.minCoeff() > 0, name + ".halfExtents must be positive");
        require(col.orientation.allFinite() &&
                    (col.orientation.transpose() * col.orientation - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
                    col.orientation.determinant() > 0,
                name + ".orientation must be a rotation");
        break;
      case ClothCollider::Shape::Sphere:
        require(std::isfinite(col.radius) && col.radius > 0, name + ".radius must be positive");
        break;
    }
  }
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

// Tethers (long-range attachments): every vertex the pins can reach is tied to
// its nearest pin, at its rest geodesic distance computed by fast marching
// (Kimmel–Sethian: Dijkstra's order, but a vertex whose triangle has both
// other corners done gets the planar wavefront's arrival time, falling back
// to edge paths where the wave does not cross the triangle). Rejected: plain
// Dijkstra over edges, which overestimates distances on a grid by up to 8%,
// and the tether hands that out as stretch. O(#V log #V).
double wavefrontArrival(const Eigen::Vector3d& ea, const Eigen::Vector3d& eb, double ta, double tb) {
  // Solve |∇T| = 1 for the linear T on the triangle (v, v + ea, v + eb) with
  // T(v + ea) = ta, T(v + eb) = tb: with E = [ea eb], Q = (EᵀE)⁻¹, λ = Q(t − T1),
  // λᵀ(EᵀE)λ = 1, i.e. (1ᵀQ1)T² − 2(1ᵀQt)T + tᵀQt − 1 = 0, larger root.
  Eigen::Matrix2d gram;
  gram << ea.dot(ea), ea.dot(eb), ea.dot(eb), eb.dot(eb);
  const double det = gram.determinant();
  if (!(det > 1e-12 * gram(0, 0) * gram(1, 1))) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix2d q = gram.inverse();
  const Eigen::Vector2d t(ta, tb), one(1, 1);
  const double qa = one.dot(q * one), qb = one.dot(q * t), qc = t.dot(q * t) - 1;
  const double disc = qb * qb - qa * qc;
  if (disc < 0) return std::numeric_limits<double>::infinity();
  const double arrival = (qb + std::sqrt(disc)) / qa;
  // Causal only if the wave arrives from inside the triangle: −∇T in the cone
  // of ea, eb, i.e. λ ≤ 0 componentwise.
  const Eigen::Vector2d lambda = q * (t - arrival * one);
  if (arrival < std::max(ta, tb) || lambda.maxCoeff() > 1e-12 * arrival) return std::numeric_limits<double>::infinity();
  return arrival;
}

// Vertex-to-face incidence in CSR form (faces of vertex i are
// faceOf[offsets[i] .. offsets[i+1]), in face order).
void vertexFaces(const Eigen::MatrixX3i& faces, int n, std::vector<int>& offsets, std::vector<int>& faceOf) {
  offsets.assign(static_cast<size_t>(n) + 1, 0);
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++offsets[static_cast<size_t>(faces(f, k)) + 1];
  for (int i = 0; i < n; ++i) offsets[static_cast<size_t>(i) + 1] += offsets[static_cast<size_t>(i)];
  faceOf.assign(static_cast<size_t>(offsets.back()), -1);
  std::vector<int> fill(offsets.begin(), offsets.end() - 1);
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) faceOf[static_cast<size_t>(fill[static_cast<size_t>(faces(f, k))]++)] = static_cast<int>(f);
}

void nearestPins(const Eigen::MatrixX3i& faces, const Eigen::MatrixX3d& rest, const std::vector<ClothPin>& pins,
                 std::vector<int>& pinOf, Eigen::VectorXd& distance) {
  const int n = static_cast<int>(rest.rows());
  std::vector<int> offsets, faceOf;
  vertexFaces(faces, n, offsets, faceOf);
  pinOf.assign(static_cast<size_t>(n), -1);
  distance = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
  std::vector<char> done(static_cast<size_t>(n), 0);
  using Entry = std::pair<double, int>;  // ties resolved by vertex index: deterministic
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
  auto relax = [&](int v, double d, int pin) {
    if (d < distance[v]) {
      distance[v] = d;
      pinOf[static_cast<size_t>(v)] = pin;
      heap.emplace(d, v);
    }
  };
  for (size_t p = 0; p < pins.size(); ++p) relax(pins[p].vertex, 0.0, static_cast<int>(p));
  while (!heap.empty()) {
    const auto [d, u] = heap.top();
    heap.pop();
    if (done[static_cast<size_t>(u)] || d > distance[u]) continue;
    done[static_cast<size_t>(u)] = 1;
    const int pin = pinOf[static_cast<size_t>(u)];
    for (int k = offsets[static_cast<size_t>(u)]; k < offsets[static_cast<size_t>(u) + 1]; ++k) {
      const int f = faceOf[static_cast<size_t>(k)];
      // The face's other two corners: each is reached along its edge from u,
      // and, when the other one is done with the same pin, by the wavefront.
      const int c = faces(f, 0) == u ? 0 : faces(f, 1) == u ? 1 : 2;
      for (int side = 1; side <= 2; ++side) {
        const int target = faces(f, (c + side) % 3), other = faces(f, (c + 3 - side) % 3);
        if (done[static_cast<size_t>(target)]) continue;
        relax(target, d + (rest.row(target) - rest.row(u)).norm(), pin);
        if (!done[static_cast<size_t>(other)] || pinOf[static_cast<size_t>(other)] != pin) continue;
        const Eigen::Vector3d origin = rest.row(target);
        relax(target, wavefrontArrival(rest.row(u).transpose() - origin, rest.row(other).transpose() - origin, d, distance[other]), pin);
      }
    }
  }
}

// Balanced btDbvt over the nodes in [begin, end): split at the median along
// the longest axis of their positions (ties by index, so the tree is the same
// everywhere). Tree nodes are allocated the way btDbvt frees them.
btDbvtNode* buildNodeTree(btSoftBody& body, std::vector<int>::iterator begin, std::vector<int>::iterator end,
                          btDbvtNode* parent, btScalar margin) {
  btDbvtNode* tree = new (btAlignedAlloc(sizeof(btDbvtNode), 16)) btDbvtNode();
  tree->parent = parent;
  if (end - begin == 1) {
    btSoftBody::Node& node = body.m_nodes[*begin];
    tree->volume = btDbvtVolume::FromCR(node.m_x, margin);
    tree->data = &node;
    tree->childs[1] = nullptr;  // marks a leaf
    node.m_leaf = tree;
    return tree;
  }
  btVector3 low = body.m_nodes[*begin].m_x, high = low;
  for (auto it = begin; it != end; ++it) {
    low.setMin(body.m_nodes[*it].m_x);
    high.setMax(body.m_nodes[*it].m_x);
  }
  const int axis = (high - low).maxAxis();
  const auto middle = begin + (end - begin) / 2;
  std::nth_element(begin, middle, end, [&](int a, int b) {
    const btScalar xa = body.m_nodes[a].m_x[axis], xb = body.m_nodes[b].m_x[axis];
    return xa < xb || (xa == xb && a < b);
  });
  tree->childs[0] = buildNodeTree(body, begin, middle, tree, margin);
  tree->childs[1] = buildNodeTree(body, middle, end, tree, margin);
  Merge(tree->childs[0]->volume, tree->childs[1]->volume, tree->volume);
  return tree;
}

double automaticVoxelSize(const ClothDef& def) {
  double size = 0.25;  // Bullet's default
  for (const ClothCollider& col : def.colliders) {
    if (col.shape == ClothCollider::Shape::Sphere) size = std::min(size, col.radius / 4);
    if (col.shape == ClothCollider::Shape::Box) size = std::min(size, col.halfExtents.minCoeff() / 4);
  }
  return size;
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
  if (def.recycleBulletAllocations) RecyclingBulletAllocator::install();
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
  for (size_t p = 0; p < def_.pins.size(); ++p) pinSlot_[static_cast<size_t>(def_.pins[p].vertex)] = static_cast<int>(p);
  if (def_.tethers) {
    nearestPins(faces_, rest, def_.pins, tetherPin_, tetherLengths_);
    tetherLengths_ *= 1 + def_.tetherSlack;
  } else {
    tetherPin_.assign(static_cast<size_t>(n), -1);
  }

  // World. Gravity is set once, into both places Bullet reads it: the world
  // (rigid bodies) and the soft-body world info (predictMotion).
  Bullet& b = *bullet_;
  b.configuration = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
  b.dispatcher = std::make_unique<btCollisionDispatcher>(b.configuration.get());
  b.broadphase = std::make_unique<btDbvtBroadphase>();
  b.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  b.world = std::make_unique<btSoftRigidDynamicsWorld>(b.dispatcher.get(), b.broadphase.get(), b.solver.get(),
                                                       b.configuration.get());
  const btVector3 gravity = toBullet(def_.gravity);
  b.world->setGravity(gravity);
  btSoftBodyWorldInfo& info = b.world->getWorldInfo();
  info.m_gravity = gravity;
  info.air_density = static_cast<btScalar>(def_.wind.airDensity);
  info.m_sparsesdf.setDefaultVoxelsz(
      static_cast<btScalar>(def_.collisionVoxelSize > 0 ? def_.collisionVoxelSize : automaticVoxelSize(def_)));
  info.m_sparsesdf.Reset();

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

  // The body: nodes, links, faces, in mesh order. The margin must be set before
  // the nodes are appended (it sizes their bounding volumes).
  b.body = std::make_unique<btSoftBody>(&info, 0, nullptr, nullptr);
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

  restLinkLengths_.resize(body.m_links.size());
  for (int l = 0; l < body.m_links.size(); ++l) restLinkLengths_[l] = body.m_links[l].m_rl;

  positions_.resize(n, 3);
  velocities_.resize(n, 3);
  copyOut();
  keepRollbackPoint();  // rollBack() before any step returns here
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
  if (!extraNodeMasses.allFinite() || extraNodeMasses.minCoeff() < 0)
    throw std::invalid_argument("BulletCloth::setLiquidLoads: masses must be finite and >= 0");
  if (!nodeImpulses.allFinite()) throw std::invalid_argument("BulletCloth::setLiquidLoads: impulses must be finite");
  pendingExtraMasses_ = extraNodeMasses;  // same size: no allocation
  pendingImpulses_ = nodeImpulses;
  loadsPending_ = true;
}

void BulletCloth::applyLiquidLoads() {
  btSoftBody& body = *bullet_->body;
  nodeMasses_ = lumpedMasses_ + pendingExtraMasses_;
  for (int i = 0; i < vertexCount(); ++i)
    if (!isPinned(i)) body.m_nodes[i].m_im = static_cast<btScalar>(1.0 / nodeMasses_[i]);
  body.updateLinkConstants();
  for (int i = 0; i < vertexCount(); ++i) {
    btSoftBody::Node& node = body.m_nodes[i];
    body.addVelocity(toBullet(pendingImpulses_.row(i).transpose()) * node.m_im, i);  // no-op when pinned
  }
  loadsPending_ = false;
}

void BulletCloth::movePins(double targetTime, double substep) {
  btSoftBody& body = *bullet_->body;
  bool released = false;
  for (size_t p = 0; p < def_.pins.size(); ++p) {
    if (released_[p]) continue;
    const ClothPin& pin = def_.pins[p];
    btSoftBody::Node& node = body.m_nodes[pin.vertex];
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

// Pulls each free node back onto the sphere of radius (tether length) around
// its pin's current position when it is outside, and gives it the matching
// velocity change Δx / hₛ (Bullet's own velocity update is (x − x_prev)/hₛ).
void BulletCloth::enforceTethers(double substep) {
  btSoftBody& body = *bullet_->body;
  const btScalar inverseStep = static_cast<btScalar>(1 / substep);
  for (int i = 0; i < vertexCount(); ++i) {
    const int p = tetherPin_[static_cast<size_t>(i)];
    if (p < 0 || released_[static_cast<size_t>(p)] || isPinned(i)) continue;
    btSoftBody::Node& node = body.m_nodes[i];
    const btVector3 offset = node.m_x - body.m_nodes[def_.pins[static_cast<size_t>(p)].vertex].m_x;
    const btScalar length = offset.length();
    const btScalar limit = static_cast<btScalar>(tetherLengths_[i]);
    if (length <= limit) continue;
    const btVector3 correction = offset * (limit / length - 1);
    node.m_x += correction;
    node.m_v += correction * inverseStep;
  }
}

void BulletCloth::advance(double h) {
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("BulletCloth::advance: time step must be positive");
  Bullet& b = *bullet_;
  if (loadsPending_) applyLiquidLoads();
  const double substep = h / def_.substeps;
  b.body->m_cfg.kDP = static_cast<btScalar>(1 - std::exp(-def_.dampingRate * substep));
  for (int s = 0; s < def_.substeps; ++s) {
    movePins(time_ + (s + 1) * substep, substep);
    // maxSubSteps = 0: exactly one Bullet step of this length, no accumulator.
    b.world->stepSimulation(static_cast<btScalar>(substep), 0, static_cast<btScalar>(substep));
    if (def_.tethers) enforceTethers(substep);
  }
  time_ += h;
  // Drop distance-cache cells no node has touched for a while (Bullet's demos
  // do this once per frame; otherwise the cache only grows).
  if (b.collides) b.world->getWorldInfo().m_sparsesdf.GarbageCollect();
  copyOut();
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
  // report the trajectory's exact one.
  for (size_t p = 0; p < def_.pins.size(); ++p)
    if (!released_[p]) velocities_.row(def_.pins[p].vertex) = def_.pins[p].motion.velocityAt(time_).transpose();
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

void BulletCloth::keepRollbackPoint() { captureState(rollbackState_); }

void BulletCloth::rollBack() { restoreState(rollbackState_); }

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
  if (!std::isfinite(state.time) || !state.positions.allFinite() || !state.velocities.allFinite())
    throw std::invalid_argument("BulletCloth::restoreState: time, positions and velocities must be finite");

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

// ---- Test-only access (cloth/src/bullet_cloth_testing.h) -------------------

namespace blot::cloth {

Eigen::MatrixX3i BulletClothTesting::bodyFaces(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::MatrixX3i faces(body.m_faces.size(), 3);
  for (int f = 0; f < body.m_faces.size(); ++f)
    for (int k = 0; k < 3; ++k) faces(f, k) = static_cast<int>(body.m_faces[f].m_n[k] - &body.m_nodes[0]);
  return faces;
}

Eigen::MatrixX2i BulletClothTesting::bodyLinks(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::MatrixX2i links(body.m_links.size(), 2);
  for (int l = 0; l < body.m_links.size(); ++l)
    for (int k = 0; k < 2; ++k) links(l, k) = static_cast<int>(body.m_links[l].m_n[k] - &body.m_nodes[0]);
  return links;
}

Eigen::MatrixX3d BulletClothTesting::bodyPositions(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::MatrixX3d positions(body.m_nodes.size(), 3);
  for (int i = 0; i < body.m_nodes.size(); ++i) positions.row(i) = toEigen(body.m_nodes[i].m_x).transpose();
  return positions;
}

Eigen::VectorXd BulletClothTesting::inverseMasses(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::VectorXd im(body.m_nodes.size());
  for (int i = 0; i < body.m_nodes.size(); ++i) im[i] = body.m_nodes[i].m_im;
  return im;
}

Eigen::VectorXd BulletClothTesting::linkConstants(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::VectorXd c0(body.m_links.size());
  for (int l = 0; l < body.m_links.size(); ++l) c0[l] = body.m_links[l].m_c0;
  return c0;
}

void BulletClothTesting::setMassesWithBulletSetMass(BulletCloth& cloth, const Eigen::VectorXd& masses) {
  btSoftBody& body = *cloth.bullet_->body;
  for (int i = 0; i < body.m_nodes.size(); ++i)
    if (!cloth.isPinned(i)) body.setMass(i, static_cast<btScalar>(masses[i]));
}

bool BulletClothTesting::isDisabledByBullet(const BulletCloth& cloth) {
  return cloth.bullet_->body->getActivationState() == DISABLE_SIMULATION;
}

Eigen::Vector3d BulletClothTesting::worldGravity(const BulletCloth& cloth) {
  return toEigen(cloth.bullet_->world->getGravity());
}

Eigen::Vector3d BulletClothTesting::softBodyWorldInfoGravity(const BulletCloth& cloth) {
  return toEigen(cloth.bullet_->world->getWorldInfo().m_gravity);
}

}  // namespace blot::cloth
