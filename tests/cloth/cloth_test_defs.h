#pragma once
// ClothDefs shared by the cloth tests: the mesh arrays come from a stain mesh
// through coupling::describeClothMesh, the way the engine builds them.
#include <blot/cloth/bullet_cloth.h>
#include <blot/coupling/coupled_surface.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>

namespace blot::cloth::fixtures {

inline ClothDef describe(const stain::TriangleMesh& mesh) {
  ClothDef def;
  const stain::SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  coupling::describeClothMesh(mesh, topology, def);
  return def;
}

inline int topLeft(int cells) { return cells * (cells + 1); }
inline int topRight(int cells) { return cells * (cells + 1) + cells; }

/// A 1 m square flag in the vertical xz-plane, top edge at z = 1, pinned at
/// its two top corners; (cells + 1)² vertices.
inline ClothDef hangingFlag(int cells) {
  stain::TriangleMesh mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  for (int i = 0; i < mesh.vertexPositions.rows(); ++i) {
    const double x = mesh.vertexPositions(i, 0), y = mesh.vertexPositions(i, 1);
    mesh.vertexPositions.row(i) << x, 0, y;
  }
  ClothDef def = describe(mesh);
  def.pins = {ClothPin{topLeft(cells), {}}, ClothPin{topRight(cells), {}}};
  return def;
}

/// A 1 m square lying flat at height z, no pins.
inline ClothDef flatSheet(int cells, double z) {
  stain::TriangleMesh mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  mesh.vertexPositions.col(2).setConstant(z);
  return describe(mesh);
}

}  // namespace blot::cloth::fixtures
