#pragma once
/// Stage "advect density" (paper sec. 3.1): finite-volume upwind advection of
/// free solvent and solute with cotan-weighted fluxes, sub-stepped so that no
/// vertex gives away more than it holds.
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/stages/vertex_visits.h>

#include <vector>

namespace blot::stain {

/// Work arrays, sized once by resize() (no allocation per step). Per-vertex
/// arrays are indexed by vertex id and valid only on the step's active set.
struct DensityAdvectionScratch {
  /// The vertices this step touches: the wet ones, then ring by ring as many
  /// rings as there are sub-steps (liquid moves at most one ring per sub-step);
  /// all vertices when the wet set is empty or covers half the mesh.
  std::vector<int> activeVertices;
  std::vector<char> activeMarks;  ///< #V, 1 on the active set during a call, 0 otherwise
  /// #V by 3, row-major (one cache line per vertex in the ring gathers):
  /// F_i u_i in world coordinates (m/s), and the positions at t (m).
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> vertexVelocities, vertexPositions;
  /// Per ring entry (2 #E, SurfaceTopology::ringNeighbors order) of vertex i,
  /// neighbour j: (u_ij · e_ij) max(w_ij, 0), the volume rate from i to j per
  /// unit density (m²/s); exactly minus the entry of j's ring for i.
  Vector ringSpeeds;
  Vector outflowRates;  ///< #V: Σ of the positive ringSpeeds of the vertex (m²/s)
  Vector keptFractions; ///< #V: share of its mass a vertex keeps per sub-step
  Vector givingRatios;  ///< #V: share given per unit outgoing speed per sub-step (s/m²)
  /// Per ring entry: share of the neighbour's mass flowing into the ring's
  /// vertex per sub-step.
  Vector ringInflowShares;
  Vector massSolvent, massSolute;  ///< #V (kg)
  Vector nextMassSolvent, nextMassSolute;  ///< #V (kg), sub-step double buffer
  /// Deforming surface: the edges between active vertices and their
  /// dual-edge normals at t (#E by 3, row-major; valid on activeEdges during
  /// a call), and the faces of those edges with their unit normals and
  /// centroids (#F by 3): each computed once per call, where every ring
  /// entry used to recompute its dual edge and both of its faces.
  std::vector<int> activeEdges, activeFaces;
  std::vector<char> edgeMarks, faceMarks;  ///< #E, #F: 1 on the lists during a call, 0 otherwise
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> edgeDualNormals, faceUnitNormals, faceCentroids;
  /// Allocates every array (call at build time; no allocation per step).
  void resize(int vertexCount, int edgeCount, int faceCount);
};

struct DensityAdvectionReport {
  int substeps = 0;
  double maxCourant = 0;  ///< largest h · outflow / A over wet vertices, before sub-stepping
  /// Vertices whose outflow had to be limited to what they hold (the sub-step
  /// cap was hit, or a dry vertex receiving mass had a larger Courant number).
  int limitedVertices = 0;
  int activeVertices = 0;  ///< vertices the step worked on (wet set and its halo)
};

/// F_ij = σ↑ (u_ij · e_ij) w_ij with u_ij = ½(F_i u_i + F_j u_j) in 3D (frames at
/// t), σ↑ the upwind density; σ_i -= h/A_i Σ_j F_ij. The step is split into
/// n = ceil(max_i h·outflow_i/A_i) sub-steps over wet vertices (capped by
/// ctx.maxAdvectionSubsteps; a vertex whose sub-step Courant number still
/// exceeds 1 gives exactly what it holds), so mass is conserved exactly
/// (fluxes are antisymmetric) and positivity holds. No transfer through the
/// boundary holds by construction: fluxes cross only dual edges, which all lie
/// inside the surface. Boundary edges do carry flux (their dual edge runs from
/// the edge midpoint to the face's circumcentre, inside the face): it moves
/// mass along the boundary, between two boundary cells, never out of the mesh.
/// Negative cotan weights are clamped to 0 for the flux (an upwind flux
/// against the flow would be anti-diffusive); documented in docs/transport.md.
/// `wet` (empty = all) selects the vertices whose Courant number sets n, and
/// the work is restricted to the wet set and its n-ring halo (liquid cannot
/// move further in n sub-steps); densities outside it are left untouched.
/// restEdgeFrameNormals (SurfaceGeometry::restEdgeFrameNormals, optional): used
/// instead of the positions' dual normals and frames when extrinsic.rigid.
/// reach (optional, #V, nonzero = inside): the rings stop at its edge, so no
/// mass enters a vertex outside it (the liquid band's reach set; mass stays
/// exact, edges leaving it are closed). among (optional): the vertices
/// searched for wet ones instead of all #V, a superset of them listing the
/// wet ones in index order (vertex_visits.h; the band's vertices).
DensityAdvectionReport advectDensities(const StepContext& ctx, const SurfaceTopology& topology,
                                       const IntrinsicGeometry& intrinsic,
                                       const ExtrinsicGeometry& extrinsic, const std::vector<char>& wet,
                                       DensityAdvectionScratch& scratch, StainState& state,
                                       const EdgeFrameNormals* restEdgeFrameNormals = nullptr,
                                       const std::vector<char>* reach = nullptr,
                                       const std::vector<int>* among = nullptr);

}  // namespace blot::stain
