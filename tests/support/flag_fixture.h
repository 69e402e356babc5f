#pragma once
// A square flag for the coupling tests and the coupled-flag benchmark: a
// gridMesh of cells × cells squares, side 1 m, in the vertical xz-plane with
// its top edge at z = 1, optionally pinned at its two top corners, as a
// BulletCloth with the default (stable) settings, plus the stain pieces.
#include <blot/cloth/bullet_cloth.h>
#include <blot/coupling/coupled_surface.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>

#include <memory>

namespace blot::test {

struct CoupledFlag {
  stain::TriangleMesh mesh;
  std::unique_ptr<stain::SurfaceTopology> topology;
  cloth::ClothDef cloth;
  stain::FabricField fabric;
  stain::StainSolverDef stain;
  int cells = 0;
  int topLeft() const { return cells * (cells + 1); }
  int topRight() const { return cells * (cells + 1) + cells; }
  int center() const { return (cells / 2) * (cells + 1) + cells / 2; }
};

/// cells × cells flag ((cells + 1)² vertices); pinned at the two top corners
/// when `pinned`. Stain: isotropic fabric, default liquid parameters.
inline CoupledFlag makeCoupledFlag(int cells, bool pinned) {
  CoupledFlag flag;
  flag.cells = cells;
  flag.mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  for (int i = 0; i < flag.mesh.vertexPositions.rows(); ++i) {
    const double x = flag.mesh.vertexPositions(i, 0), y = flag.mesh.vertexPositions(i, 1);
    flag.mesh.vertexPositions.row(i) << x, 0, y;
  }
  flag.topology = std::make_unique<stain::SurfaceTopology>(flag.mesh.faces,
                                                           static_cast<int>(flag.mesh.vertexPositions.rows()));
  coupling::describeClothMesh(flag.mesh, *flag.topology, flag.cloth);
  if (pinned) flag.cloth.pins = {{flag.topLeft(), {}}, {flag.topRight(), {}}};
  flag.fabric = stain::isotropicFabricField(static_cast<int>(flag.mesh.faces.rows()), 1e-4, 1e-4);
  return flag;
}

/// The flag as a CoupledSurface on a BulletCloth built from flag.cloth.
inline std::unique_ptr<coupling::CoupledSurface> makeCoupledSurface(
    const CoupledFlag& flag, coupling::CouplingMode mode,
    coupling::RelativeMomentum relative = coupling::RelativeMomentum::Dragged) {
  return std::make_unique<coupling::CoupledSurface>(std::make_unique<cloth::BulletCloth>(flag.cloth), *flag.topology,
                                                    flag.fabric, flag.stain, mode, relative);
}

}  // namespace blot::test
