// Mesh orders for locality: a permutation that keeps the mesh (positions, UVs,
// labels, orientation, edges), brings neighbours close in memory, and is
// deterministic; bad orders are refused.
#include <blot/stain/geometry/mesh_order.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

namespace blot::stain {
namespace {

/// The mesh with its vertices and faces numbered at random (a scan's file).
TriangleMesh shuffled(const TriangleMesh& mesh, unsigned seed) {
  std::mt19937 random(seed);
  MeshOrder order;
  order.vertices.resize(static_cast<size_t>(mesh.vertexPositions.rows()));
  order.faces.resize(static_cast<size_t>(mesh.faces.rows()));
  std::iota(order.vertices.begin(), order.vertices.end(), 0);
  std::iota(order.faces.begin(), order.faces.end(), 0);
  std::shuffle(order.vertices.begin(), order.vertices.end(), random);
  std::shuffle(order.faces.begin(), order.faces.end(), random);
  TriangleMesh out = mesh;
  reorderMesh(out, order);
  return out;
}

/// Median over edges of |i - j|: how far apart in memory neighbours sit.
int medianEdgeSpan(const TriangleMesh& mesh) {
  std::vector<int> spans;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f)
    for (int c = 0; c < 3; ++c) spans.push_back(std::abs(mesh.faces(f, c) - mesh.faces(f, (c + 1) % 3)));
  std::nth_element(spans.begin(), spans.begin() + static_cast<long>(spans.size() / 2), spans.end());
  return spans[spans.size() / 2];
}

/// Each face as its corner positions, rotated to start at its least corner
/// (orientation kept), with its label: the mesh without its numbering.
std::multiset<std::pair<std::vector<double>, int>> faceSet(const TriangleMesh& mesh) {
  std::multiset<std::pair<std::vector<double>, int>> out;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    std::vector<std::vector<double>> corners;
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.faces(f, c);
      corners.push_back({mesh.vertexPositions(v, 0), mesh.vertexPositions(v, 1), mesh.vertexPositions(v, 2),
                         mesh.vertexUVs.rows() ? mesh.vertexUVs(v, 0) : 0.0,
                         mesh.vertexUVs.rows() ? mesh.vertexUVs(v, 1) : 0.0});
    }
    const auto least = std::min_element(corners.begin(), corners.end()) - corners.begin();
    std::vector<double> key;
    for (int c = 0; c < 3; ++c) {
      const auto& corner = corners[static_cast<size_t>((least + c) % 3)];
      key.insert(key.end(), corner.begin(), corner.end());
    }
    out.insert({key, mesh.faceLabels.empty() ? -1 : mesh.faceLabels[static_cast<size_t>(f)]});
  }
  return out;
}

TEST(MeshOrder, LocalityOrderKeepsTheMeshAndBringsNeighboursClose) {
  TriangleMesh grid = gridMesh(60, 40, 1.5, 1.0);
  grid.faceLabels.resize(static_cast<size_t>(grid.faces.rows()));
  for (size_t f = 0; f < grid.faceLabels.size(); ++f) grid.faceLabels[f] = static_cast<int>(f % 7);
  for (const TriangleMesh& scan : {shuffled(grid, 1), shuffled(icosphereMesh(4), 2)}) {
    const MeshOrder order = localityOrder(scan);
    TriangleMesh ordered = scan;
    reorderMesh(ordered, order);
    EXPECT_EQ(faceSet(ordered), faceSet(scan));  // same faces, corners, orientation, UVs and labels
    for (Eigen::Index k = 0; k < ordered.vertexPositions.rows(); ++k)
      ASSERT_EQ(ordered.vertexPositions.row(k), scan.vertexPositions.row(order.vertices[static_cast<size_t>(k)]));
    // Shuffled: neighbours a third of the mesh apart; ordered: about one
    // breadth-first level (a grid's diagonal, a sphere's circumference).
    const int n = static_cast<int>(scan.vertexPositions.rows());
    EXPECT_GT(medianEdgeSpan(scan), n / 5);
    EXPECT_LT(medianEdgeSpan(ordered), 100) << n << " vertices";
    // Faces follow their least vertex.
    int previous = -1;
    for (Eigen::Index f = 0; f < ordered.faces.rows(); ++f) {
      const int least = ordered.faces.row(f).minCoeff();
      EXPECT_GE(least, previous);
      previous = least;
    }
    // Deterministic, and the same topology (edge count, boundary) as before.
    const MeshOrder again = localityOrder(scan);
    EXPECT_EQ(again.vertices, order.vertices);
    EXPECT_EQ(again.faces, order.faces);
    const SurfaceTopology before(scan.faces, n), after(ordered.faces, n);
    EXPECT_EQ(before.edgeCount(), after.edgeCount());
  }
}

TEST(MeshOrder, EveryComponentIsNumberedFromItsLeastVertex) {
  // Two separate grids, the second's vertices numbered first in the file.
  const TriangleMesh a = gridMesh(3, 3, 1, 1), b = gridMesh(2, 2, 1, 1);
  TriangleMesh both;
  const Eigen::Index na = a.vertexPositions.rows(), nb = b.vertexPositions.rows();
  both.vertexPositions.resize(na + nb, 3);
  both.vertexPositions << b.vertexPositions, a.vertexPositions;
  both.faces.resize(a.faces.rows() + b.faces.rows(), 3);
  both.faces << a.faces.array() + static_cast<int>(nb), b.faces;
  const MeshOrder order = localityOrder(both);
  ASSERT_EQ(order.vertices.size(), static_cast<size_t>(na + nb));
  EXPECT_EQ(order.vertices[0], 0);  // b's first vertex starts b's component
  for (Eigen::Index k = 0; k < nb; ++k) EXPECT_LT(order.vertices[static_cast<size_t>(k)], nb);
  EXPECT_EQ(order.vertices[static_cast<size_t>(nb)], static_cast<int>(nb));  // then a's, from its least vertex
}

TEST(MeshOrder, BadOrdersAndMeshesAreRefused) {
  TriangleMesh grid = gridMesh(2, 2, 1, 1);
  MeshOrder order = localityOrder(grid);
  MeshOrder repeated = order;
  repeated.vertices[1] = repeated.vertices[0];
  EXPECT_THROW(reorderMesh(grid, repeated), std::invalid_argument);
  MeshOrder shortFaces = order;
  shortFaces.faces.pop_back();
  EXPECT_THROW(reorderMesh(grid, shortFaces), std::invalid_argument);
  TriangleMesh badFace = grid;
  badFace.faces(0, 1) = 99;
  EXPECT_THROW(localityOrder(badFace), std::invalid_argument);
  TriangleMesh badLabels = grid;
  badLabels.faceLabels = {1, 2};
  EXPECT_THROW(reorderMesh(badLabels, order), std::invalid_argument);
  EXPECT_THROW(inversePermutation({0, 2, 2}), std::invalid_argument);
  EXPECT_EQ(inversePermutation({2, 0, 1}), (std::vector<int>{1, 2, 0}));
}

}  // namespace
}  // namespace blot::stain
