// Intrinsic geometry from edge lengths.
//
// Design note: docs/design-notes.md, "stain/src/geometry/intrinsic_geometry.cpp".
#include <blot/stain/geometry/intrinsic_geometry.h>

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

// Corner angles and area of face f (the body of faceCornerAngles and faceAreas).
inline void faceAnglesAndArea(const Eigen::MatrixX3i& fe, const Vector& edgeLengths, int f, Eigen::MatrixX3d& angles,
                              double& area) {
  const double l[3] = {edgeLengths(fe(f, 0)), edgeLengths(fe(f, 1)), edgeLengths(fe(f, 2))};
  area = stableHeronArea(l[0], l[1], l[2]);
  const double fourArea = 4.0 * area;
  for (int k = 0; k < 3; ++k) angles(f, k) = std::atan2(fourArea, cornerCosineTerm(l, k));
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
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  Eigen::MatrixX3d angles(topology.faceCount(), 3);
  double area;
  for (int f = 0; f < topology.faceCount(); ++f) faceAnglesAndArea(fe, edgeLengths, f, angles, area);
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
  for (int f = 0; f < faceCount; ++f) {
    const double l[3] = {edgeLengths(fe(f, 0)), edgeLengths(fe(f, 1)), edgeLengths(fe(f, 2))};
    const double area = stableHeronArea(l[0], l[1], l[2]);
    const double fourArea = 4.0 * area;
    faceAreas(f) = area;
    for (int k = 0; k < 3; ++k) {
      const double cosineTerm = cornerCosineTerm(l, k);
      faceCornerAngles(f, k) = std::atan2(fourArea, cosineTerm);
      // Corner k is opposite edge faceEdges(f, k + 1). Faces ascending: an
      // edge's lower-index face adds first, onto 0, as updateEdgeCotanWeights sums.
      edgeCotanWeights(fe(f, (k + 1) % 3)) += halfCotangent(cosineTerm, fourArea);
    }
  }
}

void updateFaceAnglesAndAreas(const SurfaceTopology& topology, const Vector& edgeLengths, const int* faces,
                              int count, Eigen::MatrixX3d& faceCornerAngles, Vector& faceAreas) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  for (int n = 0; n < count; ++n) faceAnglesAndArea(fe, edgeLengths, faces[n], faceCornerAngles, faceAreas(faces[n]));
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
