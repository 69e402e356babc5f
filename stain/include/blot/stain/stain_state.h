#pragma once
/// The stain's simulation state: one contiguous array per field, indexed by
/// vertex (struct of arrays). Densities are surface densities in kg/m²; the
/// mass a vertex holds is density × its dual area (IntrinsicGeometry).
#include <blot/stain/types.h>

namespace blot::stain {

struct StainState {
  /// #V tangential liquid velocity in the vertex frame F_i, as the complex
  /// number u_x + i u_y (m/s). Rotating by θ is multiplying by exp(iθ).
  ComplexVector velocities;
  Vector solvent;          ///< #V σ_f, free solvent (kg/m²).
  Vector solute;           ///< #V σ_s, free (dissolved) solute (kg/m²).
  Vector absorbedSolvent;  ///< #V σ_p, solvent held in the fibres (kg/m²).
  Vector absorbedSolute;   ///< #V σ_s,p, solute absorbed with it (kg/m²).
  Vector adsorbedSolute;   ///< #V σ_s,a, solute deposited on the fibres (kg/m²).
  double evaporatedSolvent = 0;  ///< kg evaporated so far (free + absorbed).
  double addedSolvent = 0;       ///< kg added so far by sources and drops.
  double addedSolute = 0;        ///< kg added so far by sources and drops.

  /// Zero state for `vertexCount` vertices (allocates; call at build time).
  void resize(int vertexCount);
  int vertexCount() const { return static_cast<int>(solvent.size()); }
};

}  // namespace blot::stain
