#pragma once
/// The liquid band (DESIGN.md, docs/transport.md "The liquid band"): the one
/// set of vertices a stain step works on. Level 0 is the wet set (vertices
/// holding liquid); level k the k-th ring around it. The band reaches as far
/// as the step's velocity advection can look (foot points of the vertices
/// liquid can reach), and on it the velocity is defined everywhere: outside
/// the wet set it is extended from the wet side, so no stage ever reads a
/// dry vertex's stale u as "liquid at rest".
#include <blot/stain/stain_state.h>
#include <blot/stain/geometry/surface_geometry.h>

#include <algorithm>
#include <vector>

namespace blot::stain {

/// The band of one step and its scratch, sized once (LiquidBand::resize);
/// buildLiquidBand refills it without allocating.
struct LiquidBand {
  /// Band vertices, wet ones first (index order), then ring by ring (each
  /// ring in discovery order: deterministic).
  std::vector<int> vertices;
  /// ringEnds[k]: end of level k in `vertices` (level 0 = wet); size rings + 1.
  std::vector<int> ringEnds;
  /// #V: level of each vertex in the band, −1 outside.
  std::vector<int> levels;
  /// Mask value of a vertex holding liquid (the interaction's "wet front"
  /// test reads it); other band vertices are 1, vertices outside 0.
  static constexpr char kHoldsLiquid = 2;
  /// #V masks for the stages (kHoldsLiquid on the wet set, 1 elsewhere inside, 0 outside):
  std::vector<char> wetMask;        ///< level 0: holds liquid (densities are advected from here)
  std::vector<char> haloMask;       ///< levels 0..1: wet and the one-ring halo
  std::vector<char> reachMask;      ///< levels 0..reachRings: where the advection can move liquid this
                                    ///< step (the density diffusion can carry traces further)
  std::vector<char> bandMask;       ///< every level: forces act here, u is defined here
  std::vector<char> diffusionMask;  ///< band vertices whose neighbours are all in the band (the
                                    ///< velocity solve's rows; the others are its boundary data)
  int rings = 0;       ///< levels beyond the wet set (outermost level)
  int reachRings = 0;  ///< deepest level of the reach set (R = ceil(h U / ℓ) + 1 on equal edges ℓ,
                       ///< fewer where the advection's sub-steps cannot get that far)
  int haloCount = 0;   ///< vertices at level 1
  int interiorCount = 0;  ///< vertices of diffusionMask (the velocity solve's rows)
  /// Times growLiquidBand grew the rings again this step: U grew past the
  /// label a "stop here" was decided on (0 on most steps).
  int regrowths = 0;
  double speedBound = 0;  ///< U (m/s): bound on |u| over the band after this step's forces
  /// d = h U was below the star radius of every reach vertex, so every foot
  /// point lies in its vertex's star, and the band is the reach set and its
  /// one ring (growLiquidBand, "Foot points in their stars").
  bool footInStar = false;
  /// #V extension weights: liquid mass A(σ_f + σ_s) on wet vertices, and on
  /// an extended vertex the mean weight of the neighbours it was built from.
  Vector weights;
  /// Per ring entry (SurfaceTopology::ringNeighbors) of vertex i, neighbour j:
  /// exp(iθ_ij), carrying j's frame into i's (eq. 6). Duplicates
  /// VelocityAdvectionScratch::ringTransports on purpose: the band is built
  /// before the advection and must not depend on its scratch. Filled per
  /// vertex, when the band first reaches it after a rebuild.
  ComplexVector ringTransports;
  /// #V: the IntrinsicGeometry::rebuildCount vertex i's ringTransports
  /// entries and distances[i].shortestEdge were filled from (−1: not yet).
  std::vector<int> ringRebuildCounts;
  /// Vertices not in the wet set whose free density σ_f + σ_s is > 0 (a
  /// trace below wetThreshold), in index order: no stage works on them;
  /// their frames are prepared only for a reader between steps that asks
  /// (StainSolverDef::framesOnDampVertices: the coupling's free relative
  /// momentum).
  std::vector<int> dampVertices;
  /// Vertices not in the wet set whose absorbed solvent σ_p is > 0 (below
  /// wetThreshold, or a soaked vertex's), in index order: the interaction
  /// dries them wherever they are, so a step that runs it changes them.
  std::vector<int> absorbingVertices;
  /// Soaked vertices, filed apart from the wet set when the liquid's u lives
  /// on the free liquid only (updateWetVertices with soakedApart): σ_p above
  /// wetThreshold and σ_f + σ_s not, liquid the fibres hold, which moves
  /// with the cloth (u = 0). The band does not grow around them: one it
  /// reaches gets u = 0 and extension weight 0 instead of an extended u (the
  /// body forces then act on it as on a wet vertex without free liquid, whose
  /// u they clear); one outside it gets u = 0 (settleSoakedVelocities).
  /// Index order; also in absorbingVertices.
  std::vector<int> soakedVertices;
  std::vector<char> soakedMask;  ///< #V: 1 on soakedVertices (the interaction's wet-front test)
  /// The incremental wet set (updateWetVertices): a superset of the vertices
  /// that are wet, damp or absorbing now, namely those the last scan found
  /// plus every vertex noted as changed since (noteChanged). A vertex outside
  /// it kept the values a scan found neither wet, damp nor absorbing, so it
  /// still is none of them. scanAll: a change the list does not hold (a
  /// whole-mesh write, a write from outside a step): the next update scans
  /// every vertex.
  std::vector<int> candidates;
  std::vector<char> candidateMarks;  ///< #V: 1 on `candidates`
  bool scanAll = true;
  /// Per vertex, m: the shortest edge at it (intrinsic, filled with its
  /// ringTransports), then growLiquidBand's distance labels (valid on band
  /// vertices): the least distance a path from the wet set (the reach set)
  /// covers to reach the vertex, and the least such label among its
  /// neighbours at the level below. One record per vertex: the band's sweep
  /// reads all of a neighbour's at once.
  /// starRadius (m, intrinsic, filled with shortestEdge): the least altitude
  /// from the vertex of its triangles; a path from the vertex shorter than it
  /// stays in the vertex's star.
  struct Distances {
    double shortestEdge = 0, fromWet = 0, fromReach = 0, nearestWet = 0, nearestReach = 0, starRadius = 0;
  };
  std::vector<Distances> distances;  ///< #V

  /// Sizes everything for the mesh (allocates: call at build time). With
  /// ringEntries (SurfaceTopology::ringNeighbors().size()) the ring table
  /// too, written once so that its pages are mapped: the first
  /// growLiquidBand then allocates and faults nothing.
  void resize(int vertexCount, int ringEntries = 0);
  /// Forgets what was computed from the intrinsic tier (call when it is
  /// replaced by a restored snapshot, whose rebuildCount may repeat one).
  void invalidateIntrinsic() {
    std::fill(ringRebuildCounts.begin(), ringRebuildCounts.end(), -1);
  }
  /// Level-0 count (vertices holding liquid).
  int wetCount() const { return ringEnds.empty() ? 0 : ringEnds[0]; }
  int size() const { return static_cast<int>(vertices.size()); }
  /// Vertex v (or `count` vertices) may have changed since the last scan.
  /// Past an eighth of the mesh the sorted visit costs more than the scan: a
  /// list noted sets scanAll once the candidates hold more than #V/8
  /// distinct vertices (the stages note the same band again and again, so
  /// the lengths of the lists are no measure of it).
  void noteChanged(int v) {
    if (candidateMarks[static_cast<size_t>(v)]) return;
    candidateMarks[static_cast<size_t>(v)] = 1;
    candidates.push_back(v);
  }
  void noteChanged(const int* list, int count) {
    for (int k = 0; k < count && !scanAll; ++k) {
      noteChanged(list[k]);
      if (8 * candidates.size() > candidateMarks.size()) scanAll = true;
    }
  }
};

/// What decides the band of a step.
struct LiquidBandInputs {
  double h = 0.01;  ///< time step (s)
  Vector3 gravity = Vector3::Zero();  ///< world gravity acting this step (m/s²; zero when switched off)
  bool useAccelerations = false;      ///< linear inertia acts this step (p̈ enters the speed bound)
  /// Largest kick of the film's potential gradient on the wet set (m/s²,
  /// filmAccelerations; 0 without film pressure), added to every vertex's.
  double filmAcceleration = 0;
  /// Frame velocities enter the extension (the surface moved): the extension
  /// then carries the liquid's world velocity, see extendBandVelocities.
  bool surfaceMoved = false;
  /// Grow the band over the whole connected component (the velocity
  /// diffusion is a whole-mesh direct solve, which reads u everywhere).
  bool coverComponent = false;
};

/// Whether vertex i holds free liquid: σ_f or σ_s above wetThreshold, or
/// σ_f + σ_s > 0 (a trace). Exactly the vertices updateWetVertices files as
/// wet by their free liquid or as damp, so a vertex outside the incremental
/// wet set's candidates (when not scanAll) holds none.
inline bool holdsFreeLiquid(const StainState& state, int i, double wetThreshold) {
  return state.solvent[i] + state.solute[i] > 0 || state.solvent[i] > wetThreshold || state.solute[i] > wetThreshold;
}

/// Level 0 of the band: the vertices holding liquid (σ_f, σ_s or σ_p above
/// wetThreshold), in index order. Resets the previous band (O(previous band)
/// for the masks, O(#V) for the scan). Call after the sources of the step.
/// Also lists the band's dampVertices (same scan). soakedApart: a vertex
/// whose σ_p is above wetThreshold and whose σ_f + σ_s is not is filed under
/// soakedVertices (and absorbingVertices) instead of the wet set.
void markWetVertices(double wetThreshold, const StainState& state, LiquidBand& band, bool soakedApart = false);
/// markWetVertices from the incremental wet set: the same wet set, damp,
/// absorbing and soaked lists, in the same order, scanning only
/// band.candidates (sorted; O(k log k) for k candidates) unless band.scanAll
/// or more than #V/8 candidates, which make it the full scan. Afterwards the
/// candidates are what it found.
void updateWetVertices(double wetThreshold, const StainState& state, LiquidBand& band, bool soakedApart = false);
/// u = 0 on the soaked vertices outside the band (their liquid moves with the
/// cloth); calls changed(i) for each vertex whose u it changed. O(soaked).
template <class Changed>
void settleSoakedVelocities(const LiquidBand& band, StainState& state, const Changed& changed) {
  for (const int i : band.soakedVertices) {
    if (band.levels[static_cast<size_t>(i)] >= 0 || state.velocities[i] == Complex(0.0, 0.0)) continue;
    state.velocities[i] = Complex(0.0, 0.0);
    changed(i);
  }
}

/// Drops every level but the wet set (its masks and levels reset), so that
/// growLiquidBand grows the band again, e.g. over the whole component.
void shrinkBandToWetSet(LiquidBand& band);

/// Grows the band marked by markWetVertices ring by ring and extends the
/// velocity onto it: state.velocities on band vertices outside the wet set
/// are overwritten; wet ones and vertices outside the band are untouched.
///
/// Extent: U = max |u| over the band plus h max |tangential part of g − p̈|
/// (the speed after this step's kick; extended values included, which on a
/// moving surface can exceed the wet ones by the frame velocity's change),
/// and d = h U, the farthest a foot point of the semi-Lagrangian backtrack
/// lies from its vertex. Crossing from a vertex j to its neighbour i is taken
/// to cover at least min(s_j, s_i), s the shortest edge at a vertex (the rule
/// the band had with the mesh's shortest edge ℓ_min, applied where the path
/// goes). fromWet (fromReach) is the least such distance along the levels
/// from the wet set (the reach set), and nearest* the least label among a
/// vertex's neighbours at the level below. A vertex is in the reach set if it
/// is wet or has a neighbour at the level below that is wet or whose
/// nearestWet < d: the liquid can get to that neighbour's star, so to every
/// vertex of a triangle there (liquid is moved only inside the reach set by
/// the density advection, clipped to reachMask). The band grows past a
/// vertex if it is in the reach set or its nearestReach < d: the foot points
/// of reach vertices, d further. On a mesh of equal edges ℓ this is the old
/// rule, levels 0..R in the reach set and 2R rings in the band,
/// R = ceil(d / ℓ) + 1; with unequal edges it is never wider than that rule
/// with ℓ_min, and short edges away from the liquid do not widen it. The
/// speed bound grows ring by ring; a band stopped somewhere the final d
/// would have passed (a rejected label below it) is grown again from the wet
/// set (LiquidBand::regrowths; after two tries it covers the component). coverComponent: the whole
/// component, reach set as above.
///
/// Sub-step rings: the density advection moves liquid one ring a sub-step
/// and takes at most ceil(d · max over the wet set of P_i / A_i) of them
/// (P_i the barycentric dual half-edges around i, from the positions; see
/// the source), so a level past that is out of the reach set whatever the
/// labels say (its label joins the regrowth test like theirs).
///
/// Foot points in their stars: the backtrack from a reach vertex x walks
/// h |u_x| ≤ d from x along the surface, so while d is below the least
/// altitude from x of x's triangles (Distances::starRadius) the foot point
/// lies in x's star, whose corners are x and its neighbours. The band is
/// first grown so, stopping at the reach set's one ring; when the final d is
/// below the least star radius of the reach set (LiquidBand::footInStar),
/// that band is kept: the reach vertices are the velocity solve's rows and
/// their ring its boundary data. Otherwise it is grown again by the labels
/// above from the wet set's speed bound, which is the band without this rule,
/// to the bit (regrowths counts the labels' attempts only). The star attempt
/// is skipped where the wet set's own d already reaches the wet set's least
/// star radius, and abandoned at the first ring whose d reaches the reach
/// set's: d only grows and that radius only shrinks as the band grows.
///
/// Extension (breadth-first, level by level): vertex i at level k gets
///   u_i = Σ_j w_j (e^{iθ_ij} u_j + P_i (v_j − v_i)) / Σ_j w_j
/// over its neighbours j at levels < k, w_j the weights above, e^{iθ_ij} the
/// connection's transport from j's frame into i's, v the surface velocity of
/// the last step (p^t − p^{t−h})/h and P_i the projection on i's tangent axes
/// (F_i^t): the liquid's world velocity V = v + F u is extended, its part
/// relative to the cloth carried by the connection. On a static surface the
/// second term vanishes. state.velocities are read in F^t (after the half
/// frame rotation of the discrete frame change).
///
/// toPrepare: when given (its extrinsic() is `extrinsic`), each new ring's
/// vertices are prepared (SurfaceGeometry::prepareVertices) before their
/// frames and p̈ are read, so a geometry in VertexRefresh::OnDemand computes
/// exactly the band; the wet set must be prepared by the caller.
void growLiquidBand(const LiquidBandInputs& inputs, const SurfaceTopology& topology,
                    const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry& extrinsic, LiquidBand& band,
                    StainState& state, SurfaceGeometry* toPrepare = nullptr);

}  // namespace blot::stain
