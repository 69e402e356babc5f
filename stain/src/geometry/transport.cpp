// Discrete parallel transport: geodesic polar maps, edge and face transport
// angles (paper sec. 3.1, eq. 6).
//
// Design note: docs/design-notes.md, "stain/src/geometry/transport.cpp".
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
