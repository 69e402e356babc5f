// Discrete parallel transport: polar maps, edge angles θ_ij, face angles φ,
// holonomy on flat and curved meshes.
//
// Which identity is "the holonomy around each interior vertex equals its angle
// defect"? Two transports live on the mesh:
//  (1) Face-to-face Levi-Civita transport (unfold the two faces across their
//      shared edge). Its holonomy around the dual loop of vertex v (the faces
//      of v's star, in order) is exactly d_v = 2π − γ_v: the loop encloses v
//      and nothing else. Tested as DualLoopHolonomyEqualsAngleDefect.
//  (2) The vertex-to-vertex transport θ_ij = α_ij − α_ji + π built from the
//      rescaled polar maps (what the connection Laplacian uses). Going around
//      face (i, j, k) counter-clockwise, the α differences add up to
//      Σ_w s_w c_w + 3π with s_w = 2π/γ_w; since Σ c_w = π this is, mod 2π,
//      H_f = Σ_w (s_w − 1) c_w = Σ_w d_w c_w / γ_w: each corner carries the
//      fraction c_w/γ_w of its vertex's defect (a counter-clockwise loop on a
//      positively curved surface turns vectors counter-clockwise; composing θ
//      the other way, θ_ij + θ_jk + θ_ki, gives −H_f). Transport is abelian, so
//      the holonomy of the link loop of v (the boundary of its star) is the sum
//      of H_f over the star: all of d_v plus fractions of the neighbours'
//      defects. Summed over all faces, each vertex's shares add to exactly its
//      defect (Σ_f H_f = Σ_v d_v = 2πχ): the curvature "at v" is d_v in the
//      sense that v's corners carry exactly d_v of the face holonomies.
//  So the statement maps to (1) exactly, and to (2) as the per-corner
// share identity; both are tested to 1e-10 (they hold to ~1e-14).
#include <blot/stain/geometry/transport.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "geometry_test_support.h"

namespace blot::stain {
namespace {

using testing::Geometry;
using testing::kPi;
using testing::kTwoPi;
using testing::wrapAngle;

int cornerOf(const Geometry& g, int f, int v) {
  const Triangles& faces = g.topology.faces();
  return faces(f, 0) == v ? 0 : (faces(f, 1) == v ? 1 : 2);
}

// Angle of the directed edge a -> b in face f's frame (x along v0 -> v1,
// counter-clockwise), from corner angles only: the 2D layout puts v0 at the
// origin, v1 on +x and v2 above it.
double edgeAngleInFace(const Geometry& g, int f, int a, int b) {
  const int k = cornerOf(g, f, a);
  double angle = 0.0;  // of a -> v_{k+1}
  if (k == 1) angle = kPi - g.angles(f, 1);
  if (k == 2) angle = kPi + g.angles(f, 0);
  if (g.topology.faces()(f, (k + 1) % 3) == b) return angle;
  return angle + g.angles(f, k);  // a -> v_{k+2} is one corner further
}

// Share of face f's holonomy: Σ_w d_w c_w / γ_w over its corners.
double faceHolonomyShare(const Geometry& g, int f) {
  double share = 0.0;
  for (int k = 0; k < 3; ++k) {
    const int w = g.topology.faces()(f, k);
    share += (kTwoPi - g.angleSums(w)) * g.angles(f, k) / g.angleSums(w);
  }
  return share;
}

// Holonomy of vertex transport around face f, counter-clockwise.
double faceLoopHolonomy(const Geometry& g, int f) {
  const int i = g.topology.faces()(f, 0), j = g.topology.faces()(f, 1), k = g.topology.faces()(f, 2);
  return wrapAngle(g.transportAngle(j, i) + g.transportAngle(k, j) + g.transportAngle(i, k));
}

// Holonomy of vertex transport around the link of v (its ring, closed; for a
// boundary vertex the loop returns through v itself), counter-clockwise.
double linkLoopHolonomy(const Geometry& g, int v) {
  const int begin = g.topology.ringOffsets()[static_cast<size_t>(v)];
  const int end = g.topology.ringOffsets()[static_cast<size_t>(v) + 1];
  std::vector<int> loop(g.topology.ringNeighbors().begin() + begin, g.topology.ringNeighbors().begin() + end);
  if (g.topology.vertexIsBoundary()[static_cast<size_t>(v)]) loop.push_back(v);
  double total = 0.0;
  for (size_t m = 0; m < loop.size(); ++m) total += g.transportAngle(loop[(m + 1) % loop.size()], loop[m]);
  return wrapAngle(total);
}

// Angle of the projection of a 3D direction in the xy-plane (flat meshes).
double planarAngle(const Eigen::RowVector3d& d) { return std::atan2(d.y(), d.x()); }

// wrapAngle is std::remainder(angle, 2π) to the bit: random angles over
// [−20, 20] (both of its fast paths and the fallback) and the edges of each
// path (±π and their neighbours, ±3π, ±9.4, exact ties at ±π), ±0 and NaN.
// Qualified: this file's unqualified wrapAngle is the test support's
// std::remainder, the reference.
TEST(Transport, WrapAngleIsBitwiseTheRemainder) {
  const double pi = std::acos(-1.0);
  const double twoPi = 2.0 * pi;
  std::vector<double> angles = {0.0, -0.0, pi, -pi, 3.0 * pi, -3.0 * pi, 9.4, -9.4, twoPi, -twoPi, 1e300, -1e300};
  for (const double a : {pi, 3.0 * pi, 9.4, twoPi}) {
    for (const double s : {1.0, -1.0}) {
      angles.push_back(std::nextafter(s * a, 0.0));
      angles.push_back(std::nextafter(s * a, s * 1e9));
    }
  }
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> uniform(-20.0, 20.0);
  for (int k = 0; k < 200000; ++k) angles.push_back(uniform(random));
  for (const double a : angles) {
    const double expected = std::remainder(a, twoPi), got = blot::stain::wrapAngle(a);
    ASSERT_EQ(std::memcmp(&expected, &got, sizeof(double)), 0) << std::hexfloat << a << ": " << got << " vs " << expected;
  }
  EXPECT_TRUE(std::isnan(blot::stain::wrapAngle(std::numeric_limits<double>::quiet_NaN())));
}

TEST(Transport, PolarMapConventionsInteriorAndBoundary) {
  for (const Geometry& g : {Geometry(testing::jitteredIcosphere(2, 0.3, 2)),
                            Geometry(testing::jitteredGrid(6, 0.24, 3)), Geometry(discMesh(3, 1.0))}) {
    for (int v = 0; v < g.vertexCount(); ++v) {
      const int begin = g.topology.ringOffsets()[static_cast<size_t>(v)];
      const int end = g.topology.ringOffsets()[static_cast<size_t>(v) + 1];
      const bool boundary = g.topology.vertexIsBoundary()[static_cast<size_t>(v)] != 0;
      EXPECT_EQ(g.polarMap.ringAngles(begin), 0.0) << "reference edge of vertex " << v;
      for (int m = begin + 1; m < end; ++m) EXPECT_GT(g.polarMap.ringAngles(m), g.polarMap.ringAngles(m - 1));
      const double scale = g.polarMap.vertexAngleScales(v);
      if (boundary) {
        EXPECT_EQ(scale, 1.0);
        EXPECT_NEAR(g.polarMap.ringAngles(end - 1), g.angleSums(v), 1e-14) << "vertex " << v;
      } else {
        EXPECT_NEAR(scale, kTwoPi / g.angleSums(v), 1e-14);
        const int lastFace = g.topology.ringFaces()[static_cast<size_t>(end - 1)];
        const double closing = g.polarMap.ringAngles(end - 1) + scale * g.angles(lastFace, cornerOf(g, lastFace, v));
        EXPECT_NEAR(closing, kTwoPi, 1e-14) << "vertex " << v;
      }
    }
    for (int e = 0; e < g.topology.edgeCount(); ++e) {
      EXPECT_LE(std::abs(g.edgeAngles(e)), kPi);
    }
  }
}

class FlatTransport : public ::testing::TestWithParam<int> {
 protected:
  static TriangleMesh mesh(int which) {
    if (which == 0) return gridMesh(12, 8, 1.5, 1.0);  // boundary with four corners
    if (which == 1) return testing::jitteredGrid(12, 0.24, 17);
    return discMesh(6, 1.0);
  }
};

TEST_P(FlatTransport, EdgeAndFaceAnglesMatchThePlanarFrames) {
  const Geometry g(mesh(GetParam()));
  // u_i = exp(iθ_ij) u_j for the coordinates of one fixed planar vector:
  // θ_ij = angle(x_j) − angle(x_i).
  for (int e = 0; e < g.topology.edgeCount(); ++e) {
    const int i = g.topology.edgeVertices()(e, 0), j = g.topology.edgeVertices()(e, 1);
    const double expected = planarAngle(g.frames.xAxes.row(j)) - planarAngle(g.frames.xAxes.row(i));
    EXPECT_NEAR(wrapAngle(g.edgeAngles(e) - expected), 0.0, 1e-12) << "edge " << i << "-" << j;
  }
  // φ(f, k) carries vertex frame to face frame: angle(x_v) − angle(x_f).
  for (int f = 0; f < g.faceCount(); ++f) {
    const Eigen::RowVector3d xFace = g.mesh.vertexPositions.row(g.topology.faces()(f, 1)) -
                                     g.mesh.vertexPositions.row(g.topology.faces()(f, 0));
    for (int k = 0; k < 3; ++k) {
      const int v = g.topology.faces()(f, k);
      const double expected = planarAngle(g.frames.xAxes.row(v)) - planarAngle(xFace);
      EXPECT_NEAR(wrapAngle(g.faceAngles(f, k) - expected), 0.0, 1e-12) << "face " << f << " corner " << k;
    }
  }
}

TEST_P(FlatTransport, EveryClosedLoopHasTrivialHolonomy) {
  const Geometry g(mesh(GetParam()));
  double worst = 0.0;
  for (int f = 0; f < g.faceCount(); ++f) worst = std::max(worst, std::abs(faceLoopHolonomy(g, f)));
  for (int v = 0; v < g.vertexCount(); ++v) worst = std::max(worst, std::abs(linkLoopHolonomy(g, v)));
  // The boundary itself: with boundary fans rescaled to π instead, each corner
  // of the rectangle would add a spurious quarter turn here.
  for (const std::vector<int>& loop : g.topology.boundaryLoops()) {
    double total = 0.0;
    for (size_t m = 0; m < loop.size(); ++m) total += g.transportAngle(loop[(m + 1) % loop.size()], loop[m]);
    worst = std::max(worst, std::abs(wrapAngle(total)));
  }
  std::printf("max |holonomy| over face, link and boundary loops: %.1e\n", worst);
  EXPECT_LE(worst, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(GridJitteredGridDisc, FlatTransport, ::testing::Values(0, 1, 2));

std::vector<Geometry> curvedMeshes() {
  std::vector<Geometry> meshes;
  for (int level = 1; level <= 3; ++level) meshes.emplace_back(icosphereMesh(level));
  meshes.emplace_back(testing::jitteredIcosphere(3, 0.4, 21));
  return meshes;
}

TEST(Transport, FaceHolonomyIsTheSumOfCornerDefectShares) {
  for (const Geometry& g : curvedMeshes()) {
    double worst = 0.0, total = 0.0;
    for (int f = 0; f < g.faceCount(); ++f) {
      const double holonomy = faceLoopHolonomy(g, f);
      worst = std::max(worst, std::abs(holonomy - faceHolonomyShare(g, f)));
      total += holonomy;
    }
    std::printf("%d vertices: max |H_f − Σ d_w c_w/γ_w| = %.1e, |Σ_f H_f − 4π| = %.1e\n",
                g.vertexCount(), worst, std::abs(total - 4 * kPi));
    EXPECT_LE(worst, 1e-10);
    // Gauss–Bonnet: the face holonomies account for all of the curvature.
    EXPECT_NEAR(total, 4 * kPi, 1e-10);
  }
}

TEST(Transport, LinkLoopHolonomyContainsTheVertexDefect) {
  for (const Geometry& g : curvedMeshes()) {
    double worst = 0.0;
    for (int v = 0; v < g.vertexCount(); ++v) {
      const int begin = g.topology.ringOffsets()[static_cast<size_t>(v)];
      const int end = g.topology.ringOffsets()[static_cast<size_t>(v) + 1];
      // d_v (all of v's own corners) plus the neighbours' shares in the star.
      double expected = kTwoPi - g.angleSums(v);
      for (int m = begin; m < end; ++m) {
        const int f = g.topology.ringFaces()[static_cast<size_t>(m)];
        for (int k = 0; k < 3; ++k) {
          const int w = g.topology.faces()(f, k);
          if (w != v) expected += (kTwoPi - g.angleSums(w)) * g.angles(f, k) / g.angleSums(w);
        }
      }
      worst = std::max(worst, std::abs(wrapAngle(linkLoopHolonomy(g, v) - expected)));
    }
    std::printf("%d vertices: max link-loop holonomy error %.1e\n", g.vertexCount(), worst);
    EXPECT_LE(worst, 1e-10);
  }
}

TEST(Transport, DualLoopHolonomyEqualsAngleDefect) {
  for (const Geometry& g : curvedMeshes()) {
    double worst = 0.0;
    for (int v = 0; v < g.vertexCount(); ++v) {
      const int begin = g.topology.ringOffsets()[static_cast<size_t>(v)];
      const int end = g.topology.ringOffsets()[static_cast<size_t>(v) + 1];
      const int count = end - begin;
      double total = 0.0;
      for (int m = 0; m < count; ++m) {
        // Unfold face f_m onto f_{m+1} across their shared edge v -> n_{m+1}:
        // a vector keeps its angle to the edge.
        const int from = g.topology.ringFaces()[static_cast<size_t>(begin + m)];
        const int to = g.topology.ringFaces()[static_cast<size_t>(begin + (m + 1) % count)];
        const int n = g.topology.ringNeighbors()[static_cast<size_t>(begin + (m + 1) % count)];
        total += edgeAngleInFace(g, to, v, n) - edgeAngleInFace(g, from, v, n);
      }
      worst = std::max(worst, std::abs(wrapAngle(total - (kTwoPi - g.angleSums(v)))));
    }
    std::printf("%d vertices: max |dual-loop holonomy − d_v| = %.1e\n", g.vertexCount(), worst);
    EXPECT_LE(worst, 1e-10);
  }
}

TEST(Transport, FaceAnglesAreEdgeAnglesUpToHalfTheRescaling) {
  // Through face f, transport l -> k is φ_l − φ_k = θ_kl − ½ Σ c_w (1 − s_w)
  // over the two ends: eq. 6 up to half of each end's polar-map rescaling.
  for (const Geometry& g : curvedMeshes()) {
    double worst = 0.0;
    for (int f = 0; f < g.faceCount(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int l = (k + 1) % 3;
        const int vk = g.topology.faces()(f, k), vl = g.topology.faces()(f, l);
        const double correction = 0.5 * (g.angles(f, k) * (1 - g.polarMap.vertexAngleScales(vk)) +
                                         g.angles(f, l) * (1 - g.polarMap.vertexAngleScales(vl)));
        const double through = g.faceAngles(f, l) - g.faceAngles(f, k);
        worst = std::max(worst, std::abs(wrapAngle(through - g.transportAngle(vk, vl) + correction)));
      }
    }
    EXPECT_LE(worst, 1e-12);
  }
}

TEST(Transport, EdgeAnglesConvergeToSmoothTransportOnTheSphere) {
  // Reference: carry x_j to i by the minimal rotation taking normal z_j to z_i
  // (exact Levi-Civita transport along the great circle when normals are
  // radial), then read its angle in frame i.
  double previous = 0.0;
  for (int level = 2; level <= 5; ++level) {
    const Geometry g(icosphereMesh(level));
    double worst = 0.0;
    for (int e = 0; e < g.topology.edgeCount(); ++e) {
      const int i = g.topology.edgeVertices()(e, 0), j = g.topology.edgeVertices()(e, 1);
      const Vector3 zi = g.mesh.vertexPositions.row(i).transpose(), zj = g.mesh.vertexPositions.row(j).transpose();
      const Matrix3 rotation = Eigen::Quaterniond::FromTwoVectors(zj, zi).toRotationMatrix();
      const Matrix3 Fi = g.frames.frame(i);
      // Frames use vertex normals; on the icosphere they differ from the radial
      // direction by O(h), so project into i's tangent plane before reading.
      const Vector3 carried = rotation * g.frames.xAxes.row(j).transpose();
      const double expected = std::atan2(carried.dot(Fi.col(1)), carried.dot(Fi.col(0)));
      worst = std::max(worst, std::abs(wrapAngle(g.edgeAngles(e) - expected)));
    }
    std::printf("icosphere level %d: max |θ_ij − θ_smooth| = %.3e", level, worst);
    if (level > 2) std::printf(", observed order %.2f", std::log2(previous / worst));
    std::printf("\n");
    if (level > 2) {
      EXPECT_LT(worst, 0.75 * previous);
    }
    previous = worst;
  }
}

}  // namespace
}  // namespace blot::stain
