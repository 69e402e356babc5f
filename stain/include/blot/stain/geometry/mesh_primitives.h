#pragma once
/// Meshes built in code: rectangular grids (flags, tablecloths), icospheres
/// (analytic tests), discs. Each returns a validated, counter-clockwise mesh.
#include <blot/stain/geometry/triangle_mesh.h>

namespace blot::stain {

/// Rectangle [0, width] x [0, height] in the z = 0 plane with (nx + 1) x (ny + 1)
/// vertices, row-major (vertex (i, j) at index j * (nx + 1) + i), each quad split
/// along alternating diagonals. UVs are (x / width, y / height). Normal +z.
TriangleMesh gridMesh(int nx, int ny, double width, double height);

/// Unit-radius icosphere: the icosahedron with each triangle split into four
/// `level` times and vertices projected to the sphere. Level L has
/// 10 * 4^L + 2 vertices.
TriangleMesh icosphereMesh(int level, double radius = 1.0);

/// Disc of `radius` in the z = 0 plane, `rings` concentric rings of vertices,
/// 6 * r vertices on ring r (a hexagonal-ish triangulation).
TriangleMesh discMesh(int rings, double radius);

}  // namespace blot::stain
