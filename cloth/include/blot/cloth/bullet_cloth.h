#pragma once
/// Bullet soft-body cloth as a SurfaceMotion: a btSoftBody in a classic
/// soft-rigid world, built node by node from any triangle mesh so that cloth
/// node i is mesh vertex i and Bullet face f is mesh face f. Positions and
/// velocities are copied out into Eigen arrays (double) after each advance().
/// Bullet types appear only as the two forward-declared pointers of a shared
/// world (ClothDef::world, ClothDef::body; docs/embedding.md).
///
/// Units: metres, kilograms, seconds. The model and the chosen solver settings
/// (and why) are in docs/cloth.md.
#include <blot/cloth/surface_motion.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <limits>
#include <memory>
#include <vector>

class btSoftRigidDynamicsWorld;
class btSoftBody;

namespace blot::cloth {

/// Largest |coordinate| of a pin target set at runtime (m): a scene's bound
/// on its magnitudes (engine/scene.h, kMaxSceneMagnitude).
inline constexpr double kMaxPinTarget = 1e6;
/// Smallest voxel of Bullet's signed-distance cache (m). Bullet indexes its
/// cells by position / voxel in int: a 1e-12 m sphere's automatic voxel
/// (2.5e-13 m) or an explicit 1e-20 m overflowed it and crashed inside
/// btSoftBody::checkContact; at 1 mm a scene's 1e6 m stays within int.
inline constexpr double kMinCollisionVoxelSize = 1e-3;
/// Smallest mass of a cloth node (kg): Bullet keeps 1 / mass in a float.
/// totalMass is refused where the lightest node would be lighter.
inline constexpr double kMinNodeMass = 1e-30;

/// Prescribed motion of one pinned vertex. Its target position is
///   x(t) = x̄ + velocity·t + amplitude ⊙ (sin(2π·frequency·t + phase) − sin(phase)),
/// (x̄ the rest position, ⊙ per axis), so x(0) = x̄. The defaults hold the
/// vertex still. From t = releaseTime on the vertex is free (a dropped cloth):
/// it gets its node mass (lumped cloth mass plus any liquid) and keeps the
/// pin's velocity at release.
struct PinMotion {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();   ///< m/s, constant drift
  Eigen::Vector3d amplitude = Eigen::Vector3d::Zero();  ///< m, sinusoid amplitude per axis
  double frequency = 0;                                 ///< Hz (waving); 0 = no oscillation
  double phase = 0;                                     ///< rad
  double releaseTime = std::numeric_limits<double>::infinity();  ///< s; +∞ = never released

  /// Target position (m) at time t (s) for rest position `rest` (m).
  Eigen::Vector3d position(const Eigen::Vector3d& rest, double t) const;
  /// Time derivative of position() (m/s).
  Eigen::Vector3d velocityAt(double t) const;
};

/// One pinned vertex (infinite mass in Bullet: m_im = 0) and how it moves.
struct ClothPin {
  int vertex = -1;
  PinMotion motion;
};

/// Bullet's aerodynamic models (btSoftBody::eAeroModel), same order and meaning:
/// per vertex (node normal, area = one third of the adjacent face areas) or per
/// face; one-sided models push only on the side the normal faces.
enum class AeroModel {
  VertexPoint,             ///< V_Point: node normals, oriented toward the relative velocity
  VertexTwoSided,          ///< V_TwoSided
  VertexTwoSidedLiftDrag,  ///< V_TwoSidedLiftDrag: separate lift and drag laws
  VertexOneSided,          ///< V_OneSided
  FaceTwoSided,            ///< F_TwoSided (default)
  FaceTwoSidedLiftDrag,    ///< F_TwoSidedLiftDrag
  FaceOneSided             ///< F_OneSided
};

/// Air: uniform wind and Bullet's aerodynamic force. With both coefficients 0
/// (the default) there is no aerodynamic force at all. Drag acts on the cloth's
/// velocity relative to the air, so it also slows a cloth moving in still air.
/// For the point/two-sided models the force on an element of area A, normal n,
/// relative velocity v is −½ρ|v|²A (n·v̂)(kDG v̂ + kLF n) (Bullet's formula).
struct ClothWind {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< m/s, uniform air velocity
  double dragCoefficient = 0;                          ///< Bullet kDG (dimensionless, ≥ 0)
  double liftCoefficient = 0;                          ///< Bullet kLF (dimensionless, ≥ 0)
  double airDensity = 1.2;                             ///< kg/m³
  AeroModel model = AeroModel::FaceTwoSided;
};

/// A static collision shape. Cloth nodes are kept `collisionMargin` outside it.
struct ClothCollider {
  enum class Shape { Plane, Box, Sphere };
  Shape shape = Shape::Plane;
  /// Plane: a point on it. Box, sphere: the centre. Metres.
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  /// Plane only: the normal pointing to the free side (normalized on use).
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  /// Box only: half side lengths along its own axes (m) and its orientation.
  Eigen::Vector3d halfExtents = Eigen::Vector3d::Constant(0.5);
  Eigen::Matrix3d orientation = Eigen::Matrix3d::Identity();
  /// Sphere only: radius (m).
  double radius = 0.5;
  /// Coulomb-like friction; Bullet uses kDF · friction (kDF = 0.2 default cfg,
  /// we set kDF = 1 so this is the coefficient itself), in [0, 1].
  double friction = 0.5;

  static ClothCollider plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal);
  static ClothCollider box(const Eigen::Vector3d& center, const Eigen::Vector3d& halfExtents,
                           const Eigen::Matrix3d& orientation = Eigen::Matrix3d::Identity());
  static ClothCollider sphere(const Eigen::Vector3d& center, double radius);
};

/// Which Bullet constraint solver runs the links (btSoftBody::eSolverPresets).
enum class ClothSolver {
  /// Default: links, anchors and contacts are projected on positions
  /// (positionIterations Gauss–Seidel sweeps); velocityIterations and
  /// driftIterations do nothing in this mode.
  Positions,
  /// Links solved on velocities (velocityIterations) then corrected for drift
  /// (driftIterations); contacts still on positions (positionIterations).
  Velocities
};

/// Everything needed to build a BulletCloth. Defaults are the settings measured
/// stable for long runs at 2.5K, 10K and 35K nodes (docs/cloth.md).
struct ClothDef {
  /// The rest shape as plain arrays, so that cloth/ needs no mesh library
  /// (blot::coupling::describeClothMesh fills them all from a stain mesh and
  /// its SurfaceTopology). The mesh must be a manifold triangle mesh; these
  /// arrays are checked for shapes, finiteness and index ranges only.
  Eigen::MatrixX3d restPositions;  ///< #V by 3 (m); node i is vertex i
  Eigen::MatrixX3i faces;          ///< #F by 3, counter-clockwise; Bullet face f is face f
  /// #V by 2 texture coordinates, or 0 rows: they tell structural edges
  /// (axis-aligned in UV) from shear diagonals. Without them every edge is structural.
  Eigen::MatrixX2d uvs;
  Eigen::MatrixX2i edges;          ///< #E by 2 mesh edges (each once): the first #E links, in this order
  /// #B by 2: per interior edge, the two vertices opposite it (not themselves
  /// an edge), each pair once; the bending links, after the edges. Unused
  /// when bendStiffness is 0.
  Eigen::MatrixX2i bendingPairs;
  Eigen::VectorXd nodeAreas;       ///< #V lumped areas (m², one third of the one-ring area; ≥ 0)
  /// Total cloth mass (kg, > 0), spread by lumped area: node i gets
  /// totalMass · Aᵢ / ΣA with Aᵢ = nodeAreas[i].
  double totalMass = 0.15;
  /// Bullet link stiffness kLST in (0, 1] for structural mesh edges: the fraction
  /// of a link's length error removed per solver iteration (not a modulus: the
  /// effective stiffness rises with iterations and substeps).
  double stretchStiffness = 1.0;
  /// kLST in (0, 1] for mesh edges that are diagonal in UV space (shear). Without
  /// UVs every mesh edge is structural and this is unused.
  double shearStiffness = 1.0;
  /// kLST in [0, 1] for bending links (one per interior edge, joining the two
  /// vertices opposite it); 0 builds no bending links.
  double bendStiffness = 0.2;
  /// Velocity damping rate c (1/s): each substep of length hₛ multiplies node
  /// velocities by e^{−c hₛ} (Bullet kDP = 1 − e^{−c hₛ}), so the damping does
  /// not depend on the substep count. It damps absolute velocity (like air
  /// resistance on every node), so a free fall is slowed too.
  double dampingRate = 0.5;
  ClothSolver solver = ClothSolver::Positions;
  int positionIterations = 4;   ///< Bullet piterations (≥ 1)
  int velocityIterations = 0;   ///< Bullet viterations (Velocities solver only)
  int driftIterations = 0;      ///< Bullet diterations (Velocities solver only)
  /// Bullet steps per advance(h), each of h / substeps (≥ 1).
  int substeps = 4;
  std::vector<ClothPin> pins;  ///< pinned vertices (each at most once)
  /// Long-range attachments: after each substep a node farther from its
  /// nearest pin than its rest geodesic distance × (1 + tetherSlack) is pulled
  /// back onto that sphere. Bullet's Gauss–Seidel link solver alone lets a
  /// cloth hanging from a few pins stretch with resolution (a 1 m flag's bottom
  /// 0.38 m too low at 10K nodes, 1.23 m at 35K; docs/cloth.md); tethers only
  /// ever pull toward a pin, so folds and waving are untouched. Inactive
  /// without pins and for released pins.
  bool tethers = true;
  /// Stretch allowed beyond the rest geodesic distance to the nearest pin
  /// (fraction, ≥ 0). Woven cloth gives several percent on the bias; with 0 a
  /// flag hanging from two corners cannot sag under a liquid load at all (its
  /// rest shape is already taut between the pins).
  double tetherSlack = 0.05;
  /// Gravity (m/s²), written once into both the world and the soft-body world info.
  Eigen::Vector3d gravity = Eigen::Vector3d(0, 0, -9.8);
  ClothWind wind;
  std::vector<ClothCollider> colliders;
  /// Distance (m) nodes keep from colliders (also the node bounding-volume
  /// radius). 0 = automatic: a quarter of the mean rest edge length.
  double collisionMargin = 0;
  /// Fraction of a node's penetration into a collider removed per solver
  /// iteration (Bullet kKHR, in (0, 1]). Bullet's default 0.1 let a draped
  /// 2.5K cloth sink 1.5 cm into the ground at 2 iterations; 1 keeps it out
  /// but makes resting nodes chatter (±4 cm/s, 0.2 mm); 0.5 chatters less
  /// (±2 cm/s, 0.1 mm: Bullet turns the push-out into velocity).
  double contactHardness = 0.5;
  /// Voxel size (m) of Bullet's sparse signed-distance cache used for
  /// cloth–collider contact: 0 or at least kMinCollisionVoxelSize. 0 =
  /// automatic: the smaller of 0.25 m and a quarter of the smallest sphere
  /// radius or box half extent, but not below kMinCollisionVoxelSize.
  double collisionVoxelSize = 0;
  /// Bullet 3.24 allocates scratch arrays on every substep (4 mallocs, in
  /// btSoftBody::applyClusters, even without clusters). With true, the first
  /// BulletCloth routes Bullet's raw allocations (btAlignedAllocSetCustom,
  /// process-wide) through a small recycling cache so a steady step allocates
  /// nothing. Set false when the host application installs its own Bullet
  /// allocator: Bullet has only one, and ours would then free the host's blocks.
  bool recycleBulletAllocations = true;

  /// A shared world: the caller's btSoftRigidDynamicsWorld, which the caller
  /// owns and steps (the same Bullet build and precision as Blot's). Null (the
  /// default): the cloth owns a private world and steps it in advance(). With
  /// a world the cloth's body lives in it, so the caller's rigid bodies
  /// collide with it, and advance(h) steps nothing: it reads the nodes the
  /// caller's world step moved and prepares the next step (docs/embedding.md
  /// gives the contract: one world step of h per advance(h), in `substeps`
  /// substeps). The world's gravity and soft-body world info are the
  /// caller's: `gravity` must equal the world info's m_gravity (checked),
  /// windVelocity, drag and lift still go to a body Blot builds. `colliders`
  /// are added to that world as static objects and removed again by the
  /// cloth's destructor, so the world must outlive the cloth (and the Engine
  /// that owns it): destroy the engine first.
  btSoftRigidDynamicsWorld* world = nullptr;
  /// With `world`: a body the caller built (it need not be in the world yet;
  /// the cloth adds it then and removes it again on destruction). Node i must
  /// be vertex i of restPositions and, when the body has faces, face f must be
  /// `faces` row f. The caller's links, materials, solver settings and node
  /// masses stay as they are (totalMass, the stiffnesses, iterations and
  /// dampingRate are not used; its node masses are the cloth's own masses);
  /// nodes the caller holds (m_im = 0) are never given a mass. Null: Blot
  /// builds the body from this def and owns it.
  btSoftBody* body = nullptr;
};

/// Everything a BulletCloth carries from one advance() to the next, as plain
/// arrays (save/load). Bullet's single-precision values are stored exactly in
/// doubles. Restoring it into a cloth built from the same ClothDef and
/// stepping gives bit-identical positions to the run it was captured from
/// (docs/cloth.md says what is rebuilt rather than stored).
struct BulletClothState {
  double time = 0;                 ///< s
  Eigen::MatrixX3d positions;      ///< #V by 3, Bullet m_x (m)
  Eigen::MatrixX3d previousPositions;   ///< #V by 3, m_q: positions before the last substep (m)
  Eigen::MatrixX3d velocities;     ///< #V by 3, m_v (m/s; Bullet's own, damped, also for pins)
  Eigen::MatrixX3d previousVelocities;  ///< #V by 3, m_vn (m/s)
  Eigen::MatrixX3d forces;         ///< #V by 3, m_f force accumulator (N; 0 between steps)
  Eigen::MatrixX3d nodeNormals;    ///< #V by 3, m_n (aerodynamics reads them before refreshing)
  Eigen::VectorXd nodeAreas;       ///< #V, m_area (m²)
  Eigen::MatrixX3d faceNormals;    ///< #F by 3, m_normal
  Eigen::VectorXd inverseMasses;   ///< #V, m_im (1/kg; 0 = pinned)
  Eigen::VectorXd nodeMasses;      ///< #V, lumped + applied liquid (kg)
  Eigen::VectorXd pendingExtraMasses;  ///< #V, liquid loads not yet applied (kg)
  Eigen::MatrixX3d pendingImpulses;    ///< #V by 3 (N·s)
  bool loadsPending = false;
  std::vector<char> releasedPins;  ///< per ClothDef pin: 1 once released
  /// Per ClothDef pin: 1 once moved by BulletCloth::setPinTarget (its
  /// PinMotion no longer applies), and the position it is moved to (m; zero rows
  /// for pins never moved).
  std::vector<char> movedPins;
  Eigen::MatrixX3d pinTargets;
  /// Every field, once (save/load and the state hash are built on it).
  template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static void fields(Self& s, Visitor& v) {
    v.field("time", s.time);
    v.field("positions", s.positions);
    v.field("previousPositions", s.previousPositions);
    v.field("velocities", s.velocities);
    v.field("previousVelocities", s.previousVelocities);
    v.field("forces", s.forces);
    v.field("nodeNormals", s.nodeNormals);
    v.field("nodeAreas", s.nodeAreas);
    v.field("faceNormals", s.faceNormals);
    v.field("inverseMasses", s.inverseMasses);
    v.field("nodeMasses", s.nodeMasses);
    v.field("pendingExtraMasses", s.pendingExtraMasses);
    v.field("pendingImpulses", s.pendingImpulses);
    v.field("loadsPending", s.loadsPending);
    v.field("releasedPins", s.releasedPins);
    v.field("movedPins", s.movedPins);
    v.field("pinTargets", s.pinTargets);
  }
};

/// Bullet soft-body cloth. Move-only; owns its Bullet world, or lives in the
/// caller's (ClothDef::world).
class BulletCloth final : public SurfaceMotion {
 public:
  /// Builds the body from the def's arrays in O((#V + #F) log #V) (a balanced
  /// node tree, fast marching for tethers; no vertex-count² table), or adopts
  /// ClothDef::body. Throws std::invalid_argument naming the field (and row)
  /// for a bad def.
  explicit BulletCloth(const ClothDef& def);
  ~BulletCloth() override;
  BulletCloth(BulletCloth&&) noexcept;
  BulletCloth& operator=(BulletCloth&&) noexcept;
  BulletCloth(const BulletCloth&) = delete;
  BulletCloth& operator=(const BulletCloth&) = delete;

  int vertexCount() const override { return static_cast<int>(positions_.rows()); }
  double time() const override { return time_; }
  /// Node positions at time(), #V by 3 (m). Valid until the next advance().
  const Eigen::MatrixX3d& positions() const override { return positions_; }
  /// Node velocities at time(), #V by 3 (m/s); pinned nodes report their
  /// trajectory's exact velocity.
  const Eigen::MatrixX3d& velocities() const override { return velocities_; }
  /// Applies pending liquid loads, then runs `substeps` Bullet steps of h /
  /// substeps (h > 0, s), moving pinned nodes along their trajectories and
  /// releasing pins whose time has come. Allocates nothing itself (Bullet may
  /// when contacts appear or its distance cache grows).
  /// In a shared world (ClothDef::world) the caller has just stepped the
  /// world by h: advance(h) puts held pins exactly on their targets at
  /// time() + h, releases pins, enforces tethers, reads the nodes, and gives
  /// held pins the velocity that carries them to their next targets during
  /// the caller's next world step of h.
  void advance(double h) override;

  /// Moves the pin at `vertex` at runtime: during the next advance() it goes
  /// in a straight line from where it is to `position` (m, finite, each
  /// coordinate within kMaxPinTarget) and is held
  /// there afterwards; its PinMotion (drift, waving, release) no longer
  /// applies. A later call replaces the target. Deterministic, saved with the
  /// state. Throws std::invalid_argument unless `vertex` is a pin not yet
  /// released.
  void setPinTarget(int vertex, const Eigen::Vector3d& position) override;
  /// True when the body lives in the caller's world (ClothDef::world).
  bool sharesWorld() const;

  /// Two-way coupling input, applied at the start of the next advance():
  /// extraNodeMasses (#V, kg ≥ 0) is the liquid mass carried by each node and
  /// replaces the previous value (node mass = lumped cloth mass + extra);
  /// nodeImpulses (#V by 3, N·s) is added once as a velocity change
  /// impulse / node mass. Pinned nodes ignore both (infinite mass).
  /// The mass goes into Bullet's inverse mass directly, followed by a refresh
  /// of the link constants — never btSoftBody::setMass, which would make the
  /// current stretched link lengths the new rest lengths (docs/cloth.md).
  /// Calling it again before advance() replaces the pending loads. In a
  /// shared world they are written into the body at once, for the caller's
  /// next world step.
  void setLiquidLoads(const Eigen::VectorXd& extraNodeMasses, const Eigen::MatrixX3d& nodeImpulses) override;
  bool acceptsLiquidLoads() const override { return true; }
  const Eigen::VectorXd* clothNodeMasses() const override { return &lumpedMasses_; }
  bool hasDynamicState() const override { return true; }
  /// captureState / restoreState through BulletClothState's field list.
  void saveDynamicState(MotionStateVisitor& visitor) const override;
  void loadDynamicState(MotionStateVisitor& visitor) override;

  const Eigen::MatrixX3i& faces() const { return faces_; }
  /// Node masses (kg, #V): lumped cloth mass plus the liquid mass last applied
  /// (also for pinned nodes, which Bullet holds with infinite mass; a released
  /// pin gets this mass).
  const Eigen::VectorXd& nodeMasses() const { return nodeMasses_; }
  /// The cloth's own node masses (kg, #V): totalMass spread by lumped area,
  /// without liquid.
  const Eigen::VectorXd& lumpedMasses() const { return lumpedMasses_; }
  /// True while vertex i is held by a pin (false after its release time).
  bool isPinned(int vertex) const;

  /// Links in Bullet's order, #L by 2 vertex indices: ClothDef.edges in their
  /// order, then ClothDef.bendingPairs (when bendStiffness > 0).
  const Eigen::MatrixX2i& linkVertices() const { return linkVertices_; }
  /// Per link: true for a mesh edge, false for a bending link (#L).
  const std::vector<bool>& linkIsEdge() const { return linkIsEdge_; }
  /// Rest length (m) of every link, recorded when the body was built (#L).
  const Eigen::VectorXd& restLinkLengths() const { return restLinkLengths_; }
  /// Bullet's rest length (m) of every link now, read from the body (#L).
  /// Equals restLinkLengths() bit for bit unless something reset it.
  Eigen::VectorXd currentLinkRestLengths() const;
  /// Largest |ℓ/ℓ̄ − 1| over the mesh-edge links at the current positions.
  double maxEdgeStrain() const;

  /// Axis-aligned bounding box of positions() (m).
  const Eigen::AlignedBox3d& boundingBox() const { return boundingBox_; }
  /// Σ ½ mᵢ |vᵢ|² over all nodes with nodeMasses() (J).
  double kineticEnergy() const;
  /// Σ −mᵢ g·xᵢ (J), relative to the origin.
  double gravitationalEnergy() const;
  /// Finite positions and velocities, bounding-box diagonal at most 10× the rest
  /// one, no mesh edge longer than 10× its rest length, and Bullet has not
  /// disabled the body (it does so silently when the body's box passes 10⁶ m
  /// after a blow-up). O(#V + #E).
  bool isHealthy() const override;
  /// The state between two advance() calls (allocates; for save/load).
  BulletClothState captureState() const;
  /// The same into `state`, reusing its arrays: no allocation once they have
  /// this cloth's sizes (keepRollbackPoint calls it every step).
  void captureState(BulletClothState& state) const;
  /// Puts a captured state back (same ClothDef: vertex, face and pin counts
  /// must match, std::invalid_argument naming the field otherwise). Rebuilds
  /// what Bullet derives from it: link constants from the inverse masses, the
  /// node bounding-volume tree and the body's bounds from the positions.
  void restoreState(const BulletClothState& state);
  /// Captures the state into a kept BulletClothState (O(#V + #F) copies,
  /// about 1 % of a step; the copy costs ~250 bytes per vertex of memory).
  void keepRollbackPoint() override;
  /// restoreState(kept state); the construction state before any keepRollbackPoint().
  void rollBack() override;

  /// Distance nodes keep from colliders (m), after the automatic choice.
  double collisionMargin() const { return collisionMargin_; }
  const ClothDef& definition() const { return def_; }

 private:
  friend struct BulletClothTesting;
  struct Bullet;  // the Bullet objects, defined in cloth/src/bullet_cloth_impl.h
  void applyLiquidLoads();
  void adoptBody();
  void movePins(double targetTime, double substep, double fraction);
  Eigen::Vector3d pinTarget(std::size_t pin, double t) const;
  void advanceSharedWorld(double h);
  void enforceTethers(double substep);
  void copyOut();

  ClothDef def_;
  std::unique_ptr<Bullet> bullet_;
  Eigen::MatrixX3d restPositions_;
  Eigen::MatrixX3i faces_;
  Eigen::VectorXd lumpedMasses_, nodeMasses_;
  Eigen::VectorXd pendingExtraMasses_;
  Eigen::MatrixX3d pendingImpulses_;
  bool loadsPending_ = false;
  std::vector<int> pinSlot_;     // per vertex: index into def_.pins or -1
  std::vector<char> released_;   // per pin
  std::vector<char> moved_;      // per pin: 1 once setPinTarget moved it
  Eigen::MatrixX3d pinTargets_;  // per pin: setPinTarget's position (m)
  Eigen::MatrixX3d moveStarts_;  // per pin: where a moved pin was when this advance began
  std::vector<char> heldByCaller_;  // per vertex: m_im = 0 in an adopted body (never given a mass)
  double lastStep_ = 0;          // h of the last advance (shared world: the next world step's length)
  Eigen::MatrixX2i linkVertices_;
  std::vector<bool> linkIsEdge_;
  std::vector<int> tetherPin_;     // per vertex: pin slot it is tied to, or -1
  Eigen::VectorXd tetherLengths_;  // per vertex: longest allowed distance to that pin (m)
  Eigen::VectorXd restLinkLengths_;
  Eigen::MatrixX3d positions_, velocities_;
  Eigen::AlignedBox3d boundingBox_;
  BulletClothState rollbackState_;  // keepRollbackPoint / rollBack
  // A shared world: the state the last advance() left, before the owner's
  // next world step; the rollback point once the step that made it is over.
  BulletClothState sharedNext_;
  bool sharedNextValid_ = false;
  double restDiagonal_ = 0;
  double collisionMargin_ = 0;
  double time_ = 0;
};

}  // namespace blot::cloth
