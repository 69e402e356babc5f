// Intrinsic geometry: angles, areas, cotan weights, dual areas, angle sums.
#include <blot/stain/geometry/intrinsic_geometry.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "geometry_test_support.h"

namespace blot::stain {
namespace {

using testing::Geometry;
using testing::kPi;
using testing::kTwoPi;

// One triangle (0, 1, 2) with given side lengths: l01, l12, l20.
struct SingleTriangle {
  SurfaceTopology topology{Triangles((Triangles(1, 3) << 0, 1, 2).finished()), 3};
  Vector lengths(double l01, double l12, double l20) const {
    Vector l(3);
    for (int e = 0; e < 3; ++e) {
      const int a = topology.edgeVertices()(e, 0), b = topology.edgeVertices()(e, 1);
      l(e) = (a == 0 && b == 1) ? l01 : (a == 1 && b == 2) ? l12 : l20;
    }
    return l;
  }
};

TEST(IntrinsicGeometry, RightTriangleAnglesAreaAndCotanWeights) {
  const SingleTriangle t;
  const Vector l = t.lengths(3.0, 5.0, 4.0);  // right angle at vertex 0
  const Eigen::MatrixX3d angles = faceCornerAngles(t.topology, l);
  EXPECT_NEAR(angles(0, 0), kPi / 2, 1e-15);
  EXPECT_NEAR(angles(0, 1), std::atan2(4.0, 3.0), 1e-15);
  EXPECT_NEAR(angles(0, 2), std::atan2(3.0, 4.0), 1e-15);
  EXPECT_NEAR(faceAreas(t.topology, l)(0), 6.0, 1e-14);
  const Vector w = edgeCotanWeights(t.topology, l, faceAreas(t.topology, l));
  for (int e = 0; e < 3; ++e) {
    const int a = t.topology.edgeVertices()(e, 0), b = t.topology.edgeVertices()(e, 1);
    // Boundary edges: one term, ½ cot of the opposite angle.
    const double expected = (a == 1 && b == 2) ? 0.0 : (a == 0 && b == 1) ? 0.5 * 4.0 / 3.0 : 0.5 * 3.0 / 4.0;
    EXPECT_NEAR(w(e), expected, 1e-15) << "edge " << a << "-" << b;
  }
}

TEST(IntrinsicGeometry, NeedleTriangleKeepsFullRelativeAccuracy) {
  // Isosceles with apex angle ~1e-8: naive Heron loses ~8 digits, acos of the
  // law of cosines loses the apex angle entirely.
  const SingleTriangle t;
  const double c = 1e-8;
  const Vector l = t.lengths(1.0, c, 1.0);  // apex at vertex 0, short edge 1-2
  const double exactArea = 0.25 * c * std::sqrt(4.0 - c * c);
  const double exactApex = 2.0 * std::asin(0.5 * c);
  EXPECT_NEAR(faceAreas(t.topology, l)(0) / exactArea, 1.0, 1e-14);
  const Eigen::MatrixX3d angles = faceCornerAngles(t.topology, l);
  EXPECT_NEAR(angles(0, 0) / exactApex, 1.0, 1e-13);
  EXPECT_NEAR(angles.row(0).sum(), kPi, 1e-15);
}

TEST(IntrinsicGeometry, CapTriangleHasAngleNearPi) {
  const SingleTriangle t;
  const Vector l = t.lengths(1.0, 1.0, 2.0 - 1e-12);  // nearly flat at vertex 1
  const Eigen::MatrixX3d angles = faceCornerAngles(t.topology, l);
  EXPECT_GT(angles(0, 1), kPi - 1e-5);
  EXPECT_NEAR(angles.row(0).sum(), kPi, 1e-14);
  // A triangle that violates the inequality by rounding has area 0, not NaN.
  const Vector bad = t.lengths(1.0, 1.0, 2.0 + 1e-15);
  EXPECT_EQ(faceAreas(t.topology, bad)(0), 0.0);
}

TEST(IntrinsicGeometry, RandomMeshAnglesAreasAndCotansMatchEmbedding) {
  const Geometry g(testing::jitteredIcosphere(3, 0.3, 11));
  double totalArea = 0.0;
  for (int f = 0; f < g.faceCount(); ++f) {
    EXPECT_NEAR(g.angles.row(f).sum(), kPi, 1e-14) << "face " << f;
    Vector3 p[3];
    for (int k = 0; k < 3; ++k) p[k] = g.mesh.vertexPositions.row(g.topology.faces()(f, k)).transpose();
    const double area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
    EXPECT_NEAR(g.areas(f) / area, 1.0, 1e-13) << "face " << f;
    totalArea += area;
    for (int k = 0; k < 3; ++k) {
      const Vector3 a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
      EXPECT_NEAR(g.angles(f, k), std::atan2(a.cross(b).norm(), a.dot(b)), 1e-13);
    }
  }
  EXPECT_NEAR(g.dualAreas.sum() / totalArea, 1.0, 1e-14);

  // Cotan weights from the embedding: ½ Σ (a·b)/|a×b| over the opposite corners.
  Vector expected = Vector::Zero(g.topology.edgeCount());
  for (int f = 0; f < g.faceCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Vector3 p = g.mesh.vertexPositions.row(g.topology.faces()(f, k)).transpose();
      const Vector3 a = g.mesh.vertexPositions.row(g.topology.faces()(f, (k + 1) % 3)).transpose() - p;
      const Vector3 b = g.mesh.vertexPositions.row(g.topology.faces()(f, (k + 2) % 3)).transpose() - p;
      expected(g.topology.faceEdges()(f, (k + 1) % 3)) += 0.5 * a.dot(b) / a.cross(b).norm();
    }
  }
  EXPECT_LE((g.cotanWeights - expected).cwiseAbs().maxCoeff(), 1e-12 * expected.cwiseAbs().maxCoeff());
}

// The weights come from the lengths ((b² + c² − a²) / 4A), the angles from
// atan2 of the same two numbers: on every edge of a jittered sphere (acute
// and obtuse corners) the weight is ½ Σ cot of the returned angles to 1e-14
// relative. A face of area 0 keeps the angles' limits: +inf opposite a zero
// angle, a large finite negative weight opposite an angle of π.
TEST(IntrinsicGeometry, CotanWeightsAreHalfTheCotOfTheCornerAngles) {
  const Geometry g(testing::jitteredIcosphere(3, 0.45, 7));
  Vector fromAngles = Vector::Zero(g.topology.edgeCount());
  int obtuse = 0;
  for (int f = 0; f < g.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) {
      const double angle = g.angles(f, k);
      obtuse += angle > kPi / 2 ? 1 : 0;
      fromAngles(g.topology.faceEdges()(f, (k + 1) % 3)) += 0.5 * std::cos(angle) / std::sin(angle);
    }
  EXPECT_GT(obtuse, 0);  // the comparison covers negative cotangents too
  for (int e = 0; e < g.topology.edgeCount(); ++e)
    EXPECT_NEAR(g.cotanWeights(e), fromAngles(e), 1e-14 * (1.0 + std::abs(fromAngles(e)))) << "edge " << e;

  const SingleTriangle t;
  const Vector flat = t.lengths(1.0, 1.0, 2.0);  // vertex 1 at angle π, vertices 0 and 2 at 0
  const Vector w = edgeCotanWeights(t.topology, flat, faceAreas(t.topology, flat));
  for (int e = 0; e < 3; ++e) {
    const int a = t.topology.edgeVertices()(e, 0), b = t.topology.edgeVertices()(e, 1);
    if (a == 0 && b == 2) {
      EXPECT_TRUE(std::isfinite(w(e)));  // opposite vertex 1, angle π
      EXPECT_LT(w(e), -1e15);
    } else {
      EXPECT_EQ(w(e), std::numeric_limits<double>::infinity()) << "edge " << a << "-" << b;
    }
  }
}

// The one-pass function a rebuild calls gives bitwise the three whole-mesh
// functions' values, on a closed sphere and on a sheet with boundary edges
// (one cotan term), into arrays of another size (resized) and of the right
// size (reused).
TEST(IntrinsicGeometry, OnePassAnglesAreasAndCotansAreTheSeparateFunctionsBitwise) {
  for (const TriangleMesh& mesh : {testing::jitteredIcosphere(3, 0.45, 7), gridMesh(7, 5, 1.0, 0.6)}) {
    const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
    const Vector lengths = edgeLengths(topology, mesh.vertexPositions);
    Eigen::MatrixX3d angles(2, 3);
    Vector areas(1), weights;
    for (int pass = 0; pass < 2; ++pass) {
      faceAnglesAreasAndCotanWeights(topology, lengths, angles, areas, weights);
      EXPECT_EQ(angles, faceCornerAngles(topology, lengths));
      EXPECT_EQ(areas, faceAreas(topology, lengths));
      EXPECT_EQ(weights, edgeCotanWeights(topology, lengths, faceAreas(topology, lengths)));
    }
  }
}

TEST(IntrinsicGeometry, AngleSumsOnFlatAndClosedMeshes) {
  // Flat grid: interior vertices sum to 2π, corners to π/2, edges to π.
  const Geometry grid(gridMesh(6, 4, 3.0, 2.0));
  for (int v = 0; v < grid.vertexCount(); ++v) {
    const int i = v % 7, j = v / 7;
    const bool edgeI = i == 0 || i == 6, edgeJ = j == 0 || j == 4;
    const double expected = edgeI && edgeJ ? kPi / 2 : (edgeI || edgeJ ? kPi : kTwoPi);
    EXPECT_NEAR(grid.angleSums(v), expected, 1e-14) << "vertex " << v;
  }
  // Closed sphere: discrete Gauss–Bonnet, Σ (2π − γ_v) = 2π χ = 4π.
  const Geometry sphere(testing::jitteredIcosphere(2, 0.3, 5));
  EXPECT_NEAR((kTwoPi - sphere.angleSums.array()).sum(), 4 * kPi, 1e-11);
}

TEST(IntrinsicGeometry, InvariantUnderRigidMotion) {
  TriangleMesh mesh = testing::jitteredIcosphere(2, 0.3, 3);
  const Geometry before(mesh);
  const Matrix3 rotation = Eigen::AngleAxisd(0.7, Vector3(1, 2, 3).normalized()).toRotationMatrix();
  mesh.vertexPositions = ((mesh.vertexPositions * rotation.transpose()).rowwise() +
                          Eigen::RowVector3d(4.0, -2.0, 1.0)).eval();
  const Geometry after(mesh);
  EXPECT_LE((before.lengths - after.lengths).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LE((before.angles - after.angles).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LE((before.cotanWeights - after.cotanWeights).cwiseAbs().maxCoeff(), 1e-11);
}

}  // namespace
}  // namespace blot::stain
