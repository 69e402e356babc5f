#pragma once
// The flag every cloth and coupling test (and the coupled-flag benchmark)
// hangs: a gridMesh of cells × cells squares, side 1 m, in the vertical
// xz-plane with its top edge at z = 1, optionally pinned at its two top
// corners, as a BulletCloth with the default (stable) settings; the mesh
// arrays come through coupling::describeClothMesh, the way the engine builds
// them. CoupledFlag adds the stain pieces.
#include <blot/cloth/bullet_cloth.h>
#include <blot/coupling/coupled_surface.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>

#include <memory>

namespace blot::test {

/// Top corners and centre vertex of the cells × cells flag.
inline int flagTopLeft(int cells) { return cells * (cells + 1); }
inline int flagTopRight(int cells) { return cells * (cells + 1) + cells; }
inline int flagCenter(int cells) { return (cells / 2) * (cells + 1) + cells / 2; }

/// The flag's rest mesh ((cells + 1)² vertices), in the xz-plane.
inline stain::TriangleMesh flagMesh(int cells) {
  stain::TriangleMesh mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  for (int i = 0; i < mesh.vertexPositions.rows(); ++i) {
    const double x = mesh.vertexPositions(i, 0), y = mesh.vertexPositions(i, 1);
    mesh.vertexPositions.row(i) << x, 0, y;
  }
  return mesh;
}

/// A ClothDef with the default settings on `mesh`.
inline cloth::ClothDef describeCloth(const stain::TriangleMesh& mesh) {
  cloth::ClothDef def;
  const stain::SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  coupling::describeClothMesh(mesh, topology, def);
  return def;
}

/// The flag as a bare cloth, pinned at its two top corners.
inline cloth::ClothDef hangingFlag(int cells) {
  cloth::ClothDef def = describeCloth(flagMesh(cells));
  def.pins = {cloth::ClothPin{flagTopLeft(cells), {}}, cloth::ClothPin{flagTopRight(cells), {}}};
  return def;
}

/// A 1 m square lying flat at height z, no pins.
inline cloth::ClothDef flatSheet(int cells, double z) {
  stain::TriangleMesh mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  mesh.vertexPositions.col(2).setConstant(z);
  return describeCloth(mesh);
}

struct CoupledFlag {
  stain::TriangleMesh mesh;
  std::unique_ptr<stain::SurfaceTopology> topology;
  cloth::ClothDef cloth;
  stain::FabricField fabric;
  stain::StainSolverDef stain;
  int cells = 0;
  int topLeft() const { return flagTopLeft(cells); }
  int topRight() const { return flagTopRight(cells); }
  int center() const { return flagCenter(cells); }
};

/// cells × cells flag ((cells + 1)² vertices); pinned at the two top corners
/// when `pinned`. Stain: isotropic fabric, default liquid parameters.
inline CoupledFlag makeCoupledFlag(int cells, bool pinned) {
  CoupledFlag flag;
  flag.cells = cells;
  flag.mesh = flagMesh(cells);
  flag.topology = std::make_unique<stain::SurfaceTopology>(flag.mesh.faces,
                                                           static_cast<int>(flag.mesh.vertexPositions.rows()));
  coupling::describeClothMesh(flag.mesh, *flag.topology, flag.cloth);
  if (pinned) flag.cloth.pins = {{flag.topLeft(), {}}, {flag.topRight(), {}}};
  flag.fabric = stain::isotropicFabricField(static_cast<int>(flag.mesh.faces.rows()), 1e-4, 1e-4);
  return flag;
}

/// The flag as a CoupledSurface on a BulletCloth built from flag.cloth.
/// The heavy stain the coupling tests put on the flag: a drop of 0.3 kg
/// solvent (twice the cloth's 0.15 kg at 49 cells) and 0.03 kg solute,
/// radius 0.25 m, at the centre vertex.
inline stain::DropDef heavyCentreDrop(const CoupledFlag& flag) {
  stain::DropDef drop;
  drop.centerVertex = flag.center();
  drop.radius = 0.25;
  drop.solventMass = 0.3;
  drop.soluteMass = 0.03;
  return drop;
}

inline std::unique_ptr<coupling::CoupledSurface> makeCoupledSurface(
    const CoupledFlag& flag, coupling::CouplingMode mode,
    coupling::RelativeMomentum relative = coupling::RelativeMomentum::Dragged) {
  return std::make_unique<coupling::CoupledSurface>(std::make_unique<cloth::BulletCloth>(flag.cloth), *flag.topology,
                                                    flag.fabric, flag.stain, mode, relative);
}

}  // namespace blot::test
