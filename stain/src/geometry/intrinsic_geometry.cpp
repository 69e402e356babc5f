// Intrinsic geometry from edge lengths.
//
// Design note: docs/design-notes.md, "stain/src/geometry/intrinsic_geometry.cpp".
#include <blot/stain/geometry/intrinsic_geometry.h>

#include "numerics/vector_trig.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

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

// Corner k of a face with edge lengths l: its adjacent edges faceEdges(f, k)
// and faceEdges(f, k + 2), its opposite edge faceEdges(f, k + 1). Returns
// b² + c² − a² = 2bc·cos θ_k in the cancellation-free order (b >= c), so that
// θ_k = atan2(4A, that) and cot θ_k = that / 4A.
inline double cornerCosineTerm(const double (&l)[3], int k) {
  double b = l[k], c = l[(k + 2) % 3];
  const double a = l[(k + 1) % 3];
  if (b < c) std::swap(b, c);
  return (b - a) * (b + a) + c * c;
}

// Visits faces list[0..count) (faces 0..count without a list) in order with
// each one's area, its corners' b² + c² − a² and its corner angles θ_k =
// atan2(4A, b² + c² − a²). The angles of a block of faces are one vector
// batch (numerics/vector_trig.h: the same bits as one at a time).
template <typename Visit>
void forEachFaceCorners(const Eigen::MatrixX3i& fe, const Vector& edgeLengths, const int* list, int count,
                        const Visit& visit) {
  constexpr int kBlock = 32;
  double area[kBlock], y[3 * kBlock], x[3 * kBlock], theta[3 * kBlock];
  for (int start = 0; start < count; start += kBlock) {
    const int size = std::min(kBlock, count - start);
    for (int b = 0; b < size; ++b) {
      const int f = list != nullptr ? list[start + b] : start + b;
      const double l[3] = {edgeLengths(fe(f, 0)), edgeLengths(fe(f, 1)), edgeLengths(fe(f, 2))};
      area[b] = stableHeronArea(l[0], l[1], l[2]);
      for (int k = 0; k < 3; ++k) {
        y[3 * b + k] = 4.0 * area[b];
        x[3 * b + k] = cornerCosineTerm(l, k);
      }
    }
    trig::atan2(y, x, theta, 3 * size);
    for (int b = 0; b < size; ++b)
      visit(list != nullptr ? list[start + b] : start + b, area[b], x + 3 * b, theta + 3 * b);
  }
}

// ½ cot θ of a corner from its b² + c² − a² and its face's 4A, without a
// trigonometric call; a face of area 0 keeps the limit of the angle's cot:
// +inf at θ = 0, its cos / sin at θ = π.
inline double halfCotangent(double cosineTerm, double fourArea) {
  if (fourArea > 0.0) return 0.5 * cosineTerm / fourArea;
  const double angle = std::atan2(fourArea, cosineTerm);
  return 0.5 * std::cos(angle) / std::sin(angle);
}

// Half of the cotangent of the angle opposite half-edge h (its face's corner
// (h % 3 + 2) % 3), from the lengths and the area the corner angles are built from.
inline double halfCotangentOpposite(const Eigen::MatrixX3i& fe, const Vector& edgeLengths, const Vector& faceAreas,
                                    int h) {
  const int f = h / 3;
  const double l[3] = {edgeLengths(fe(f, 0)), edgeLengths(fe(f, 1)), edgeLengths(fe(f, 2))};
  return halfCotangent(cornerCosineTerm(l, (h % 3 + 2) % 3), 4.0 * faceAreas(f));
}

}  // namespace

double triangleArea(double a, double b, double c) { return stableHeronArea(a, b, c); }

Vector edgeLengths(const SurfaceTopology& topology, const RowVectors3& vertexPositions) {
  Vector lengths;
  edgeLengths(topology, vertexPositions, lengths);
  return lengths;
}

void edgeLengths(const SurfaceTopology& topology, const RowVectors3& vertexPositions, Vector& lengths) {
  const Eigen::MatrixX2i& ev = topology.edgeVertices();
  lengths.resize(topology.edgeCount());
  for (int e = 0; e < topology.edgeCount(); ++e) {
    lengths(e) = (vertexPositions.row(ev(e, 1)) - vertexPositions.row(ev(e, 0))).norm();
  }
}

Eigen::MatrixX3d faceCornerAngles(const SurfaceTopology& topology, const Vector& edgeLengths) {
  Eigen::MatrixX3d angles(topology.faceCount(), 3);
  forEachFaceCorners(topology.faceEdges(), edgeLengths, nullptr, topology.faceCount(),
                     [&](int f, double, const double*, const double* theta) {
                       for (int k = 0; k < 3; ++k) angles(f, k) = theta[k];
                     });
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

Vector edgeCotanWeights(const SurfaceTopology& topology, const Vector& edgeLengths, const Vector& faceAreas) {
  Vector weights(topology.edgeCount());
  for (int e = 0; e < topology.edgeCount(); ++e)
    updateEdgeCotanWeights(topology, edgeLengths, faceAreas, &e, 1, weights);
  return weights;
}

Vector vertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas) {
  Vector dual;
  vertexDualAreas(topology, faceAreas, dual);
  return dual;
}

void vertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas, Vector& dual) {
  const Triangles& faces = topology.faces();
  dual.setZero(topology.vertexCount());
  for (int f = 0; f < topology.faceCount(); ++f) {
    const double third = faceAreas(f) / 3.0;
    for (int k = 0; k < 3; ++k) dual(faces(f, k)) += third;
  }
}

void faceAnglesAreasAndCotanWeights(const SurfaceTopology& topology, const Vector& edgeLengths,
                                    Eigen::MatrixX3d& faceCornerAngles, Vector& faceAreas,
                                    Vector& edgeCotanWeights) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  const int faceCount = topology.faceCount();
  faceCornerAngles.resize(faceCount, 3);
  faceAreas.resize(faceCount);
  edgeCotanWeights.setZero(topology.edgeCount());
  forEachFaceCorners(fe, edgeLengths, nullptr, faceCount,
                     [&](int f, double area, const double* cosineTerms, const double* theta) {
                       faceAreas(f) = area;
                       for (int k = 0; k < 3; ++k) {
                         faceCornerAngles(f, k) = theta[k];
                         // Corner k is opposite edge faceEdges(f, k + 1). Faces ascending: an edge's
                         // lower-index face adds first, onto 0, as updateEdgeCotanWeights sums.
                         edgeCotanWeights(fe(f, (k + 1) % 3)) += halfCotangent(cosineTerms[k], 4.0 * area);
                       }
                     });
}

void updateFaceAnglesAndAreas(const SurfaceTopology& topology, const Vector& edgeLengths, const int* faces,
                              int count, Eigen::MatrixX3d& faceCornerAngles, Vector& faceAreas) {
  forEachFaceCorners(topology.faceEdges(), edgeLengths, faces, count,
                     [&](int f, double area, const double*, const double* theta) {
                       faceAreas(f) = area;
                       for (int k = 0; k < 3; ++k) faceCornerAngles(f, k) = theta[k];
                     });
}

void updateEdgeCotanWeights(const SurfaceTopology& topology, const Vector& edgeLengths, const Vector& faceAreas,
                            const int* edges, int count, Vector& edgeCotanWeights) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  for (int n = 0; n < count; ++n) {
    // The lower-index face's half first, then the other's: the order of a
    // face-by-face sum, so the bits do not depend on which edges are updated.
    const int e = edges[n];
    const int h = topology.edgeHalfedges()[static_cast<size_t>(e)];
    const int twin = topology.halfedgeTwins()[static_cast<size_t>(h)];
    double w = halfCotangentOpposite(fe, edgeLengths, faceAreas, h);
    if (twin >= 0) w += halfCotangentOpposite(fe, edgeLengths, faceAreas, twin);
    edgeCotanWeights(e) = w;
  }
}

void updateVertexDualAreas(const SurfaceTopology& topology, const Vector& faceAreas, const int* vertices, int count,
                           Vector& vertexDualAreas) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  for (int n = 0; n < count; ++n) {
    const int v = vertices[n];
    // The ring's faces in ascending order (the order vertexDualAreas adds
    // them in), by repeated selection of the next larger face id: rings are
    // small, and this needs no storage whatever the valence.
    const int begin = offsets[static_cast<size_t>(v)], end = offsets[static_cast<size_t>(v) + 1];
    double dual = 0.0;
    int last = -1;
    for (;;) {
      int next = -1;
      for (int m = begin; m < end; ++m) {
        const int f = ringFaces[static_cast<size_t>(m)];
        if (f > last && (next < 0 || f < next)) next = f;
      }
      if (next < 0) break;
      dual += faceAreas(next) / 3.0;
      last = next;
    }
    vertexDualAreas(v) = dual;
  }
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
