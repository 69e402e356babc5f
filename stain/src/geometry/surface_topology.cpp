// Connectivity of a manifold triangle mesh.
//
// Design note: half-edges are implicit (h = 3f + k), so the only arrays are the
// twin map and the edge map; nothing is a pointer. Edges are found by sorting
// the 3F half-edges by their undirected key, which is O(F log F), deterministic,
// and needs no hash map (whose iteration order we would have to fix anyway).
// Every manifold and orientation check happens here, once, so every later
// stage may assume a consistently oriented 2-manifold with boundary.
#include <blot/stain/geometry/surface_topology.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <numeric>
#include <sstream>

namespace blot::stain {
namespace {

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw MeshError(source + ": " + what);
}

}  // namespace

SurfaceTopology::SurfaceTopology(const Triangles& faces, int vertexCount,
                                 const std::string& sourceName)
    : vertexCount_(vertexCount), faces_(faces) {
  const int F = static_cast<int>(faces.rows());
  const int H = 3 * F;
  if (vertexCount <= 0 || F == 0) fail(sourceName, "mesh has no vertices or no faces");

  for (int f = 0; f < F; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = faces(f, k);
      if (v < 0 || v >= vertexCount) {
        std::ostringstream s;
        s << "face " << f << ": vertex index " << v << " out of range [0, " << vertexCount - 1 << "]";
        fail(sourceName, s.str());
      }
    }
    if (faces(f, 0) == faces(f, 1) || faces(f, 1) == faces(f, 2) || faces(f, 0) == faces(f, 2)) {
      std::ostringstream s;
      s << "face " << f << " repeats a vertex (" << faces(f, 0) << ", " << faces(f, 1) << ", "
        << faces(f, 2) << ")";
      fail(sourceName, s.str());
    }
  }

  // Group half-edges by undirected edge: sort (key, h) pairs.
  std::vector<std::pair<std::int64_t, int>> keyed(static_cast<size_t>(H));
  for (int h = 0; h < H; ++h) {
    const std::int64_t a = halfedgeTail(h), b = halfedgeHead(h);
    keyed[static_cast<size_t>(h)] = {std::min(a, b) * vertexCount + std::max(a, b), h};
  }
  std::sort(keyed.begin(), keyed.end());

  halfedgeTwins_.assign(static_cast<size_t>(H), -1);
  halfedgeEdges_.assign(static_cast<size_t>(H), -1);
  std::vector<std::array<int, 2>> edges;
  edges.reserve(static_cast<size_t>(H) / 2 + 1);
  for (size_t first = 0; first < keyed.size();) {
    size_t last = first;
    while (last < keyed.size() && keyed[last].first == keyed[first].first) ++last;
    const int count = static_cast<int>(last - first);
    const int h0 = keyed[first].second;
    const int a = std::min(halfedgeTail(h0), halfedgeHead(h0));
    const int b = std::max(halfedgeTail(h0), halfedgeHead(h0));
    if (count > 2) {
      std::ostringstream s;
      s << "non-manifold edge (" << a << ", " << b << ") is shared by " << count << " faces (";
      for (size_t m = first; m < last; ++m) s << (m > first ? ", " : "") << keyed[m].second / 3;
      s << ")";
      fail(sourceName, s.str());
    }
    const int e = static_cast<int>(edges.size());
    edges.push_back({a, b});
    edgeHalfedges_.push_back(h0);
    halfedgeEdges_[static_cast<size_t>(h0)] = e;
    if (count == 2) {
      const int h1 = keyed[first + 1].second;
      if (halfedgeTail(h0) == halfedgeTail(h1)) {
        // The same triangle twice meets itself in the same direction too:
        // named as what it is, not as an orientation to fix.
        const auto corners = [&](int f) {
          std::array<int, 3> v{halfedgeTail(3 * f), halfedgeTail(3 * f + 1), halfedgeTail(3 * f + 2)};
          std::sort(v.begin(), v.end());
          return v;
        };
        std::ostringstream s;
        if (corners(h0 / 3) == corners(h1 / 3)) {
          const std::array<int, 3> v = corners(h0 / 3);
          s << "faces " << h0 / 3 << " and " << h1 / 3 << " are the same triangle (vertices " << v[0] << ", " << v[1]
            << ", " << v[2] << "): a duplicated face";
        } else {
          s << "faces " << h0 / 3 << " and " << h1 / 3 << " disagree on orientation across edge (" << a << ", " << b
            << ") (inconsistent orientation)";
        }
        fail(sourceName, s.str());
      }
      halfedgeTwins_[static_cast<size_t>(h0)] = h1;
      halfedgeTwins_[static_cast<size_t>(h1)] = h0;
      halfedgeEdges_[static_cast<size_t>(h1)] = e;
    }
    first = last;
  }
  edgeVertices_.resize(static_cast<Eigen::Index>(edges.size()), 2);
  for (size_t e = 0; e < edges.size(); ++e) {
    edgeVertices_(static_cast<Eigen::Index>(e), 0) = edges[e][0];
    edgeVertices_(static_cast<Eigen::Index>(e), 1) = edges[e][1];
  }
  faceEdges_.resize(F, 3);
  for (int h = 0; h < H; ++h) faceEdges_(h / 3, h % 3) = halfedgeEdges_[static_cast<size_t>(h)];

  // Ring start per vertex: its twin-less outgoing half-edge (boundary), else
  // its lowest outgoing half-edge. Two twin-less outgoing half-edges mean two
  // boundary fans meet at the vertex: non-manifold.
  std::vector<int> ringStart(static_cast<size_t>(vertexCount), -1);
  std::vector<int> cornerCount(static_cast<size_t>(vertexCount), 0);
  vertexIsBoundary_.assign(static_cast<size_t>(vertexCount), 0);
  for (int h = 0; h < H; ++h) {
    const auto v = static_cast<size_t>(halfedgeTail(h));
    ++cornerCount[v];
    if (halfedgeTwins_[static_cast<size_t>(h)] < 0) {
      if (vertexIsBoundary_[v]) {
        std::ostringstream s;
        s << "non-manifold vertex " << v << ": two boundary fans meet there";
        fail(sourceName, s.str());
      }
      vertexIsBoundary_[v] = 1;
      ringStart[v] = h;
    } else if (!vertexIsBoundary_[v] && ringStart[v] < 0) {
      ringStart[v] = h;
    }
  }

  ringOffsets_.assign(static_cast<size_t>(vertexCount) + 1, 0);
  ringNeighbors_.reserve(static_cast<size_t>(H + vertexCount));
  ringEdges_.reserve(static_cast<size_t>(H + vertexCount));
  ringFaces_.reserve(static_cast<size_t>(H + vertexCount));
  ringCorners_.reserve(static_cast<size_t>(H + vertexCount));
  for (int v = 0; v < vertexCount; ++v) {
    const auto vs = static_cast<size_t>(v);
    if (ringStart[vs] < 0) {
      std::ostringstream s;
      s << "vertex " << v << " is not referenced by any face";
      fail(sourceName, s.str());
    }
    int facesSeen = 0;
    int h = ringStart[vs];
    while (true) {
      ringNeighbors_.push_back(halfedgeHead(h));
      ringEdges_.push_back(halfedgeEdges_[static_cast<size_t>(h)]);
      ringFaces_.push_back(h / 3);
      ringCorners_.push_back(static_cast<signed char>(h % 3));  // h leaves v: v = faces(h / 3, h % 3)
      ++facesSeen;
      const int p = prev(h);  // (k -> v) in the same face
      const int t = halfedgeTwins_[static_cast<size_t>(p)];
      if (t < 0) {  // reached the other boundary edge: close the fan
        ringNeighbors_.push_back(halfedgeTail(p));
        ringEdges_.push_back(halfedgeEdges_[static_cast<size_t>(p)]);
        ringFaces_.push_back(-1);
        ringCorners_.push_back(-1);
        break;
      }
      h = t;
      if (h == ringStart[vs] || facesSeen > cornerCount[vs]) break;
    }
    if (facesSeen != cornerCount[vs]) {
      std::ostringstream s;
      s << "non-manifold vertex " << v << ": its " << cornerCount[vs]
        << " faces form more than one fan (one fan has " << facesSeen << ")";
      fail(sourceName, s.str());
    }
    ringOffsets_[vs + 1] = static_cast<int>(ringNeighbors_.size());
  }

  // Boundary loops, surface on the left: follow twin-less half-edges head to
  // the ring start (the twin-less outgoing half-edge) of the head vertex.
  std::vector<char> visited(static_cast<size_t>(H), 0);
  for (int h0 = 0; h0 < H; ++h0) {
    if (halfedgeTwins_[static_cast<size_t>(h0)] >= 0 || visited[static_cast<size_t>(h0)]) continue;
    std::vector<int> loop;
    for (int h = h0; !visited[static_cast<size_t>(h)];
         h = ringStart[static_cast<size_t>(halfedgeHead(h))]) {
      visited[static_cast<size_t>(h)] = 1;
      loop.push_back(halfedgeTail(h));
    }
    boundaryLoops_.push_back(std::move(loop));
  }
}

}  // namespace blot::stain
