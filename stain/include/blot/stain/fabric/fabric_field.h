#pragma once
/// The per-face fabric of a surface: diffusion tensors and weft directions.
#include <blot/stain/types.h>

namespace blot::stain {

/// Per-face fabric: tensors in the fabric basis (s_ww, s_wp, s_pp) and weft
/// directions (operators.h). One set for the densities (S_f), one for the
/// velocity (S_v).
struct FabricField {
  Eigen::MatrixX3d densityTensors;   ///< #F by 3 (m²/s), S_f
  Eigen::MatrixX3d velocityTensors;  ///< #F by 3 (m²/s), S_v
  RowVectors3 weftDirections;        ///< #F by 3, in the rest shape
};

/// The same isotropic tensors on every face: densityDiffusivity·I for the
/// densities, viscosity·I for the velocity (m²/s); weft directions zero
/// (isotropic faces ignore the weft, see operators.h). faceCount >= 1.
FabricField isotropicFabricField(int faceCount, double densityDiffusivity, double viscosity);

}  // namespace blot::stain
