// The per-face fabric the geometry cache and the stages read.
#include <blot/stain/fabric/fabric_field.h>

#include <blot/stain/geometry/operators.h>

#include <stdexcept>

namespace blot::stain {

FabricField isotropicFabricField(int faceCount, double densityDiffusivity, double viscosity) {
  if (faceCount < 1 || !(densityDiffusivity >= 0) || !(viscosity >= 0))
    throw std::invalid_argument("isotropicFabricField: need faceCount >= 1 and finite, non-negative coefficients");
  FabricField fabric;
  fabric.densityTensors = densityDiffusivity * identityFaceTensors(faceCount);
  fabric.velocityTensors = viscosity * identityFaceTensors(faceCount);
  fabric.weftDirections = RowVectors3::Zero(faceCount, 3);
  return fabric;
}

}  // namespace blot::stain
