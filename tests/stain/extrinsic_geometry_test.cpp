// Extrinsic geometry: face and vertex normals, per-vertex tangent frames.
#include <blot/stain/geometry/extrinsic_geometry.h>

#include <gtest/gtest.h>

#include <cstdio>

#include "geometry_test_support.h"

namespace blot::stain {
namespace {

using testing::Geometry;

TEST(ExtrinsicGeometry, FlatGridNormalsAndFramesArePlanar) {
  const Geometry g(testing::jitteredGrid(8, 0.24, 1));
  const RowVectors3 fn = faceNormals(g.topology, g.mesh.vertexPositions);
  for (int f = 0; f < g.faceCount(); ++f) EXPECT_LE((fn.row(f) - Eigen::RowVector3d(0, 0, 1)).norm(), 1e-15);
  for (int v = 0; v < g.vertexCount(); ++v) {
    EXPECT_LE((g.normals.row(v) - Eigen::RowVector3d(0, 0, 1)).norm(), 1e-15);
    EXPECT_NEAR(g.frames.xAxes(v, 2), 0.0, 1e-15);
  }
}

TEST(ExtrinsicGeometry, VertexNormalIsAreaWeighted) {
  // Vertex 0 shared by a big face in the z = 0 plane and a small face in the
  // x = 0 plane: the normal leans towards +z in proportion to the areas.
  TriangleMesh mesh;
  mesh.vertexPositions.resize(4, 3);
  mesh.vertexPositions << 0, 0, 0,  0, 1, 0,  3, 0, 0,  0, 0, 1;
  mesh.faces.resize(2, 3);
  mesh.faces << 0, 2, 1,  0, 1, 3;
  const SurfaceTopology topology(mesh.faces, 4);
  const RowVectors3 n = vertexNormals(topology, mesh.vertexPositions);
  // Face 0 normal: (3,0,0)×(0,1,0) = +3 z, area 1.5; face 1: (0,1,0)×(0,0,1) = +x, area 0.5.
  const Vector3 expected = Vector3(1.0, 0.0, 3.0).normalized();
  EXPECT_LE((n.row(0).transpose() - expected).norm(), 1e-15);
  const RowVectors3 fn = faceNormals(topology, mesh.vertexPositions);
  EXPECT_LE((fn.row(0) - Eigen::RowVector3d(0, 0, 1)).norm(), 1e-15);
  EXPECT_LE((fn.row(1) - Eigen::RowVector3d(1, 0, 0)).norm(), 1e-15);
}

TEST(ExtrinsicGeometry, SphereNormalsConvergeToRadialDirection) {
  // Area weighting is first-order accurate on irregular one-rings (second
  // order only for symmetric ones, e.g. the level-1 icosphere, where it is
  // exact): the error must halve with each refinement from level 2 on.
  double previous = 0.0;
  for (int level = 1; level <= 5; ++level) {
    const Geometry g(icosphereMesh(level));
    double worst = 0.0;
    for (int v = 0; v < g.vertexCount(); ++v)
      worst = std::max(worst, (g.normals.row(v) - g.mesh.vertexPositions.row(v)).norm());
    std::printf("icosphere level %d: max |n - x| = %.3e", level, worst);
    if (level > 2) std::printf(", observed order %.2f", std::log2(previous / worst));
    std::printf("\n");
    if (level == 1) {
      EXPECT_LT(worst, 1e-14);
    } else {
      EXPECT_LT(worst, 0.1 / (1 << level));
    }
    if (level > 2) {
      EXPECT_GT(std::log2(previous / worst), 0.9);
    }
    previous = worst;
  }
}

TEST(ExtrinsicGeometry, FramesAreRightHandedWithXAlongTheReferenceEdge) {
  const Geometry g(testing::jitteredIcosphere(3, 0.35, 9));
  for (int v = 0; v < g.vertexCount(); ++v) {
    const Matrix3 F = g.frames.frame(v);
    EXPECT_LE((F.transpose() * F - Matrix3::Identity()).norm(), 1e-14) << "vertex " << v;
    EXPECT_NEAR(F.determinant(), 1.0, 1e-14);
    EXPECT_LE((F.col(2) - g.normals.row(v).transpose()).norm(), 1e-15);
    const int ref = g.topology.ringNeighbors()[static_cast<size_t>(g.topology.ringOffsets()[static_cast<size_t>(v)])];
    const Vector3 e = (g.mesh.vertexPositions.row(ref) - g.mesh.vertexPositions.row(v)).transpose();
    const Vector3 projected = e - e.dot(F.col(2)) * F.col(2);
    // Polar-map angle of the reference edge is 0: along +x, no y component.
    EXPECT_NEAR(F.col(0).dot(projected), projected.norm(), 1e-14);
    EXPECT_NEAR(F.col(1).dot(e), 0.0, 1e-14);
  }
}

TEST(ExtrinsicGeometry, FramesRotateWithTheMesh) {
  TriangleMesh mesh = testing::jitteredIcosphere(2, 0.3, 4);
  const Geometry before(mesh);
  const Matrix3 R = Eigen::AngleAxisd(1.1, Vector3(-1, 0.5, 2).normalized()).toRotationMatrix();
  mesh.vertexPositions = ((mesh.vertexPositions * R.transpose()).rowwise() + Eigen::RowVector3d(1, 2, 3)).eval();
  const Geometry after(mesh);
  for (int v = 0; v < before.vertexCount(); ++v)
    EXPECT_LE((after.frames.frame(v) - R * before.frames.frame(v)).norm(), 1e-13) << "vertex " << v;
}

}  // namespace
}  // namespace blot::stain
