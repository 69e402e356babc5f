// Generated meshes: counts, extents, orientation and radius.
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>

#include <gtest/gtest.h>

namespace blot::stain {
namespace {

double signedAreaZ(const TriangleMesh& m, int f) {
  const Vector3 a = m.vertexPositions.row(m.faces(f, 0)), b = m.vertexPositions.row(m.faces(f, 1)),
                c = m.vertexPositions.row(m.faces(f, 2));
  return 0.5 * (b - a).cross(c - a).z();
}

TEST(MeshPrimitives, GridCountsAreaAndOrientation) {
  const TriangleMesh g = gridMesh(10, 4, 2.0, 0.5);
  EXPECT_EQ(g.vertexPositions.rows(), 11 * 5);
  EXPECT_EQ(g.faces.rows(), 80);
  double area = 0;
  for (int f = 0; f < g.faces.rows(); ++f) {
    EXPECT_GT(signedAreaZ(g, f), 0.0) << "face " << f;
    area += signedAreaZ(g, f);
  }
  EXPECT_NEAR(area, 1.0, 1e-14);
  EXPECT_DOUBLE_EQ(g.vertexPositions(54, 0), 2.0);
  EXPECT_DOUBLE_EQ(g.vertexPositions(54, 1), 0.5);
}

TEST(MeshPrimitives, IcosphereCountsRadiusAndOutwardNormals) {
  for (int level = 0; level <= 3; ++level) {
    const TriangleMesh s = icosphereMesh(level, 2.0);
    const int expectedVertices = 10 * (1 << (2 * level)) + 2;
    EXPECT_EQ(s.vertexPositions.rows(), expectedVertices);
    EXPECT_EQ(s.faces.rows(), 20 * (1 << (2 * level)));
    EXPECT_NEAR((s.vertexPositions.rowwise().norm().array() - 2.0).abs().maxCoeff(), 0.0, 1e-14);
    for (int f = 0; f < s.faces.rows(); ++f) {
      const Vector3 a = s.vertexPositions.row(s.faces(f, 0)), b = s.vertexPositions.row(s.faces(f, 1)),
                    c = s.vertexPositions.row(s.faces(f, 2));
      EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0) << "face " << f << " points inward";
    }
  }
}

TEST(MeshPrimitives, DiscCountsAndOrientation) {
  const TriangleMesh d = discMesh(6, 1.5);
  EXPECT_EQ(d.vertexPositions.rows(), 1 + 3 * 6 * 7);
  EXPECT_EQ(d.faces.rows(), 6 * 36);  // 6 r² triangles
  for (int f = 0; f < d.faces.rows(); ++f) EXPECT_GT(signedAreaZ(d, f), 0.0) << "face " << f;
  EXPECT_NEAR(d.vertexPositions.rowwise().norm().maxCoeff(), 1.5, 1e-14);
  EXPECT_NO_THROW(SurfaceTopology(d.faces, static_cast<int>(d.vertexPositions.rows())));
}

}  // namespace
}  // namespace blot::stain
