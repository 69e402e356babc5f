#pragma once
/// Discrete parallel transport between vertex tangent frames (paper sec. 3.1).
///
/// Geodesic polar map: around vertex i the one-ring edges get angles α_ij,
/// the cumulative corner angles counter-clockwise from the reference edge
/// (first ring neighbour, α = 0), scaled by 2π/γ_i at interior vertices. At
/// boundary vertices the true angles are kept (scale 1): rescaling a boundary
/// fan to π would rotate vectors spuriously at every corner of a flat sheet.
///
/// Transport j -> i along edge ij is the rotation by θ_ij = α_ij − α_ji + π
/// (eq. 6): u_i ≈ R(θ_ij) u_j, or in complex form u_i ≈ exp(iθ_ij) u_j, where a
/// tangent vector (x, y) in a vertex frame is the complex number x + iy.
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>

#include <cmath>

namespace blot::stain {

struct PolarMap {
  /// Per ring entry (aligned with SurfaceTopology::ringNeighbors): α_ij in
  /// [0, 2π) (interior) or [0, γ_i] (boundary).
  Vector ringAngles;
  /// #V: 2π / γ_i at interior vertices, 1 at boundary vertices.
  Vector vertexAngleScales;
};

PolarMap geodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles);
/// The same into `polarMap` (resized; no allocation at the mesh's sizes). So
/// too the whole-mesh transport angles below with an output argument: what a
/// metric rebuild calls.
void geodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles, PolarMap& polarMap);

/// std::remainder(angle, 2π): wrapAngle's path outside its fast range.
double wrapAngleByRemainder(double angle);

/// angle wrapped to [−π, π]: bitwise std::remainder(angle, 2π), without its
/// call for |angle| < 9.4 (the transport angles' range). Inline: the library
/// is built position-independent, so a function it exports is not inlined
/// into its own file's callers (a call was 5 % of a metric rebuild).
/// |angle| ≤ π is returned as it is (quotient ≤ 1/2, rounded to the even 0);
/// up to 9.4 < 3π the quotient rounds to ±1 and angle ∓ 2π is exact
/// (Sterbenz: 2π/2 ≤ |angle| ≤ 2 · 2π); a zero result takes the sign of
/// angle, as std::remainder's does (−2π + 2π is +0 in IEEE arithmetic, the
/// remainder −0). NaN and the rest go to std::remainder.
inline double wrapAngle(double angle) {
  constexpr double kHalfTurn = 3.14159265358979323846, kTurn = 2.0 * kHalfTurn;
  if (angle >= -kHalfTurn && angle <= kHalfTurn) return angle;
  if (angle > kHalfTurn && angle < 9.4) return angle - kTurn;
  if (angle < -kHalfTurn && angle > -9.4) {
    const double wrapped = angle + kTurn;
    return wrapped != 0.0 ? wrapped : -0.0;
  }
  return wrapAngleByRemainder(angle);
}

/// #E transport angles θ_ij for each edge (i, j) = edgeVertices row, i < j:
/// the rotation carrying vectors in j's frame into i's frame. θ_ji = −θ_ij.
Vector edgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap);
void edgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap, Vector& edgeTransportAngles);

/// exp(iθ_vj) for each ring entry m of vertex v, into out[m] (out indexed
/// like topology.ringNeighbors()): j the entry's neighbour across edge e
/// carries j's frame into v's (θ stored for the lower end, negated from the
/// upper one). The one formula the band's and the velocity advection's ring
/// tables fill from; the ring's sines and cosines are one vector batch
/// (stain/src/numerics/vector_trig.h).
void fillRingTransports(const SurfaceTopology& topology, const Vector& edgeTransportAngles, int v, Complex* out);

/// #F by 3 rotation angles φ(f, k) carrying a vector from the frame of vertex
/// faces(f, k) into face f's own frame (x along the half-edge faces(f,0) ->
/// faces(f,1), y = n × x). Each is the average, over the two edges of f at that
/// vertex, of (angle of the edge in the face) − (α of the edge in the polar
/// map), so it is exact where the polar map is unscaled (flat or boundary).
/// Used to assemble the connection Laplacian per triangle.
Eigen::MatrixX3d faceTransportAngles(const SurfaceTopology& topology,
                                     const Eigen::MatrixX3d& faceCornerAngles,
                                     const PolarMap& polarMap);
void faceTransportAngles(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles,
                         const PolarMap& polarMap, Eigen::MatrixX3d& faceTransportAngles);

/// Partial updates (SurfaceGeometry's partial intrinsic rebuild): for the
/// listed elements only, bitwise what the whole-mesh functions above give from
/// the same inputs; other entries are left alone. Allocate nothing.
/// The polar map (ring angles and scale) of vertices[0, count).
void updateGeodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles,
                            const int* vertices, int count, PolarMap& polarMap);
/// θ of edges[0, count).
void updateEdgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap, const int* edges, int count,
                               Vector& edgeTransportAngles);
/// φ(f, k) of every ring face f of vertices[0, count), at the corner k of that vertex.
void updateFaceTransportAngles(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles,
                               const PolarMap& polarMap, const int* vertices, int count,
                               Eigen::MatrixX3d& faceTransportAngles);

}  // namespace blot::stain
