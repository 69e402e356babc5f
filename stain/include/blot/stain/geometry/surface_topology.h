#pragma once
/// Connectivity of a manifold triangle mesh, built once from the face list.
///
/// Half-edge h = 3 f + k runs from faces(f, k) to faces(f, (k + 1) % 3) and lies
/// in face f (f on its left). Edges are undirected, stored with the smaller
/// vertex index first. One-rings are counter-clockwise about the outward normal:
/// interior vertices start at the neighbour of their first outgoing half-edge
/// (lowest face index); boundary vertices start at the neighbour across the
/// boundary edge that has the vertex's fan on its left, and end at the other
/// boundary neighbour, so the fan is never split.
#include <blot/stain/geometry/triangle_mesh.h>
#include <blot/stain/types.h>

#include <vector>

namespace blot::stain {

class SurfaceTopology {
 public:
  /// Builds connectivity. Throws MeshError naming `sourceName` and the element
  /// when an edge has more than two faces, a vertex's faces form more than one
  /// fan, two faces sharing an edge disagree on orientation, or an index is out
  /// of range. Vertices referenced by no face are reported as errors too.
  SurfaceTopology(const Triangles& faces, int vertexCount,
                  const std::string& sourceName = "mesh");

  int vertexCount() const { return vertexCount_; }
  int faceCount() const { return static_cast<int>(faces_.rows()); }
  int edgeCount() const { return static_cast<int>(edgeVertices_.rows()); }
  int halfedgeCount() const { return 3 * faceCount(); }

  const Triangles& faces() const { return faces_; }
  /// #E by 2 vertex indices (i < j).
  const Eigen::MatrixX2i& edgeVertices() const { return edgeVertices_; }
  /// #H: edge of each half-edge.
  const std::vector<int>& halfedgeEdges() const { return halfedgeEdges_; }
  /// #H: opposite half-edge, or -1 on the boundary.
  const std::vector<int>& halfedgeTwins() const { return halfedgeTwins_; }
  /// #E: one half-edge of each edge (the one in the lower-index face).
  const std::vector<int>& edgeHalfedges() const { return edgeHalfedges_; }
  /// #F by 3: edge of half-edge 3f+k, i.e. the edge (faces(f,k), faces(f,(k+1)%3)).
  const Eigen::MatrixX3i& faceEdges() const { return faceEdges_; }

  int halfedgeTail(int h) const { return faces_(h / 3, h % 3); }
  int halfedgeHead(int h) const { return faces_(h / 3, (h % 3 + 1) % 3); }
  static int next(int h) { return 3 * (h / 3) + (h % 3 + 1) % 3; }
  static int prev(int h) { return 3 * (h / 3) + (h % 3 + 2) % 3; }

  /// One-ring neighbours in CSR form: vertex i's ring is entries
  /// [ringOffsets()[i], ringOffsets()[i+1]). Interior: k neighbours and k faces;
  /// boundary: k + 1 neighbours and k faces.
  const std::vector<int>& ringOffsets() const { return ringOffsets_; }
  const std::vector<int>& ringNeighbors() const { return ringNeighbors_; }
  /// Per ring entry: the edge to that neighbour.
  const std::vector<int>& ringEdges() const { return ringEdges_; }
  /// Per ring entry m: the face between neighbour m and neighbour m+1
  /// (wrapping for interior vertices); -1 at a boundary vertex's last entry.
  const std::vector<int>& ringFaces() const { return ringFaces_; }
  /// Per ring entry m of vertex i: the corner k of ringFaces()[m] at i
  /// (faces(f, k) == i), −1 where the ring face is −1. What a search of the
  /// face's three vertices would find, without the search.
  const std::vector<signed char>& ringCorners() const { return ringCorners_; }
  int ringSize(int i) const { return ringOffsets_[i + 1] - ringOffsets_[i]; }

  const std::vector<char>& vertexIsBoundary() const { return vertexIsBoundary_; }
  /// Boundary loops as vertex sequences, each oriented with the surface on its left.
  const std::vector<std::vector<int>>& boundaryLoops() const { return boundaryLoops_; }

 private:
  int vertexCount_ = 0;
  Triangles faces_;
  Eigen::MatrixX2i edgeVertices_;
  Eigen::MatrixX3i faceEdges_;
  std::vector<int> halfedgeEdges_, halfedgeTwins_, edgeHalfedges_;
  std::vector<int> ringOffsets_, ringNeighbors_, ringEdges_, ringFaces_;
  std::vector<signed char> ringCorners_;
  std::vector<char> vertexIsBoundary_;
  std::vector<std::vector<int>> boundaryLoops_;
};

}  // namespace blot::stain
