// Meshes built in code for tests, benchmarks and demo scenes.
//
// Design note: grids alternate their diagonals so the discrete operators have
// no preferred diagonal direction (a one-way split biases anisotropic
// diffusion along it). Icosphere midpoints are found through a sorted edge
// list, not a hash map, so vertex numbering is deterministic.
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <stdexcept>

namespace blot::stain {

TriangleMesh gridMesh(int nx, int ny, double width, double height) {
  if (nx < 1 || ny < 1 || !(width > 0) || !(height > 0))
    throw std::invalid_argument("gridMesh: need nx, ny >= 1 and positive width, height");
  TriangleMesh mesh;
  const int vx = nx + 1;
  mesh.vertexPositions.resize(vx * (ny + 1), 3);
  mesh.vertexUVs.resize(vx * (ny + 1), 2);
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const int v = j * vx + i;
      const double u = static_cast<double>(i) / nx, w = static_cast<double>(j) / ny;
      mesh.vertexPositions.row(v) << u * width, w * height, 0.0;
      mesh.vertexUVs.row(v) << u, w;
    }
  }
  mesh.faces.resize(2 * nx * ny, 3);
  int f = 0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const int v00 = j * vx + i, v10 = v00 + 1, v01 = v00 + vx, v11 = v01 + 1;
      if ((i + j) % 2 == 0) {
        mesh.faces.row(f++) << v00, v10, v11;
        mesh.faces.row(f++) << v00, v11, v01;
      } else {
        mesh.faces.row(f++) << v00, v10, v01;
        mesh.faces.row(f++) << v10, v11, v01;
      }
    }
  }
  return mesh;
}

TriangleMesh icosphereMesh(int level, double radius) {
  if (level < 0 || level > 8 || !(radius > 0))
    throw std::invalid_argument("icosphereMesh: need 0 <= level <= 8 and radius > 0");
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vector3> points = {
      {-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
      {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> tris = {
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& p : points) p.normalize();
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int, int>, int> midpoints;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      points.push_back((points[static_cast<size_t>(a)] + points[static_cast<size_t>(b)]).normalized());
      const int m = static_cast<int>(points.size()) - 1;
      midpoints.emplace(key, m);
      return m;
    };
    std::vector<std::array<int, 3>> refined;
    refined.reserve(tris.size() * 4);
    for (const auto& tri : tris) {
      const int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      refined.push_back({tri[0], a, c});
      refined.push_back({tri[1], b, a});
      refined.push_back({tri[2], c, b});
      refined.push_back({a, b, c});
    }
    tris.swap(refined);
  }
  TriangleMesh mesh;
  mesh.vertexPositions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t v = 0; v < points.size(); ++v)
    mesh.vertexPositions.row(static_cast<Eigen::Index>(v)) = radius * points[v].transpose();
  mesh.faces.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f)
    mesh.faces.row(static_cast<Eigen::Index>(f)) << tris[f][0], tris[f][1], tris[f][2];
  return mesh;
}

TriangleMesh discMesh(int rings, double radius) {
  if (rings < 1 || !(radius > 0)) throw std::invalid_argument("discMesh: need rings >= 1, radius > 0");
  const double pi = 3.14159265358979323846;
  std::vector<Vector3> points = {Vector3::Zero()};
  std::vector<int> ringFirst = {0};
  for (int r = 1; r <= rings; ++r) {
    ringFirst.push_back(static_cast<int>(points.size()));
    const int n = 6 * r;
    for (int k = 0; k < n; ++k) {
      const double a = 2.0 * pi * k / n, rr = radius * r / rings;
      points.emplace_back(rr * std::cos(a), rr * std::sin(a), 0.0);
    }
  }
  std::vector<std::array<int, 3>> tris;
  for (int k = 0; k < 6; ++k) tris.push_back({0, 1 + k, 1 + (k + 1) % 6});
  for (int r = 2; r <= rings; ++r) {
    const int ni = 6 * (r - 1), no = 6 * r;
    const int fi = ringFirst[static_cast<size_t>(r - 1)], fo = ringFirst[static_cast<size_t>(r)];
    int a = 0, b = 0;
    // Merge the two rings by angle: advance the ring whose next vertex comes first.
    while (a < ni || b < no) {
      const double nextInner = static_cast<double>(a + 1) / ni;
      const double nextOuter = static_cast<double>(b + 1) / no;
      if (b < no && (a >= ni || nextOuter <= nextInner)) {
        tris.push_back({fi + a % ni, fo + b, fo + (b + 1) % no});
        ++b;
      } else {
        tris.push_back({fi + a % ni, fo + b % no, fi + (a + 1) % ni});
        ++a;
      }
    }
  }
  TriangleMesh mesh;
  mesh.vertexPositions.resize(static_cast<Eigen::Index>(points.size()), 3);
  mesh.vertexUVs.resize(static_cast<Eigen::Index>(points.size()), 2);
  for (size_t v = 0; v < points.size(); ++v) {
    mesh.vertexPositions.row(static_cast<Eigen::Index>(v)) = points[v].transpose();
    mesh.vertexUVs.row(static_cast<Eigen::Index>(v)) << 0.5 + 0.5 * points[v].x() / radius,
        0.5 + 0.5 * points[v].y() / radius;
  }
  mesh.faces.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) {
    auto tri = tris[f];
    const Vector3 n = (points[static_cast<size_t>(tri[1])] - points[static_cast<size_t>(tri[0])])
                          .cross(points[static_cast<size_t>(tri[2])] - points[static_cast<size_t>(tri[0])]);
    if (n.z() < 0) std::swap(tri[1], tri[2]);  // keep every triangle counter-clockwise (+z)
    mesh.faces.row(static_cast<Eigen::Index>(f)) << tri[0], tri[1], tri[2];
  }
  return mesh;
}

}  // namespace blot::stain
