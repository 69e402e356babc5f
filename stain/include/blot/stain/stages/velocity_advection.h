#pragma once
/// Stage "advect velocity" (paper sec. 3.1): semi-Lagrangian advection of the
/// tangent velocity in the flattened one-ring, walking across the triangle
/// strip when the foot point leaves the ring (no time-step limit).
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/stages/vertex_visits.h>

#include <algorithm>
#include <vector>

namespace blot::stain {

/// Per vertex, the three vertices and convex weights of a foot point (#V by 3).
using FootVertices = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using FootWeights = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Scratch sized once (no allocation per step), plus unit-complex tables taken
/// from the intrinsic tier so the per-step walk needs no trigonometry.
struct VelocityAdvectionScratch {
  ComplexVector advected;  ///< #V
  /// #V by 3, per vertex advected last: the foot point of its backtrack as
  /// Σ_c footWeights(i, c) · vertex footVertices(i, c) (convex weights; the
  /// vertex itself with weight 1 when it did not move). What the Coriolis
  /// stage interpolates the frame velocity with
  /// (applyFrameVelocityChange in external_forces.h).
  FootVertices footVertices;
  FootWeights footWeights;  ///< #V by 3, see footVertices
  /// Per ring entry (SurfaceTopology::ringNeighbors) of vertex i, neighbour j:
  /// ℓ_ij exp(iα_ij), j's position in i's flattened one-ring (m).
  ComplexVector ringPoints;
  /// Per ring entry: exp(iθ_ij), carrying j's frame into i's (eq. 6).
  ComplexVector ringTransports;
  /// #V: the IntrinsicGeometry::rebuildCount vertex i's ring entries were
  /// filled from (−1: not since the last prepare). A vertex's entries are
  /// filled when it first walks after a rebuild, so a rebuild costs what the
  /// liquid's vertices need, not the whole mesh. (The strip walk's per-face
  /// values, (ℓ_ca/ℓ_ab) exp(iγ_a) and the face frame rotations, are computed
  /// where a walk crosses a face: a few faces per step.)
  std::vector<int> ringRebuildCounts;

  void resize(int vertexCount) {
    advected.resize(vertexCount);
    footVertices.resize(vertexCount, 3);
    footWeights.resize(vertexCount, 3);
  }
  /// Sizes everything for `topology` and marks every vertex's ring entries
  /// unfilled (allocates: call at build time; advectVelocity calls it itself
  /// when the sizes differ). Call invalidate() when the intrinsic tier is
  /// replaced (a restored snapshot): its rebuildCount may repeat a count the
  /// entries were filled from.
  void prepare(const SurfaceTopology& topology);
  void invalidate() { std::fill(ringRebuildCounts.begin(), ringRebuildCounts.end(), -1); }
};

/// Statistics of one advection (for the profile and tests).
struct VelocityAdvectionReport {
  int stripSteps = 0;      ///< triangles crossed beyond the first one-ring, summed
  int boundaryStops = 0;   ///< backtracks stopped at the mesh boundary (free slip)
  int cappedWalks = 0;     ///< backtracks stopped by the 1000-triangle walk cap
};

/// For each wet vertex i: backtrack from i by −h u_i in its flattened one-ring
/// (polar map), continuing straight across neighbouring triangles (unfolded)
/// when the ring is left; at the foot point in triangle (a, b, c) with
/// barycentric λ, the new velocity is Σ λ_k T_k u_k where T_k transports u_k
/// along the walked path into frame i (ring vertices by exp(iθ_ij), vertices
/// further along the strip through their face frame and the unfolding; see the
/// design note in velocity_advection.cpp). At the mesh boundary the path stops
/// where it meets the boundary and the velocity is interpolated there, so the
/// foot point never leaves the mesh (free slip: nothing is reflected or
/// zeroed; a uniform field stays uniform up to the boundary). Walks longer
/// than 1000 triangles stop where they are. Only vertices marked in `wet`
/// (nonzero, or all when empty; the solver passes the liquid band's reach
/// set) are advected; the others keep u. Reads state.velocities,
/// writes them back. `among` (optional): the vertices visited instead of all
/// #V, a superset of those `wet` marks (vertex_visits.h).
VelocityAdvectionReport advectVelocity(const StepContext& ctx, const SurfaceTopology& topology,
                                       const IntrinsicGeometry& geometry, const std::vector<char>& wet,
                                       VelocityAdvectionScratch& scratch, StainState& state,
                                       const std::vector<int>* among = nullptr);

}  // namespace blot::stain
