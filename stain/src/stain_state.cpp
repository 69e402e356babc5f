// The stain state's storage (struct of arrays, one vector per field).
//
// Design note: resize allocates every field at once and zeroes it, including
// the running totals, so a state is either fully sized for a mesh or empty;
// the step never resizes (no allocation inside step).
#include <blot/stain/stain_state.h>

#include <stdexcept>

namespace blot::stain {

void StainState::resize(int vertexCount) {
  if (vertexCount < 0) throw std::invalid_argument("StainState::resize: negative vertex count");
  velocities = ComplexVector::Zero(vertexCount);
  solvent = Vector::Zero(vertexCount);
  solute = Vector::Zero(vertexCount);
  absorbedSolvent = Vector::Zero(vertexCount);
  absorbedSolute = Vector::Zero(vertexCount);
  adsorbedSolute = Vector::Zero(vertexCount);
  evaporatedSolvent = 0;
  addedSolvent = 0;
  addedSolute = 0;
}

}  // namespace blot::stain
