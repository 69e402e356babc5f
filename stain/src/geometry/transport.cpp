// Discrete parallel transport: geodesic polar maps, edge and face transport
// angles (paper sec. 3.1, eq. 6).
//
// Design note.
//  - Polar map: α_ij = s_i Σ (corner angles at i between the reference edge and
//    edge ij, counter-clockwise), with s_i = 2π/γ_i at interior vertices and
//    s_i = 1 at boundary vertices. The paper rescales every fan to 2π; a
//    boundary fan has no such target (rescaling it to π rotates vectors at every
//    corner of a flat sheet: a flat 41×41 grid's connection Laplacian then has
//    smallest eigenvalue 0.38 instead of 0 with our per-triangle assembly
//    (operators_test), 1.02 with the edge-wise form; DESIGN.md quotes 0.99), so
//    boundary fans keep their true angles and a flat sheet, corners included,
//    has exactly trivial transport.
//  - Edge transport θ_ij = α_ij − α_ji + π carries j's frame into i's:
//    a vector along j→i has angle α_ji at j and α_ij + π at i.
//  - Face transport φ(f, k): rotation from the frame of corner vertex v_k into
//    face f's frame (x along v0→v1, y = n × x). Each edge of f at v_k gives an
//    estimate (angle of the edge in the face) − (its α); the two differ by
//    c_k (1 − s_k), zero where the polar map is unscaled, so we take their mean,
//    written in closed form as (first estimate) + c_k (1 − s_k) / 2 so that no
//    angle wrapping can split the average. Face-frame edge angles come from
//    the 2D layout p0 = 0, p1 on +x, p2 above: at v0 the edge to v1 has angle 0,
//    at v1 the edge to v2 has angle π − c1, at v2 the edge to v0 has angle π + c0.
//    Going through the face, vertex l → k transport is φ_l − φ_k
//    = θ_kl − ½ (c_k (1 − s_k) + c_l (1 − s_l)): eq. 6 up to half of the
//    rescaling at each end, exactly eq. 6 on flat or boundary vertices.
#include <blot/stain/geometry/transport.h>

#include <cmath>

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;

// Angle in [−π, π].
double wrapAngle(double angle) { return std::remainder(angle, kTwoPi); }

int cornerOf(const Triangles& faces, int f, int v) {
  return faces(f, 0) == v ? 0 : (faces(f, 1) == v ? 1 : 2);
}

}  // namespace

PolarMap geodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles) {
  const Triangles& faces = topology.faces();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  PolarMap map;
  map.ringAngles.resize(static_cast<Eigen::Index>(topology.ringNeighbors().size()));
  map.vertexAngleScales.resize(topology.vertexCount());
  for (int v = 0; v < topology.vertexCount(); ++v) {
    const int begin = offsets[static_cast<size_t>(v)], end = offsets[static_cast<size_t>(v) + 1];
    // Unscaled cumulative angles; entry m + 1 = entry m + corner of ring face m.
    double cumulative = 0.0;
    for (int m = begin; m < end; ++m) {
      map.ringAngles(m) = cumulative;
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f >= 0) cumulative += faceCornerAngles(f, cornerOf(faces, f, v));
    }
    const bool boundary = topology.vertexIsBoundary()[static_cast<size_t>(v)] != 0;
    const double scale = boundary ? 1.0 : kTwoPi / cumulative;
    map.vertexAngleScales(v) = scale;
    if (!boundary) map.ringAngles.segment(begin, end - begin) *= scale;
  }
  return map;
}

Vector edgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap) {
  const Eigen::MatrixX2i& ev = topology.edgeVertices();
  const std::vector<int>& ringEdges = topology.ringEdges();
  // α_ij (angle of the edge at its lower vertex) and α_ji (at its upper vertex).
  Vector alphaLow(topology.edgeCount()), alphaHigh(topology.edgeCount());
  for (int v = 0; v < topology.vertexCount(); ++v) {
    const int begin = topology.ringOffsets()[static_cast<size_t>(v)];
    const int end = topology.ringOffsets()[static_cast<size_t>(v) + 1];
    for (int m = begin; m < end; ++m) {
      const int e = ringEdges[static_cast<size_t>(m)];
      (ev(e, 0) == v ? alphaLow : alphaHigh)(e) = polarMap.ringAngles(m);
    }
  }
  Vector theta(topology.edgeCount());
  for (int e = 0; e < topology.edgeCount(); ++e) {
    theta(e) = wrapAngle(alphaLow(e) - alphaHigh(e) + kPi);
  }
  return theta;
}

Eigen::MatrixX3d faceTransportAngles(const SurfaceTopology& topology,
                                     const Eigen::MatrixX3d& faceCornerAngles,
                                     const PolarMap& polarMap) {
  const Triangles& faces = topology.faces();
  const std::vector<int>& ringFaces = topology.ringFaces();
  Eigen::MatrixX3d phi(topology.faceCount(), 3);
  for (int v = 0; v < topology.vertexCount(); ++v) {
    const int begin = topology.ringOffsets()[static_cast<size_t>(v)];
    const int end = topology.ringOffsets()[static_cast<size_t>(v) + 1];
    const double scale = polarMap.vertexAngleScales(v);
    for (int m = begin; m < end; ++m) {
      // Ring face m lies between neighbour m (= v_{k+1} in the face) and
      // neighbour m + 1 (= v_{k+2}), counter-clockwise.
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      const int k = cornerOf(faces, f, v);
      const double corner = faceCornerAngles(f, k);
      double faceAngle = 0.0;  // angle of edge v_k -> v_{k+1} in the face frame
      if (k == 1) faceAngle = kPi - faceCornerAngles(f, 1);
      if (k == 2) faceAngle = kPi + faceCornerAngles(f, 0);
      const double firstEstimate = faceAngle - polarMap.ringAngles(m);
      phi(f, k) = wrapAngle(firstEstimate + 0.5 * corner * (1.0 - scale));
    }
  }
  return phi;
}

}  // namespace blot::stain
