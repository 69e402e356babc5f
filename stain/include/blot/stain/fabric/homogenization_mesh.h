#pragma once
/// Triangle meshes of a periodic weave tile (a torus of rows x cols unit cells)
/// for the homogenization cell problems: the uniform "union jack" mesh and a
/// mesh geometrically graded toward every lattice corner, where cell corners
/// meet and the cell-problem solutions are singular (docs/patterns.md).
#include <blot/stain/types.h>

#include <array>
#include <vector>

namespace blot::stain {

/// A conforming P1 mesh of the tile torus. Cell units: each cell is the unit
/// square. Positions are stored per triangle corner relative to an anchor of
/// that triangle (a square's corner, or the lattice corner a graded quarter
/// belongs to), so elements graded down to 1e-60 cells keep full relative
/// precision and the torus needs no wrapped coordinates; every formula used
/// (stiffness, ∫∇x_i) depends only on differences inside one triangle.
struct CellMesh {
  int vertexCount = 0;
  std::vector<std::array<int, 3>> triangleVertices;         ///< #T, vertex ids in [0, vertexCount)
  std::vector<Eigen::Matrix<double, 3, 2>> triangleCorners; ///< #T, corner k = row k, cell units, per-triangle anchor
  std::vector<int> triangleCells;  ///< #T, cell index row·cols + col (file row 0 = top of the tile)
  /// Graded meshes: per triangle, its lattice corner (j·cols + i for the corner at
  /// x = i, y = j) and its ring (0 = outermost layer ... ringCount − 1 = the fan
  /// around the corner), for the energy-per-ring indicator. Empty for uniform meshes.
  std::vector<int> triangleLatticeCorners;
  std::vector<int> triangleRings;
  int ringCount = 0;
  int latticeCornerCount = 0;
  int raysPerSide = 0;  ///< Graded meshes: GradedMeshLevel::raysPerSide.
};

/// The uniform mesh: each cell K x K squares, each square two triangles along
/// alternating diagonals (even K: invariant under 90° rotations and axis
/// reflections). rows·cols·K² vertices.
CellMesh uniformCellMesh(int rows, int cols, int subdivisions);

/// Parameters of the graded mesh. Each cell is split into four quarters, one
/// per corner; quarter (with the corner at its origin, [0, ½]²) is covered by
/// rays from the corner to 2·raysPerSide + 1 points spaced evenly along its two
/// far sides, cut by `layers` square rings at L∞ radius s_ℓ = ½·σ^ℓ with
/// σ = exp(−1/raysPerSide) (ring thickness ≈ ray spacing, so elements stay
/// shape-regular at every scale), and a fan of triangles around the corner
/// inside the innermost ring, of radius ½·σ^layers.
struct GradedMeshLevel {
  int raysPerSide = 1;  ///< m ≥ 1: rays per far side of a quarter (2m intervals per cell side).
  int layers = 1;       ///< L ≥ 1: rings between the cell midlines and the innermost fan.
};

/// σ = exp(−1/m), the ratio of consecutive ring radii.
double gradedRingRatio(int raysPerSide);
/// The fewest layers whose innermost radius ½σ^L is at most `innerRadius` (cells, > 0).
int gradedLayersFor(int raysPerSide, double innerRadius);
/// Innermost radius ½σ^L of a level (cells).
double gradedInnerRadius(const GradedMeshLevel& level);
/// Vertices of the graded mesh, 4·rows·cols·m·(2L + 1), without building it.
long gradedVertexCount(int rows, int cols, const GradedMeshLevel& level);

/// The graded mesh (vertex count as gradedVertexCount). Conforming: quarters
/// across a cell edge or a cell midline are mirror images, so their nodes match.
CellMesh gradedCellMesh(int rows, int cols, const GradedMeshLevel& level);

}  // namespace blot::stain
