#pragma once
/// The geometry cache the stain stages read, in two tiers (DESIGN.md, step 2).
///
///  - IntrinsicGeometry: everything that depends on edge lengths only (angles,
///    areas, cotan weights, lumped mass, polar maps, transport angles) plus the
///    operators built from them. The cloth is inelastic, so this is rebuilt only
///    when the largest edge strain since the last rebuild passes a tolerance;
///    rigid and isometric motion never rebuild it.
///  - ExtrinsicGeometry: what the embedding changes every step (positions at
///    t−h, t, t+h; normals; Kabsch rotations; frames; accelerations; angular
///    velocities).
///
/// Values change only in SurfaceGeometry::refresh*(), called once per step by
/// the step's "refresh geometry" stage; every other stage reads them const.
#include <blot/stain/fabric/fabric_field.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/geometry/rotation_fit.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/transport.h>
#include <blot/stain/types.h>

#include <utility>
#include <vector>

namespace blot::stain {

struct IntrinsicGeometry {
  Vector edgeLengths;                   ///< #E (m), at the last rebuild
  Eigen::MatrixX3d faceCornerAngles;    ///< #F by 3 (rad)
  Vector faceAreas;                     ///< #F (m²)
  Vector edgeCotanWeights;              ///< #E, ½(cot α + cot β)
  Vector vertexDualAreas;               ///< #V (m²), lumped mass
  PolarMap polarMap;                    ///< α per ring entry, scale per vertex
  Vector edgeTransportAngles;           ///< #E θ_ij (i < j), u_i ≈ e^{iθ_ij} u_j
  Eigen::MatrixX3d faceTransportAngles; ///< #F by 3, vertex frame -> face frame
  SparseMatrix densityStiffness;        ///< #V by #V, L_Sf (PSD)
  ComplexSparseMatrix velocityStiffness;  ///< #V by #V, connection Laplacian with S_v (PSD)
  int rebuildCount = 0;                 ///< how many times this tier was built
  /// Exchanges every field's buffers, copying nothing. std::swap would copy
  /// the two operators three times each: Eigen 3.4's SparseMatrix has no move.
  friend void swap(IntrinsicGeometry& a, IntrinsicGeometry& b) noexcept {
    a.edgeLengths.swap(b.edgeLengths);
    a.faceCornerAngles.swap(b.faceCornerAngles);
    a.faceAreas.swap(b.faceAreas);
    a.edgeCotanWeights.swap(b.edgeCotanWeights);
    a.vertexDualAreas.swap(b.vertexDualAreas);
    a.polarMap.ringAngles.swap(b.polarMap.ringAngles);
    a.polarMap.vertexAngleScales.swap(b.polarMap.vertexAngleScales);
    a.edgeTransportAngles.swap(b.edgeTransportAngles);
    a.faceTransportAngles.swap(b.faceTransportAngles);
    a.densityStiffness.swap(b.densityStiffness);
    a.velocityStiffness.swap(b.velocityStiffness);
    std::swap(a.rebuildCount, b.rebuildCount);
  }
  /// Every field, once (save/load and the state hash are built on it).
  template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static void fields(Self& s, Visitor& v) {
    v.field("edgeLengths", s.edgeLengths);
    v.field("faceCornerAngles", s.faceCornerAngles);
    v.field("faceAreas", s.faceAreas);
    v.field("edgeCotanWeights", s.edgeCotanWeights);
    v.field("vertexDualAreas", s.vertexDualAreas);
    v.field("polarMap.ringAngles", s.polarMap.ringAngles);
    v.field("polarMap.vertexAngleScales", s.polarMap.vertexAngleScales);
    v.field("edgeTransportAngles", s.edgeTransportAngles);
    v.field("faceTransportAngles", s.faceTransportAngles);
    v.field("densityStiffness", s.densityStiffness);
    v.field("velocityStiffness", s.velocityStiffness);
    v.field("rebuildCount", s.rebuildCount);
  }
};

struct ExtrinsicGeometry {
  RowVectors3 previousPositions;  ///< #V by 3 at t − h (m)
  RowVectors3 positions;          ///< #V by 3 at t (m)
  RowVectors3 nextPositions;      ///< #V by 3 at t + h (m)
  RowVectors3 vertexNormals;      ///< #V by 3 at t, unit
  /// Per vertex, 3x3 frames with columns (x, y, z): F̄_i at rest (x along the
  /// reference edge), F_i^t = U_i^t F̄_i and F_i^{t+h} = U_i^{t+h} F̄_i.
  std::vector<Matrix3> restFrames, frames, nextFrames;
  std::vector<Matrix3> kabschRotations;  ///< U_i^{t+h}: best rotation rest one-ring -> current
  RowVectors3 vertexAccelerations;       ///< #V by 3, p̈_i^t by centred differences (m/s², world)
  /// #V by 3, ω_i in frame coordinates of F_i^t (rad/s): the rotation vector
  /// (exact log map) of (F^t)ᵀ F^{t+h}, divided by h. The paper's antisymmetrised
  /// ((F^t)ᵀ F^{t+h} − (F^{t+h})ᵀ F^t) / 2h is its first-order form (it returns
  /// sin(|ω|h)/h instead of |ω|). Component z is the normal rate that rotates
  /// tangent vectors (Coriolis).
  RowVectors3 vertexAngularVelocities;
  /// Whether positions and frames at t (rigid) and at t + h (nextRigid) are
  /// R x̄ + c and R F̄_i for one rotation R (x̄, F̄ the rest shape): set by
  /// refreshExtrinsicRigid, cleared by refreshExtrinsic and
  /// setPreviousPositions. Stages may then use rest-shape quantities instead
  /// of recomputing them from the positions (density advection does).
  bool rigid = true, nextRigid = true;
  /// Every field, once (save/load and the state hash are built on it).
  template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static void fields(Self& s, Visitor& v) {
    v.field("previousPositions", s.previousPositions);
    v.field("positions", s.positions);
    v.field("nextPositions", s.nextPositions);
    v.field("vertexNormals", s.vertexNormals);
    v.field("restFrames", s.restFrames);
    v.field("frames", s.frames);
    v.field("nextFrames", s.nextFrames);
    v.field("kabschRotations", s.kabschRotations);
    v.field("vertexAccelerations", s.vertexAccelerations);
    v.field("vertexAngularVelocities", s.vertexAngularVelocities);
    v.field("rigid", s.rigid);
    v.field("nextRigid", s.nextRigid);
  }
};
// A field added to either tier without a line in its fields() fails here first.
static_assert(sizeof(IntrinsicGeometry) == 7 * sizeof(Vector) + 2 * sizeof(Eigen::MatrixX3d) + sizeof(SparseMatrix) +
                                               sizeof(ComplexSparseMatrix) + 8,
              "IntrinsicGeometry changed: list the new field in IntrinsicGeometry::fields");
static_assert(sizeof(ExtrinsicGeometry) == 6 * sizeof(RowVectors3) + 4 * sizeof(std::vector<Matrix3>) + 8,
              "ExtrinsicGeometry changed: list the new field in ExtrinsicGeometry::fields");


/// Per edge, 4 numbers (row-major #E by 4): see SurfaceGeometry::restEdgeFrameNormals.
using EdgeFrameNormals = Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>;

/// Unit normal and centroid of face f at `positions` (the terms dualEdgeNormal
/// takes from each face).
inline void faceNormalAndCentroid(const SurfaceTopology& topology, const RowVectors3& positions, int f,
                                  Vector3& unitNormal, Vector3& centroid) {
  const Vector3 p0 = positions.row(topology.faces()(f, 0)).transpose();
  const Vector3 p1 = positions.row(topology.faces()(f, 1)).transpose();
  const Vector3 p2 = positions.row(topology.faces()(f, 2)).transpose();
  unitNormal = (p1 - p0).cross(p2 - p0).normalized();
  centroid = (p0 + p1 + p2) / 3.0;
}

/// dualEdgeNormal with each face's unit normal and centroid given by
/// face(f, unitNormal, centroid), e.g. from a per-step cache: the same terms
/// in the same order, so the same bits.
template <typename FaceData>
Vector3 dualEdgeNormalFrom(const SurfaceTopology& topology, const RowVectors3& positions, int e,
                           const FaceData& face) {
  Vector3 normal = Vector3::Zero();
  const int lower = topology.edgeVertices()(e, 0);
  const int first = topology.edgeHalfedges()[static_cast<size_t>(e)];
  const int second = topology.halfedgeTwins()[static_cast<size_t>(first)];
  for (const int h : {first, second}) {
    if (h < 0) continue;
    Vector3 faceNormal, centroid;
    face(h / 3, faceNormal, centroid);
    const Vector3 pa = positions.row(topology.halfedgeTail(h)).transpose();
    const Vector3 pb = positions.row(topology.halfedgeHead(h)).transpose();
    const Vector3 toCentroid = centroid - 0.5 * (pa + pb);
    // (c − m) × n points from the half-edge's tail to its head.
    const Vector3 piece = toCentroid.cross(faceNormal);
    normal += topology.halfedgeTail(h) == lower ? piece : Vector3(-piece);
  }
  return normal;
}

/// Integrated unit normal of the barycentric dual edge of edge e (m), oriented
/// from edgeVertices(e, 0) to edgeVertices(e, 1): Σ over the edge's faces of
/// (c_T − m) × n_T, c_T the face centroid, m the edge midpoint, n_T the unit
/// face normal. Evaluated in the same order whichever endpoint asks, so the
/// two ring entries of an edge can use bitwise opposite values.
inline Vector3 dualEdgeNormal(const SurfaceTopology& topology, const RowVectors3& positions, int e) {
  return dualEdgeNormalFrom(topology, positions, e, [&](int f, Vector3& unitNormal, Vector3& centroid) {
    faceNormalAndCentroid(topology, positions, f, unitNormal, centroid);
  });
}

/// How refreshIntrinsic rebuilds the intrinsic tier.
enum class IntrinsicRefresh {
  /// default: every edge takes its current length and the whole tier is
  /// rebuilt, the operators from the current positions (each face laid out
  /// in its plane, the weft carried as a material line).
  Full,
  /// Only the edges whose strain against their own built length passes
  /// kPartialRefreshFraction × the tolerance take their current length; the
  /// values that depend on those lengths (their faces' angles, areas and
  /// stiffness blocks; their vertices' dual areas, polar maps and transport
  /// angles; the operator entries these touch) are recomputed in place, the
  /// operators from the lengths (operators.h, *FromLengths). The result is
  /// bitwise the whole tier built from the same per-edge lengths
  /// (intrinsicGeometryFromLengths); more than kPartialRefreshMaxShare of the
  /// edges chosen rebuilds it from all current lengths. Not the default:
  /// the metric of mixed-age lengths costs far more accuracy than it saves
  /// time (docs/accuracy.md, "Strain tolerance").
  Partial,
  /// Every edge of the faces within kRegionRefreshRings rings of the
  /// vertices given to setRefreshRegion (StainSolver: those its strain test
  /// measured around, the free liquid) takes its current length, the rest
  /// keep theirs; the dependent values as in Partial (the same machinery and
  /// result: bitwise the tier from those per-edge lengths). Unlike Partial,
  /// the region is whole: the liquid's part of the metric is one surface's,
  /// and the lengths of different ages meet rings away from the liquid. As
  /// accurate as the whole rebuild at the same trigger, at about 0.7 of its
  /// cost on the two-way flag (docs/accuracy.md, "Strain tolerance"). More
  /// than kPartialRefreshMaxShare of the edges: the whole tier from the
  /// current lengths, as Partial (Full's whole rebuild, refilled in place).
  Region
};
/// Rings around the refresh region's vertices whose faces a Region refresh
/// re-measures too.
inline constexpr int kRegionRefreshRings = 3;
/// Share of the tolerance past which an edge is re-measured by a partial
/// refresh: the refreshed edges then start again from strain 0, the others
/// sit below half the tolerance, so the next trip needs a real change.
inline constexpr double kPartialRefreshFraction = 0.5;
/// Above this share of the edges chosen, a partial refresh rebuilds everything.
inline constexpr double kPartialRefreshMaxShare = 0.25;

/// The whole intrinsic tier from per-edge lengths (#E, m): what
/// SurfaceGeometry's refreshIntrinsic stores (faceWeftCoefficients: see
/// operators.h; the fabric's tensors per face). Allocates.
void intrinsicGeometryFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                  const Eigen::MatrixX3d& densityTensors, const Eigen::MatrixX3d& velocityTensors,
                                  const Eigen::MatrixX2d& faceWeftCoefficients, IntrinsicGeometry& geometry);

/// Which vertices a refresh computes the per-vertex extrinsic values of
/// (normals, U_i, frames at t and t + h, p̈_i, ω_i).
enum class VertexRefresh {
  AllVertices,  ///< default: every vertex, inside refreshExtrinsic*
  OnDemand      ///< only the vertices passed to prepareVertices since the refresh (the liquid band)
};

class SurfaceGeometry {
 public:
  /// Builds both tiers for the rest shape (positions at t−h = t = t+h = rest).
  /// strainTolerance: rebuild the intrinsic tier when max_e |ℓ_e/ℓ_e,built − 1|
  /// exceeds it (default 1e-3: 0.1 % stretch).
  SurfaceGeometry(const SurfaceTopology& topology, const RowVectors3& restPositions,
                  const FabricField& fabric, double strainTolerance = 1e-3);

  /// Sets the positions the next refreshExtrinsic will treat as t − h (first
  /// step: p(0) − h v(0) from the motion's velocities, so the first acceleration
  /// is not a spurious jump). Call before the first refreshExtrinsic: the slots
  /// shift at each refresh, so this writes the slot that becomes t − h. If the
  /// surface at t = 0 is not the rest shape, first call refreshExtrinsic(p(0), h)
  /// (it becomes t + h), then this, then step as usual.
  void setPreviousPositions(const RowVectors3& previous);

  /// Shifts t+h -> t -> t−h, takes `nextPositions` (#V by 3, m) as the new t+h,
  /// h (s, > 0) being the time from t to t + h, and recomputes the extrinsic
  /// tier. Returns whether the intrinsic tier must be rebuilt (strain test);
  /// does not rebuild it. Allocates nothing; uses OpenMP threads.
  /// strainTest false: no strain test (O(#E)) and false returned, for a
  /// surface whose metric nothing reads (no liquid has ever been on it);
  /// maxEdgeStrain() is then 0 and the next test measures every edge.
  bool refreshExtrinsic(const RowVectors3& nextPositions, double h, bool strainTest = true);
  /// The strain test on part of the surface: the edges of the faces at
  /// vertices[0, count) (ids in [0, #V), any order, repeats allowed), at the
  /// t + h positions of the last refresh. Returns whether max over those edges
  /// of |ℓ_e/ℓ̂_e − 1| exceeds the tolerance, and makes that max (0 for no
  /// vertex) maxEdgeStrain(). For a caller that reads the metric only around
  /// those vertices (StainSolverDef::strainTest, StrainTest::AroundLiquid),
  /// after a refreshExtrinsic without its own test. O(edges tested) with no
  /// allocation, whatever the mesh's size.
  bool strainExceededAround(const int* vertices, int count);
  /// The same for a surface known to move rigidly, nextPositions = R x̄ + c
  /// (x̄ the rest shape, R the rotation at t + h, any translation c): U_i = R
  /// for every vertex, normals R n̄, no rotation fits and no strain test
  /// (rigid motion keeps the metric); ~4x cheaper than refreshExtrinsic. The
  /// caller guarantees rigidity (checked only in BLOT_VALIDATE builds); R must
  /// be a rotation matrix (std::invalid_argument otherwise).
  bool refreshExtrinsicRigid(const RowVectors3& nextPositions, const Matrix3& rotation, double h);
  /// In VertexRefresh::OnDemand a refresh only shifts the positions and runs
  /// the strain test (O(#E), allocation-free); the per-vertex values of
  /// ExtrinsicGeometry (vertexNormals, frames, nextFrames, kabschRotations,
  /// vertexAccelerations, vertexAngularVelocities) hold this refresh's values
  /// only on the vertices prepared since it, and stale ones elsewhere. Each
  /// value is a function of the positions (or the rigid rotation) of its time
  /// slot alone, the rotation fits included (Newton from a guess built from the
  /// vertex's own normal and reference edge), so a prepared vertex holds
  /// bitwise what AllVertices computes, whatever was prepared before.
  void setVertexRefresh(VertexRefresh mode);
  VertexRefresh vertexRefresh() const { return vertexRefresh_; }
  /// Computes this refresh's per-vertex values on vertices[0, count) (ids in
  /// [0, #V), any order, repeats allowed; already prepared ones cost a
  /// compare), visiting them in index order. Uses OpenMP threads from
  /// kMinParallelVertices; allocates nothing.
  void prepareVertices(const int* vertices, int count);
  void prepareVertices(const std::vector<int>& vertices) {
    prepareVertices(vertices.data(), static_cast<int>(vertices.size()));
  }
  void prepareAllVertices();
  bool vertexPrepared(int vertex) const { return preparedAt_[static_cast<size_t>(vertex)] == refreshIndex_; }
  /// Vertices prepared since the last refresh that moved the surface (all
  /// of them in AllVertices mode).
  int preparedVertexCount() const { return preparedCount_; }
  /// Whether positions at t − h, t and t + h are not all equal (the surface
  /// moved over the last two steps), without comparing the arrays.
  bool surfaceMoved() const { return !(currentEqualsPrevious_ && nextEqualsCurrent_); }
  /// Whether the last refresh's t + h slot is fitted (a deforming refresh).
  bool fittedRefresh() const { return nextRule_.kind == SlotKind::Fitted && !nextEqualsCurrent_; }

  /// Rebuilds the intrinsic tier from the current positions (t + h), wholly
  /// or partially (setIntrinsicRefresh; the mode should be set before the
  /// first refresh after construction). The partial path allocates nothing.
  /// The tier it replaces is kept for undoIntrinsicRefresh.
  void refreshIntrinsic();
  /// Sizes now what a whole refreshIntrinsic would otherwise allocate at the
  /// first rebuild: the second tier it builds into (with the operators'
  /// patterns) and the table that refills them in place. A
  /// surface that deforms calls it before its first step, so that no rebuild
  /// allocates and the first is no dearer than the later ones; one that
  /// never deforms need not, as it then holds one more tier in memory. The
  /// spare tier holds a copy of this one (no refresh to undo: the kept tier
  /// stays invalid). Idempotent.
  void prepareWholeRebuilds();
  /// Puts back the tier, the built lengths and the strain measure as they
  /// were before the last refreshIntrinsic: the rollback of a step that
  /// rebuilt and then failed, so that the restored densities (per area) meet
  /// the areas they were computed with. Valid once after each refresh; a
  /// restore (restoreDynamicState) or a mode switch forgets the kept tier.
  void undoIntrinsicRefresh();
  /// Switching to Partial rebuilds the tier from its built lengths
  /// (intrinsicGeometryFromLengths), so that every later partial refresh
  /// starts from a tier it is bitwise consistent with; allocates.
  void setIntrinsicRefresh(IntrinsicRefresh mode);
  /// The vertices a Region refresh re-measures around (ids in [0, #V),
  /// repeats allowed, at most #V of them; copied without allocation). Kept
  /// until the next call.
  void setRefreshRegion(const int* vertices, int count);
  IntrinsicRefresh intrinsicRefresh() const { return intrinsicRefresh_; }
  /// Edges re-measured and faces whose stiffness block was recomputed by the
  /// last refreshIntrinsic (#E and #F after a whole rebuild).
  int refreshedEdgeCount() const { return refreshedEdges_; }
  int refreshedFaceCount() const { return refreshedFaces_; }
  /// Whether the last refreshIntrinsic was partial (Partial or Region, not
  /// their whole fallback), and then what it changed: the vertices whose dual
  /// area and density-operator column it recomputed (V1, ascending), and
  /// those whose connection column it recomputed (V2 ⊇ V1, ascending).
  bool lastRefreshPartial() const { return lastRefreshPartial_; }
  const std::vector<int>& refreshedVertices() const { return vertices1_; }
  const std::vector<int>& reassembledConnectionVertices() const { return vertices2_; }
  /// #F by 2, the rest wefts as combinations of the rest faces' edges (operators.h).
  const Eigen::MatrixX2d& faceWeftCoefficients() const { return faceWeftCoefficients_; }
  /// max_e |ℓ_e(t+h)/ℓ_e,built − 1| from the last refreshExtrinsic (over the
  /// edges strainExceededAround tested, when it ran after it).
  double maxEdgeStrain() const { return dynamic_.maxEdgeStrain; }

  const SurfaceTopology& topology() const { return *topology_; }
  const IntrinsicGeometry& intrinsic() const { return dynamic_.intrinsic; }
  const ExtrinsicGeometry& extrinsic() const { return dynamic_.extrinsic; }
  const FabricField& fabric() const { return fabric_; }

  /// Chooses the rotation fit used by refreshExtrinsic (default WarmStartedNewton).
  void setRotationFitMethod(RotationFitMethod method) { rotationFitMethod_ = method; }
  const RotationFitStats& rotationFitStats() const { return rotationFitStats_; }
  /// Per edge e (#E by 4, m): the rest shape's dualEdgeNormal N̄_e in the rest
  /// frames of its vertices a = edgeVertices(e, 0), b = edgeVertices(e, 1):
  /// ((F̄_aᵀ N̄_e)_x, (F̄_aᵀ N̄_e)_y, (F̄_bᵀ N̄_e)_x, (F̄_bᵀ N̄_e)_y). Under rigid
  /// motion (frames R F̄, normals R N̄) the flux speed ½(F_a u_a + F_b u_b)·N_e
  /// is ½(u_a·(first pair) + u_b·(second pair)): no 3D work per step.
  const EdgeFrameNormals& restEdgeFrameNormals() const { return restEdgeFrameNormals_; }

  /// Everything the refresh stages carry from one step to the next beyond the
  /// constructor's inputs (both tiers, the rotation history that warm-starts
  /// the fits, the last h): restoring it into a geometry built from the same
  /// topology, rest shape, fabric and tolerance makes every later refresh
  /// bit-identical. Used by StainSolver::snapshot/restore (engine save/load).
  struct DynamicState {
    IntrinsicGeometry intrinsic;
    ExtrinsicGeometry extrinsic;
    RowVectors3 nextNormals;
    std::vector<Eigen::Quaterniond> rotations, nextRotations;
    Vector inverseBuiltSquaredLengths;
    double maxEdgeStrain = 0;
    double lastH = 0;
    int unchangedRefreshes = 2;
    /// How the t + h slot's values follow from its inputs: 0 the rest shape's
    /// (constructor), 1 one rotation for every vertex (nextRotations[0],
    /// kabschRotations[0]), 2 fitted to nextPositions.
    int nextSlotKind = 0;
    /// Every field, once (save/load and the state hash are built on it).
    template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
    template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
    template <class Self, class Visitor>
    static void fields(Self& s, Visitor& v) {
      s.intrinsic.visit(v);
      s.extrinsic.visit(v);
      v.field("nextNormals", s.nextNormals);
      v.field("rotations", s.rotations);
      v.field("nextRotations", s.nextRotations);
      v.field("inverseBuiltSquaredLengths", s.inverseBuiltSquaredLengths);
      v.field("maxEdgeStrain", s.maxEdgeStrain);
      v.field("lastH", s.lastH);
      v.field("unchangedRefreshes", s.unchangedRefreshes);
      v.field("nextSlotKind", s.nextSlotKind);
    }
  };
  /// Copy of the dynamic state with every vertex's values computed (allocates;
  /// O(#V) rotation fits in OnDemand mode).
  DynamicState dynamicState() const;
  /// Restores a dynamic state taken from a geometry on the same topology
  /// (the caller checks sizes; StainSolver::restore does).
  void restoreDynamicState(const DynamicState& s);

 private:
  bool refreshExtrinsicWith(const RowVectors3& nextPositions, double h, const Matrix3* rigidRotation,
                            bool strainTest);
  /// The strain test of every edge at t + h into dynamic_.maxEdgeStrain.
  void measureStrain();
  // How a time slot's per-vertex values follow from its inputs.
  enum class SlotKind { Rest, Rigid, Fitted };
  struct SlotRule {
    SlotKind kind = SlotKind::Rest;
    Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // Rigid: U_i for every i
    Matrix3 matrix = Matrix3::Identity();                          // ... and its matrix, as given
  };
  // What this refresh's ω_i and p̈_i follow from.
  struct RateRule {
    bool still = true;      // p(t + h) == p(t): ω = 0
    double h = 1, previousH = 1;
    bool shared = false;    // U^t one rotation for every vertex: one rotation vector
    Vector3 sharedAxis = Vector3::Zero();
  };
  // One slot's values of vertex i from a Rest or Rigid rule.
  void evaluateSlot(const SlotRule& rule, int i, Eigen::Quaterniond& rotation, Matrix3& frame, RowVectors3& normals,
                    Matrix3& fit) const;
  // What the fit of a Fitted slot of vertex i reads, from `positions` (the
  // job's outputs are left to the caller; fitRotations fits it).
  void sampleSlot(const RowVectors3& positions, int i, RotationFitJob& job) const;
  // This refresh's values of count (≤ kPrepareGroup) vertices into d;
  // currentValid[g]: d's t slot of vertices[g] is up to date.
  void prepareGroup(DynamicState& d, const int* vertices, const bool* currentValid, int count,
                    RotationFitStats& counts) const;
  // ω_i, p̈_i (and the t + h slot of a still surface) once the slots are in d.
  void finishVertex(DynamicState& d, int i) const;
  // Prepares the stale vertices among vertexAt(k), k in [0, count); returns how many.
  template <typename VertexAt>
  int prepareEach(int count, const VertexAt& vertexAt, RotationFitStats& total);
  void addCounts(const RotationFitStats& counts);

  const SurfaceTopology* topology_;
  RowVectors3 restPositions_;
  FabricField fabric_;
  double strainTolerance_;
  // dynamic_.maxEdgeStrain is this surface's (not the 0 of a skipped test).
  bool strainMeasured_ = true;
  // Both tiers, the rotation history (U_i at t − h, t, t + h as unit
  // quaternions: warm start and ω), nextNormals (#V by 3, vertex normals at
  // t + h, which become vertexNormals), 1 / ℓ_e² at the last intrinsic build,
  // the largest edge strain, the h of the last refresh (0: none yet) and the
  // count of consecutive refreshes with p(t+h) == p(t): what a step carries
  // to the next, kept in one struct so that snapshots copy it whole.
  DynamicState dynamic_;
  // Preallocated per-step data (no allocation in refreshExtrinsic):
  std::vector<Vector3> restRingEdges_;  // per ring entry: v̄_j − v̄_i (rest shape)
  EdgeFrameNormals restEdgeFrameNormals_;  // #E by 4, see restEdgeFrameNormals()
  RotationFitMethod rotationFitMethod_ = RotationFitMethod::WarmStartedNewton;
  RotationFitStats rotationFitStats_;
  // Lazy per-vertex values: vertex i holds this refresh's values iff
  // preparedAt_[i] == refreshIndex_ (bumped by every refresh that shifts the
  // slots); its t slot is still valid iff preparedAt_[i] == refreshIndex_ − 1.
  VertexRefresh vertexRefresh_ = VertexRefresh::AllVertices;
  std::vector<unsigned> preparedAt_;
  unsigned refreshIndex_ = 1;
  int preparedCount_ = 0;
  SlotRule currentRule_, nextRule_;
  RateRule rates_;
  bool currentEqualsPrevious_ = true, nextEqualsCurrent_ = true;  // p(t) == p(t − h), p(t + h) == p(t)
  RowVectors3 restNormals_;  // the rest shape's vertex normals (SlotKind::Rest)
  // The intrinsic rebuild: mode, the rest wefts as edge combinations, and
  // preallocated marks and index lists of the partial path (see the design
  // note): chosen edges; faces with one (F1), their vertices (V1) and edges;
  // the ring faces of V1 (F2) and edges at V1; the vertices of F2 (V2) and
  // their ring faces (F3).
  void refreshIntrinsicFromPositions(const RowVectors3& positions);
  // Partial and Region in two parts: the edges chosen (false, nothing
  // chosen, when more than kPartialRefreshMaxShare of them would be), then
  // their lengths and what depends on them updated in place.
  bool chooseRefreshedEdges(const RowVectors3& positions);
  void refreshChosenEdges(const RowVectors3& positions);
  double unchosenStrain_ = 0;  // the largest strain among the edges not chosen
  bool lastRefreshPartial_ = false;
  // Region mode: marks (edgeMarks_) the edges of the faces within
  // kRegionRefreshRings rings of regionVertices_, the chosen edges.
  void markRegionEdges();
  std::vector<int> regionVertices_;
  IntrinsicRefresh intrinsicRefresh_ = IntrinsicRefresh::Full;
  Eigen::MatrixX2d faceWeftCoefficients_;
  std::vector<char> edgeMarks_, faceMarks_, vertexMarks_, vertexMarks2_;
  std::vector<int> chosenEdges_, faces1_, vertices1_, edges1_, faces2_, edges2_, vertices2_, faces3_;
  std::vector<int> prepareOrder_;  // prepareVertices' sorted ids (capacity #V)
  int refreshedEdges_ = 0, refreshedFaces_ = 0;
  // The tier the last refreshIntrinsic replaced (undoIntrinsicRefresh). A
  // whole rebuild assigns every field, so it swaps the tier away (no copy) and
  // builds into the buffers of the one before. A partial one changes the
  // values its lists reach and no other: it saves those in `journal` first
  // (forEachRefreshedValue's order; capacity for every value of the tier,
  // reserved when a partial mode is set, so no allocation), and the undo
  // writes them back. Costs one more tier in memory.
  struct KeptIntrinsic {
    IntrinsicGeometry intrinsic;
    Vector inverseBuiltSquaredLengths;
    std::vector<double> journal;
    bool journaled = false;  // the last refresh was partial: undo from the journal
    int rebuildCount = 0;    // the tier's count before a journaled refresh
    double maxEdgeStrain = 0;
    bool strainMeasured = false;
    bool valid = false;
  } kept_;
  // Every value a partial refresh may write, in one fixed order: part 0 the
  // chosen edges' lengths and 1 / ℓ̂² (written before the lists are made),
  // part 1 what the lists reach (the blocks and entries of F1, V1, F2, E1, E2
  // and the operators' columns of V1 and V2). `at` gets each value.
  template <class At>
  void forEachRefreshedValue(int part, const At& at);
  // Where each face's block lies in the operators' values (oneRingFaceEntries):
  // a whole rebuild after the first refills the two operators in place, a
  // partial one re-assembles its entries at their positions. Made at the
  // second build, by prepareWholeRebuilds or when a partial mode is set, so a
  // mesh that never deforms does not hold it.
  OneRingEntries faceEntries_;
};

}  // namespace blot::stain
