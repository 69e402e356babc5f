#pragma once
/// Paper Fig. 4 as a reusable experiment: a Gaussian spot diffusing on a flat
/// rectangle tiled with copies of a weave pattern, computed three ways on the
/// same fine grid — (1) the per-cell tensor field, (2) the homogenized S_eff
/// everywhere, (3) the plain cell average everywhere — with implicit Euler
/// (M + hL) σ^{t+h} = M σ^t. Used by the unit test (small) and the Fig. 4
/// study (large, with images).
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/types.h>
#include <blot/stain/fabric/weave_pattern.h>

namespace blot::test {

struct TiledSpotSetup {
  int tilesX = 8, tilesY = 8;   ///< Copies of the tile across and up.
  int squaresPerCell = 2;       ///< Fine grid squares per cell side (cell interfaces on grid lines).
  double spotRadius = 4.0;      ///< Gaussian standard deviation, in cells (unit cell size).
  double duration = 1.0;        ///< Diffusion time, in (cell size)² per coefficient unit.
  int steps = 20;               ///< Implicit Euler steps.
};

struct TiledSpotResult {
  int cellsX = 0, cellsY = 0;           ///< Rectangle size in cells.
  int verticesX = 0, verticesY = 0;     ///< Grid vertices per row / column (vertex (i, j) at j·verticesX + i, y up).
  stain::Vector original, effective, average;  ///< Final densities, per vertex.
  stain::HomogenizationResult homogenized;     ///< S_eff and the average used.
  double effectiveError = 0.0;  ///< ‖σ2 − σ1‖_M / ‖σ1‖_M
  double averageError = 0.0;    ///< ‖σ3 − σ1‖_M / ‖σ1‖_M
  double massDrift = 0.0;       ///< Largest |Σ M σ − Σ M σ0| / Σ M σ0 over the three runs.
};

/// Runs the three diffusions; S_eff at the pattern's default K.
TiledSpotResult tiledSpotDiffusion(const stain::WeavePattern& pattern, const TiledSpotSetup& setup);

}  // namespace blot::test
