// Discrete parallel transport: geodesic polar maps, edge and face transport
// angles (paper sec. 3.1, eq. 6).
//
// Design note: docs/design-notes.md, "stain/src/geometry/transport.cpp".
#include <blot/stain/geometry/transport.h>

#include "numerics/vector_trig.h"

#include <algorithm>
#include <cmath>

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;

}  // namespace

void fillRingTransports(const SurfaceTopology& topology, const Vector& edgeTransportAngles, int v, Complex* out) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const std::vector<int>& ringEdges = topology.ringEdges();
  constexpr int kBlock = 16;  // a ring of any valence, a block of entries at a time
  double theta[kBlock];
  const int begin = offsets[static_cast<size_t>(v)], end = offsets[static_cast<size_t>(v) + 1];
  for (int start = begin; start < end; start += kBlock) {
    const int size = std::min(kBlock, end - start);
    for (int b = 0; b < size; ++b) {
      const size_t m = static_cast<size_t>(start + b);
      const double angle = edgeTransportAngles(ringEdges[m]);
      theta[b] = v < neighbors[m] ? angle : -angle;
    }
    trig::unitPhases(theta, out + start, size);
  }
}

// std::remainder's result is exact; wrapAngle (the header) calls it only
// outside its fast range, where its ~50 ns call (10 % of a metric rebuild's
// samples when every angle took it) is rare.
double wrapAngleByRemainder(double angle) { return std::remainder(angle, kTwoPi); }

PolarMap geodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles) {
  PolarMap map;
  geodesicPolarMap(topology, faceCornerAngles, map);
  return map;
}

void geodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles, PolarMap& map) {
  map.ringAngles.resize(static_cast<Eigen::Index>(topology.ringNeighbors().size()));
  map.vertexAngleScales.resize(topology.vertexCount());
  for (int v = 0; v < topology.vertexCount(); ++v) updateGeodesicPolarMap(topology, faceCornerAngles, &v, 1, map);
}

void updateGeodesicPolarMap(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles,
                            const int* vertices, int count, PolarMap& map) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const std::vector<signed char>& ringCorners = topology.ringCorners();
  for (int n = 0; n < count; ++n) {
    const int v = vertices[n];
    const int begin = offsets[static_cast<size_t>(v)], end = offsets[static_cast<size_t>(v) + 1];
    // Unscaled cumulative angles; entry m + 1 = entry m + corner of ring face m.
    double cumulative = 0.0;
    for (int m = begin; m < end; ++m) {
      map.ringAngles(m) = cumulative;
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f >= 0) cumulative += faceCornerAngles(f, ringCorners[static_cast<size_t>(m)]);
    }
    const bool boundary = topology.vertexIsBoundary()[static_cast<size_t>(v)] != 0;
    const double scale = boundary ? 1.0 : kTwoPi / cumulative;
    map.vertexAngleScales(v) = scale;
    if (!boundary) map.ringAngles.segment(begin, end - begin) *= scale;
  }
}

Vector edgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap) {
  Vector theta;
  edgeTransportAngles(topology, polarMap, theta);
  return theta;
}

void edgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap, Vector& theta) {
  // updateEdgeTransportAngles over every edge, without its search of two
  // rings per edge: each ring entry is an edge seen from one end, so one pass
  // over the entries writes α at the lower end, a second one subtracts α at
  // the upper end (the same expression, the same bits).
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const std::vector<int>& ringEdges = topology.ringEdges();
  const int n = topology.vertexCount();
  theta.resize(topology.edgeCount());
  for (int v = 0; v < n; ++v)
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m)
      if (v < neighbors[static_cast<size_t>(m)]) theta(ringEdges[static_cast<size_t>(m)]) = polarMap.ringAngles(m);
  for (int v = 0; v < n; ++v)
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m)
      if (v > neighbors[static_cast<size_t>(m)]) {
        double& t = theta(ringEdges[static_cast<size_t>(m)]);
        t = wrapAngle(t - polarMap.ringAngles(m) + kPi);
      }
}

void updateEdgeTransportAngles(const SurfaceTopology& topology, const PolarMap& polarMap, const int* edges, int count,
                               Vector& theta) {
  const Eigen::MatrixX2i& ev = topology.edgeVertices();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringEdges = topology.ringEdges();
  // α of edge e in the polar map of its end v (the ring entry of e at v).
  const auto alpha = [&](int v, int e) {
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m)
      if (ringEdges[static_cast<size_t>(m)] == e) return polarMap.ringAngles(m);
    return 0.0;  // unreachable: e is in the ring of both its ends
  };
  for (int n = 0; n < count; ++n) {
    const int e = edges[n];
    // α_ij (angle of the edge at its lower vertex) and α_ji (at its upper vertex).
    theta(e) = wrapAngle(alpha(ev(e, 0), e) - alpha(ev(e, 1), e) + kPi);
  }
}

Eigen::MatrixX3d faceTransportAngles(const SurfaceTopology& topology,
                                     const Eigen::MatrixX3d& faceCornerAngles,
                                     const PolarMap& polarMap) {
  Eigen::MatrixX3d phi;
  faceTransportAngles(topology, faceCornerAngles, polarMap, phi);
  return phi;
}

void faceTransportAngles(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles,
                         const PolarMap& polarMap, Eigen::MatrixX3d& phi) {
  phi.resize(topology.faceCount(), 3);
  for (int v = 0; v < topology.vertexCount(); ++v)
    updateFaceTransportAngles(topology, faceCornerAngles, polarMap, &v, 1, phi);
}

void updateFaceTransportAngles(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles,
                               const PolarMap& polarMap, const int* vertices, int count, Eigen::MatrixX3d& phi) {
  const std::vector<int>& ringFaces = topology.ringFaces();
  const std::vector<signed char>& ringCorners = topology.ringCorners();
  for (int n = 0; n < count; ++n) {
    const int v = vertices[n];
    const int begin = topology.ringOffsets()[static_cast<size_t>(v)];
    const int end = topology.ringOffsets()[static_cast<size_t>(v) + 1];
    const double scale = polarMap.vertexAngleScales(v);
    for (int m = begin; m < end; ++m) {
      // Ring face m lies between neighbour m (= v_{k+1} in the face) and
      // neighbour m + 1 (= v_{k+2}), counter-clockwise.
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      const int k = ringCorners[static_cast<size_t>(m)];
      const double corner = faceCornerAngles(f, k);
      double faceAngle = 0.0;  // angle of edge v_k -> v_{k+1} in the face frame
      if (k == 1) faceAngle = kPi - faceCornerAngles(f, 1);
      if (k == 2) faceAngle = kPi + faceCornerAngles(f, 0);
      const double firstEstimate = faceAngle - polarMap.ringAngles(m);
      phi(f, k) = wrapAngle(firstEstimate + 0.5 * corner * (1.0 - scale));
    }
  }
}

}  // namespace blot::stain
