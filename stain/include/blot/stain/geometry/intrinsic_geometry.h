#pragma once
/// Intrinsic geometry: everything computed from edge lengths alone, so it is
/// unchanged by rigid or isometric motion. All angles in radians, lengths in
/// metres, areas in square metres.
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>

namespace blot::stain {

/// Area of a triangle with sides a, b, c (m, any order): Kahan's stable Heron;
/// 0 for sides that violate the triangle inequality by rounding.
double triangleArea(double a, double b, double c);

/// #E edge lengths from positions (#V by 3).
Vector edgeLengths(const SurfaceTopology& topology, const RowVectors3& vertexPositions);
/// The same into `lengths` (resized; no allocation when it already has #E
/// entries). The whole-mesh functions below with an output argument are each
/// their twin's values into existing storage: what a metric rebuild calls.
void edgeLengths(const SurfaceTopology& topology, const RowVectors3& vertexPositions, Vector& lengths);

/// #F by 3 interior angles; entry (f, k) is the angle at vertex faces(f, k),
/// θ = atan2(4A, b² + c² − a²): law of cosines for the cosine, stable Heron
/// for the sine, accurate to a few ulps even for needle and cap triangles.
Eigen::MatrixX3d faceCornerAngles(const SurfaceTopology& topology, const Vector& edgeLengths);

/// #F triangle areas from edge lengths (Heron, in the numerically stable
/// sorted-sides form).
Vector faceAreas(const SurfaceTopology& topology, const Vector& edgeLengths);

/// #E cotan weights w_ij = ½ (cot α_ij + cot β_ij), α, β the angles opposite the
/// edge (one term on boundary edges). Positive for Delaunay edges; the paper's
/// eq. (7) writes the Laplacian entry as −w_ij with this w. From the lengths
/// and the faceAreas of those lengths: cot θ = (b² + c² − a²) / 4A, no
/// trigonometric call (the angles' own atan2 takes the same two numbers).
Vector edgeCotanWeights(const SurfaceTopology& topology, const Vector& edgeLengths, const Vector& faceAreas);

/// faceCornerAngles, faceAreas and edgeCotanWeights above in one pass over
/// the faces, bitwise the same values, into the given arrays (resized; no
/// allocation when they already have the mesh's sizes). What a metric
/// rebuild calls.
void faceAnglesAreasAndCotanWeights(const SurfaceTopology& topology, const Vector& edgeLengths,
                                    Eigen::MatrixX3d& faceCornerAngles, Vector& faceAreas,
                                    Vector& edgeCotanWeights);

/// #V lumped (barycentric) mass: one third of the one-ring area.
Vector vertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas);
void vertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas, Vector& vertexDualAreas);

/// Partial updates (SurfaceGeometry's partial intrinsic rebuild): each writes,
/// for the listed elements only (ids ascending, no repeats), bitwise the
/// values the whole-mesh function above computes from the same inputs, and
/// leaves the other entries alone. Allocate nothing.
/// Corner angles and area of faces[0, count) from edgeLengths.
void updateFaceAnglesAndAreas(const SurfaceTopology& topology, const Vector& edgeLengths, const int* faces,
                              int count, Eigen::MatrixX3d& faceCornerAngles, Vector& faceAreas);
/// Cotan weights of edges[0, count).
void updateEdgeCotanWeights(const SurfaceTopology& topology, const Vector& edgeLengths, const Vector& faceAreas,
                            const int* edges, int count, Vector& edgeCotanWeights);
/// Dual areas of vertices[0, count).
void updateVertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas, const int* vertices, int count,
                           Vector& vertexDualAreas);

/// #V sum of corner angles at each vertex (γ_i); 2π − γ_i is the angle defect
/// at interior vertices.
Vector vertexAngleSums(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles);

}  // namespace blot::stain
