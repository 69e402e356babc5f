// Intrinsic geometry from edge lengths.
//
// Design note: docs/design-notes.md, "stain/src/geometry/intrinsic_geometry.cpp".
#include <blot/stain/geometry/intrinsic_geometry.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace blot::stain {
namespace {

// Kahan's stable Heron. Sides may come in any order; a triangle that violates
// the triangle inequality by rounding gets area 0.
double stableHeronArea(double a, double b, double c) {
  if (a < b) std::swap(a, b);
  if (b < c) std::swap(b, c);
  if (a < b) std::swap(a, b);
  const double p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
  return 0.25 * std::sqrt(std::max(p, 0.0));
}

}  // namespace

Vector edgeLengths(const SurfaceTopology& topology, const RowVectors3& vertexPositions) {
  const Eigen::MatrixX2i& ev = topology.edgeVertices();
  Vector lengths(topology.edgeCount());
  for (int e = 0; e < topology.edgeCount(); ++e) {
    lengths(e) = (vertexPositions.row(ev(e, 1)) - vertexPositions.row(ev(e, 0))).norm();
  }
  return lengths;
}

Eigen::MatrixX3d faceCornerAngles(const SurfaceTopology& topology, const Vector& edgeLengths) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  Eigen::MatrixX3d angles(topology.faceCount(), 3);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const double l0 = edgeLengths(fe(f, 0)), l1 = edgeLengths(fe(f, 1)), l2 = edgeLengths(fe(f, 2));
    const double fourArea = 4.0 * stableHeronArea(l0, l1, l2);
    // Corner k: adjacent edges faceEdges(f, k) and faceEdges(f, k + 2),
    // opposite edge faceEdges(f, k + 1).
    const double l[3] = {l0, l1, l2};
    for (int k = 0; k < 3; ++k) {
      double b = l[k], c = l[(k + 2) % 3];
      const double a = l[(k + 1) % 3];
      if (b < c) std::swap(b, c);
      angles(f, k) = std::atan2(fourArea, (b - a) * (b + a) + c * c);
    }
  }
  return angles;
}

Vector faceAreas(const SurfaceTopology& topology, const Vector& edgeLengths) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  Vector areas(topology.faceCount());
  for (int f = 0; f < topology.faceCount(); ++f) {
    areas(f) = stableHeronArea(edgeLengths(fe(f, 0)), edgeLengths(fe(f, 1)), edgeLengths(fe(f, 2)));
  }
  return areas;
}

Vector edgeCotanWeights(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  Vector weights = Vector::Zero(topology.edgeCount());
  // Fixed order (face by face) so the two half-contributions always add in
  // the same order: deterministic to the last bit.
  for (int f = 0; f < topology.faceCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      // The angle at corner k is opposite edge faceEdges(f, k + 1).
      const double angle = faceCornerAngles(f, k);
      weights(fe(f, (k + 1) % 3)) += 0.5 * std::cos(angle) / std::sin(angle);
    }
  }
  return weights;
}

Vector vertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas) {
  const Triangles& faces = topology.faces();
  Vector dual = Vector::Zero(topology.vertexCount());
  for (int f = 0; f < topology.faceCount(); ++f) {
    const double third = faceAreas(f) / 3.0;
    for (int k = 0; k < 3; ++k) dual(faces(f, k)) += third;
  }
  return dual;
}

Vector vertexAngleSums(const SurfaceTopology& topology, const Eigen::MatrixX3d& faceCornerAngles) {
  const Triangles& faces = topology.faces();
  Vector sums = Vector::Zero(topology.vertexCount());
  for (int f = 0; f < topology.faceCount(); ++f) {
    for (int k = 0; k < 3; ++k) sums(faces(f, k)) += faceCornerAngles(f, k);
  }
  return sums;
}

}  // namespace blot::stain
