// Locality orders for meshes read from files (Cuthill–McKee vertices, faces
// by their vertices).
//
// Design note: the order is for memory locality, not for a narrow band of
// the matrix (the factorization orders its own rows), so the breadth-first
// search starts at each component's least vertex rather than at a
// pseudo-peripheral one: any start keeps neighbours within about one
// level of each other. Measured on the Table 1 bunny (37.7K vertices, the
// CGAL file's numbering: median index distance of an edge's ends 8,700):
// 321 after the vertex order, and the stain step 10.3 -> 7.6 ms, 7.2 ms
// with the faces sorted too (docs/performance.md, "Mesh order").
#include <blot/stain/geometry/mesh_order.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

namespace blot::stain {

namespace {

bool isPermutation(const std::vector<int>& order, Eigen::Index size) {
  if (static_cast<Eigen::Index>(order.size()) != size) return false;
  std::vector<char> seen(order.size(), 0);
  for (const int k : order) {
    if (k < 0 || static_cast<Eigen::Index>(k) >= size || seen[static_cast<size_t>(k)]) return false;
    seen[static_cast<size_t>(k)] = 1;
  }
  return true;
}

}  // namespace

std::vector<int> inversePermutation(const std::vector<int>& order) {
  std::vector<int> inverse(order.size(), -1);
  for (size_t k = 0; k < order.size(); ++k) {
    const int v = order[k];
    if (v < 0 || static_cast<size_t>(v) >= order.size() || inverse[static_cast<size_t>(v)] >= 0)
      throw std::invalid_argument("inversePermutation: entry " + std::to_string(k) + " (" + std::to_string(v) +
                                  ") repeats or lies outside [0, " + std::to_string(order.size()) + ")");
    inverse[static_cast<size_t>(v)] = static_cast<int>(k);
  }
  return inverse;
}

MeshOrder localityOrder(const TriangleMesh& mesh) {
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const int faceCount = static_cast<int>(mesh.faces.rows());
  for (int f = 0; f < faceCount; ++f)
    for (int c = 0; c < 3; ++c)
      if (mesh.faces(f, c) < 0 || mesh.faces(f, c) >= n)
        throw std::invalid_argument("localityOrder: face " + std::to_string(f) + " names vertex " +
                                    std::to_string(mesh.faces(f, c)) + ", outside [0, " + std::to_string(n) + ")");
  // Neighbour lists (compressed rows), each sorted by old index, duplicates
  // (an edge's two faces) removed.
  std::vector<int> starts(static_cast<size_t>(n) + 1, 0);
  for (int f = 0; f < faceCount; ++f)
    for (int c = 0; c < 3; ++c) starts[static_cast<size_t>(mesh.faces(f, c)) + 1] += 2;
  for (int v = 0; v < n; ++v) starts[static_cast<size_t>(v) + 1] += starts[static_cast<size_t>(v)];
  std::vector<int> neighbours(static_cast<size_t>(starts[static_cast<size_t>(n)]));
  std::vector<int> fill(starts.begin(), starts.end() - 1);
  for (int f = 0; f < faceCount; ++f) {
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.faces(f, c);
      neighbours[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = mesh.faces(f, (c + 1) % 3);
      neighbours[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = mesh.faces(f, (c + 2) % 3);
    }
  }
  std::vector<int> degree(static_cast<size_t>(n), 0);
  for (int v = 0; v < n; ++v) {
    const auto begin = neighbours.begin() + starts[static_cast<size_t>(v)];
    auto end = neighbours.begin() + starts[static_cast<size_t>(v) + 1];
    std::sort(begin, end);
    end = std::unique(begin, end);
    degree[static_cast<size_t>(v)] = static_cast<int>(end - begin);
  }

  MeshOrder order;
  order.vertices.reserve(static_cast<size_t>(n));
  std::vector<char> visited(static_cast<size_t>(n), 0);
  std::vector<int> next;
  for (int root = 0; root < n; ++root) {
    if (visited[static_cast<size_t>(root)]) continue;
    visited[static_cast<size_t>(root)] = 1;
    order.vertices.push_back(root);
    for (size_t head = order.vertices.size() - 1; head < order.vertices.size(); ++head) {
      const int v = order.vertices[head];
      next.clear();
      for (int m = starts[static_cast<size_t>(v)]; m < starts[static_cast<size_t>(v)] + degree[static_cast<size_t>(v)];
           ++m) {
        const int w = neighbours[static_cast<size_t>(m)];
        if (visited[static_cast<size_t>(w)]) continue;
        visited[static_cast<size_t>(w)] = 1;
        next.push_back(w);
      }
      std::sort(next.begin(), next.end(), [&](int a, int b) {
        return degree[static_cast<size_t>(a)] != degree[static_cast<size_t>(b)]
                   ? degree[static_cast<size_t>(a)] < degree[static_cast<size_t>(b)]
                   : a < b;
      });
      order.vertices.insert(order.vertices.end(), next.begin(), next.end());
    }
  }

  const std::vector<int> newIndex = inversePermutation(order.vertices);
  std::vector<std::array<int, 3>> keys(static_cast<size_t>(faceCount));
  for (int f = 0; f < faceCount; ++f) {
    int lo = n, hi = -1;
    for (int c = 0; c < 3; ++c) {
      const int v = newIndex[static_cast<size_t>(mesh.faces(f, c))];
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    keys[static_cast<size_t>(f)] = {lo, hi, f};
  }
  std::sort(keys.begin(), keys.end());
  order.faces.resize(static_cast<size_t>(faceCount));
  for (int k = 0; k < faceCount; ++k) order.faces[static_cast<size_t>(k)] = keys[static_cast<size_t>(k)][2];
  return order;
}

void reorderMesh(TriangleMesh& mesh, const MeshOrder& order) {
  const Eigen::Index n = mesh.vertexPositions.rows(), faceCount = mesh.faces.rows();
  if (!isPermutation(order.vertices, n))
    throw std::invalid_argument("reorderMesh: the vertex order is not a permutation of the mesh's " +
                                std::to_string(n) + " vertices");
  if (!isPermutation(order.faces, faceCount))
    throw std::invalid_argument("reorderMesh: the face order is not a permutation of the mesh's " +
                                std::to_string(faceCount) + " faces");
  const bool labels = !mesh.faceLabels.empty();
  if (labels && static_cast<Eigen::Index>(mesh.faceLabels.size()) != faceCount)
    throw std::invalid_argument("reorderMesh: " + std::to_string(mesh.faceLabels.size()) + " face labels for " +
                                std::to_string(faceCount) + " faces");
  const bool uvs = mesh.vertexUVs.rows() == n;
  if (mesh.vertexUVs.rows() != 0 && !uvs)
    throw std::invalid_argument("reorderMesh: " + std::to_string(mesh.vertexUVs.rows()) + " UVs for " +
                                std::to_string(n) + " vertices");
  const std::vector<int> newIndex = inversePermutation(order.vertices);
  TriangleMesh out;
  out.vertexPositions.resize(n, 3);
  if (uvs) out.vertexUVs.resize(n, 2);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index old = order.vertices[static_cast<size_t>(k)];
    out.vertexPositions.row(k) = mesh.vertexPositions.row(old);
    if (uvs) out.vertexUVs.row(k) = mesh.vertexUVs.row(old);
  }
  out.faces.resize(faceCount, 3);
  if (labels) out.faceLabels.resize(static_cast<size_t>(faceCount));
  for (Eigen::Index k = 0; k < faceCount; ++k) {
    const Eigen::Index old = order.faces[static_cast<size_t>(k)];
    for (int c = 0; c < 3; ++c) out.faces(k, c) = newIndex[static_cast<size_t>(mesh.faces(old, c))];
    if (labels) out.faceLabels[static_cast<size_t>(k)] = mesh.faceLabels[static_cast<size_t>(old)];
  }
  mesh = std::move(out);
}

}  // namespace blot::stain
