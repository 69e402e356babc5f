#pragma once
/// Stage "advect velocity" (paper sec. 3.1): semi-Lagrangian advection of the
/// tangent velocity in the flattened one-ring, walking across the triangle
/// strip when the foot point leaves the ring (no time-step limit).
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/stages/vertex_visits.h>

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
  /// #H, half-edge h = 3f + k from a = v_k to b = v_{k+1}: (c − a)/(b − a) for
  /// the apex c = v_{k+2} of face f laid out flat, i.e. (ℓ_ca/ℓ_ab) exp(i γ_a).
  ComplexVector halfedgeApexRatios;
  /// #H: exp(iφ(f, k)), vertex faces(f, k)'s frame -> face f's frame.
  ComplexVector faceFrameRotations;
  /// IntrinsicGeometry::rebuildCount the tables were built from (−1: never).
  int preparedRebuildCount = -1;

  void resize(int vertexCount) {
    advected.resize(vertexCount);
    footVertices.resize(vertexCount, 3);
    footWeights.resize(vertexCount, 3);
  }
  /// Sizes everything and fills the tables from `geometry` (allocates: call at
  /// build time and after each intrinsic rebuild). advectVelocity calls it
  /// itself when preparedRebuildCount differs from geometry.rebuildCount, so
  /// the tables are never stale; use one scratch per geometry.
  void prepare(const SurfaceTopology& topology, const IntrinsicGeometry& geometry);
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
