#pragma once
/// Intrinsic geometry: everything computed from edge lengths alone, so it is
/// unchanged by rigid or isometric motion. All angles in radians, lengths in
/// metres, areas in square metres.
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>

namespace blot::stain {

/// #E edge lengths from positions (#V by 3).
Vector edgeLengths(const SurfaceTopology& topology, const RowVectors3& vertexPositions);

/// #F by 3 interior angles; entry (f, k) is the angle at vertex faces(f, k),
/// θ = atan2(4A, b² + c² − a²): law of cosines for the cosine, stable Heron
/// for the sine, accurate to a few ulps even for needle and cap triangles.
Eigen::MatrixX3d faceCornerAngles(const SurfaceTopology& topology, const Vector& edgeLengths);

/// #F triangle areas from edge lengths (Heron, in the numerically stable
/// sorted-sides form).
Vector faceAreas(const SurfaceTopology& topology, const Vector& edgeLengths);

/// #E cotan weights w_ij = ½ (cot α_ij + cot β_ij), α, β the angles opposite the
/// edge (one term on boundary edges). Positive for Delaunay edges; the paper's
/// eq. (7) writes the Laplacian entry as −w_ij with this w.
Vector edgeCotanWeights(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles);

/// #V lumped (barycentric) mass: one third of the one-ring area.
Vector vertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas);

/// #V sum of corner angles at each vertex (γ_i); 2π − γ_i is the angle defect
/// at interior vertices.
Vector vertexAngleSums(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles);

}  // namespace blot::stain
