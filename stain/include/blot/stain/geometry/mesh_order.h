#pragma once
/// Mesh orders that keep neighbours close in memory. A stain step works ring
/// by ring around the liquid (the band, the advection, the solves), reading
/// each neighbour's and each ring face's values; on a mesh whose file numbers
/// its vertices and faces in no spatial order (a scan, a decimated model)
/// nearly every such read misses the cache. Renumbering costs one pass at
/// load (docs/performance.md, "Mesh order").
#include <blot/stain/geometry/triangle_mesh.h>

#include <vector>

namespace blot::stain {

/// A renumbering: new vertex k is old vertex vertices[k], new face k is old
/// face faces[k].
struct MeshOrder {
  std::vector<int> vertices, faces;
};

/// The locality order. Vertices: Cuthill–McKee, breadth-first through each
/// connected component (components taken by their least old index, each
/// started there), a vertex's unvisited neighbours by increasing degree,
/// then old index; neighbours then sit about one breadth-first level apart.
/// Faces: by their least new vertex, then their largest, then old index.
/// Deterministic. The mesh's faces must index [0, #V).
MeshOrder localityOrder(const TriangleMesh& mesh);

/// Renumbers the mesh by `order`: positions and UVs move with their vertices,
/// faces (and their labels) with theirs; each face keeps its corners' cyclic
/// order, so its orientation. std::invalid_argument unless both lists are
/// permutations of the mesh's vertices and faces.
void reorderMesh(TriangleMesh& mesh, const MeshOrder& order);

/// The inverse of a permutation: inverse[order[k]] = k.
std::vector<int> inversePermutation(const std::vector<int>& order);

}  // namespace blot::stain
