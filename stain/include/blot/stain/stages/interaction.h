#pragma once
/// Stage "interact" (paper sec. 5): absorption into the fibres, absorbed solute,
/// Langmuir adsorption of solute, and evaporation with the boundary factor.
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>

namespace blot::stain {

/// Per-vertex closed-form-consistent updates (each as switched on):
///  absorption  σ_p += min(K_p h/(1 + K_p h) (σ_sat − σ_p), σ_f), σ_f -= same;
///              σ_s,p += (absorbed solvent) · σ_s/σ_f, σ_s -= same;
///  adsorption  σ_s,a += min(K_d h/(1 + K_d h)(A_d − σ_s,a), σ_s) (desorption
///              when σ_s,a > A_d returns solute to σ_s);
///  evaporation σ_f -= min(a K_evap h, σ_f) with a = a_evap on boundary vertices
///              and 1 inside (with EvaporationBoundary::WetFront also on
///              vertices whose `wet` value is 2, "holds liquid", next to one
///              that is not: the liquid's own edge); the remainder from σ_p
///              when σ_f runs out;
///              the evaporated mass (× dual area) is added to state.evaporatedSolvent
///              and, when `evaporatedMass` (#V, kg) is given, written per
///              vertex at the vertices processed (the caller zeroes the rest);
///  drying      solute left with no free solvent is deposited (moved to σ_s,a),
///              and desorption needs free solvent to dissolve into.
/// Solute is conserved exactly (moved between its three pools, never created).
/// Processed: the vertices `wet` marks (all when empty) and those with σ_p > 0.
/// among (optional, with a `wet` mask): the vertices visited instead of all
/// #V, in increasing index order, a superset of those processed (the
/// evaporated total is then summed in the same order, the same bits).
/// soaked (optional, #V): vertices that hold liquid although `wet` does not
/// mark them 2 (LiquidBand::soakedMask), for the wet-front test.
void interact(const StepContext& ctx, const SurfaceTopology& topology, const IntrinsicGeometry& geometry,
              const std::vector<char>& wet, StainState& state, Vector* evaporatedMass = nullptr,
              const std::vector<int>* among = nullptr, const std::vector<char>* soaked = nullptr);

}  // namespace blot::stain
