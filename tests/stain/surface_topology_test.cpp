// Connectivity invariants on generated meshes, and the manifold/orientation
// errors SurfaceTopology must raise with the offending element named.
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>

#include <gtest/gtest.h>

#include <cmath>
#include <set>

namespace blot::stain {
namespace {

void expectInvariants(const TriangleMesh& mesh, int expectedEuler, size_t expectedLoops) {
  const SurfaceTopology t(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  EXPECT_EQ(t.vertexCount() - t.edgeCount() + t.faceCount(), expectedEuler);
  EXPECT_EQ(t.boundaryLoops().size(), expectedLoops);
  // Twins are involutions, run the other way, and share the edge.
  for (int h = 0; h < t.halfedgeCount(); ++h) {
    const int tw = t.halfedgeTwins()[static_cast<size_t>(h)];
    if (tw < 0) continue;
    EXPECT_EQ(t.halfedgeTwins()[static_cast<size_t>(tw)], h);
    EXPECT_EQ(t.halfedgeTail(tw), t.halfedgeHead(h));
    EXPECT_EQ(t.halfedgeEdges()[static_cast<size_t>(tw)], t.halfedgeEdges()[static_cast<size_t>(h)]);
  }
  // Rings: every neighbour is an edge endpoint, each face appears once, and the
  // ring is counter-clockwise (consecutive neighbours span a face of the ring
  // whose orientation agrees with the vertex order (v, n_m, n_m+1)).
  int ringFaceTotal = 0;
  ASSERT_EQ(t.ringCorners().size(), t.ringFaces().size());
  for (int v = 0; v < t.vertexCount(); ++v) {
    const int b = t.ringOffsets()[static_cast<size_t>(v)], e = t.ringOffsets()[static_cast<size_t>(v) + 1];
    const bool boundary = t.vertexIsBoundary()[static_cast<size_t>(v)];
    for (int m = b; m < e; ++m) {
      const int n = t.ringNeighbors()[static_cast<size_t>(m)];
      const int edge = t.ringEdges()[static_cast<size_t>(m)];
      EXPECT_EQ(std::min(v, n), t.edgeVertices()(edge, 0));
      EXPECT_EQ(std::max(v, n), t.edgeVertices()(edge, 1));
      const int f = t.ringFaces()[static_cast<size_t>(m)];
      const int corner = t.ringCorners()[static_cast<size_t>(m)];
      if (f < 0) {
        EXPECT_TRUE(boundary);
        EXPECT_EQ(m, e - 1);
        EXPECT_EQ(corner, -1);
        continue;
      }
      ++ringFaceTotal;
      const int next = t.ringNeighbors()[static_cast<size_t>(m + 1 < e ? m + 1 : b)];
      int k = 0;
      while (t.faces()(f, k) != v) ++k;
      EXPECT_EQ(corner, k) << "vertex " << v << " ring entry " << m << ": the corner of its ring face at it";
      EXPECT_EQ(t.faces()(f, (k + 1) % 3), n) << "vertex " << v << " ring entry " << m;
      EXPECT_EQ(t.faces()(f, (k + 2) % 3), next) << "vertex " << v << " ring entry " << m;
    }
  }
  EXPECT_EQ(ringFaceTotal, 3 * t.faceCount());
}

TEST(SurfaceTopology, GridHasOneBoundaryLoopAndEulerOne) { expectInvariants(gridMesh(7, 5, 2.0, 1.0), 1, 1); }
TEST(SurfaceTopology, IcosphereIsClosedWithEulerTwo) {
  for (int level = 0; level <= 3; ++level) expectInvariants(icosphereMesh(level), 2, 0);
}
TEST(SurfaceTopology, DiscHasOneBoundaryLoop) { expectInvariants(discMesh(5, 1.0), 1, 1); }

TEST(SurfaceTopology, BoundaryLoopKeepsSurfaceOnTheLeft) {
  const TriangleMesh grid = gridMesh(3, 2, 3.0, 2.0);
  const SurfaceTopology t(grid.faces, static_cast<int>(grid.vertexPositions.rows()));
  const auto& loop = t.boundaryLoops().at(0);
  ASSERT_EQ(loop.size(), 10u);
  // Counter-clockwise in the plane: positive signed area.
  double area = 0;
  for (size_t k = 0; k < loop.size(); ++k) {
    const auto p = grid.vertexPositions.row(loop[k]);
    const auto q = grid.vertexPositions.row(loop[(k + 1) % loop.size()]);
    area += 0.5 * (p.x() * q.y() - q.x() * p.y());
  }
  EXPECT_NEAR(area, 6.0, 1e-12);
}

std::string errorOf(const Triangles& faces, int vertexCount) {
  try {
    SurfaceTopology(faces, vertexCount, "test.obj");
  } catch (const MeshError& e) {
    return e.what();
  }
  return "";
}

TEST(SurfaceTopology, RejectsNonManifoldEdge) {
  Triangles f(3, 3);
  f << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  const std::string msg = errorOf(f, 5);
  EXPECT_NE(msg.find("test.obj"), std::string::npos) << msg;
  EXPECT_NE(msg.find("non-manifold edge (0, 1)"), std::string::npos) << msg;
}

TEST(SurfaceTopology, RejectsBowtieVertex) {
  Triangles f(2, 3);
  f << 0, 1, 2, 0, 3, 4;
  const std::string msg = errorOf(f, 5);
  EXPECT_NE(msg.find("non-manifold vertex 0"), std::string::npos) << msg;
}

TEST(SurfaceTopology, RejectsTwoClosedFansAtAVertex) {
  // Two tetrahedra sharing vertex 0 only: each fan is closed, the vertex is not manifold.
  Triangles f(8, 3);
  f << 0, 2, 1, 0, 3, 2, 0, 1, 3, 1, 2, 3,  //
      0, 5, 4, 0, 6, 5, 0, 4, 6, 4, 5, 6;
  const std::string msg = errorOf(f, 7);
  EXPECT_NE(msg.find("non-manifold vertex 0"), std::string::npos) << msg;
}

TEST(SurfaceTopology, RejectsInconsistentOrientation) {
  Triangles f(2, 3);
  f << 0, 1, 2, 0, 1, 3;
  const std::string msg = errorOf(f, 4);
  EXPECT_NE(msg.find("faces 0 and 1 disagree on orientation across edge (0, 1)"), std::string::npos) << msg;
}

TEST(SurfaceTopology, RejectsOutOfRangeRepeatedAndUnreferenced) {
  Triangles f(1, 3);
  f << 0, 1, 7;
  EXPECT_NE(errorOf(f, 3).find("face 0: vertex index 7 out of range [0, 2]"), std::string::npos);
  f << 0, 1, 1;
  EXPECT_NE(errorOf(f, 3).find("face 0 repeats a vertex"), std::string::npos);
  f << 0, 1, 2;
  EXPECT_NE(errorOf(f, 4).find("vertex 3 is not referenced by any face"), std::string::npos);
}

}  // namespace
}  // namespace blot::stain
