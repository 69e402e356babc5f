#pragma once
/// Stage "pressure" (paper eq. (3), the −∇p_ext/ρ term the paper ignores):
/// hydrostatic pressure of the free liquid film, which pushes liquid from
/// thick to thin regions. Off by default (PhysicsSwitches::filmPressure).
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>

namespace blot::stain {

/// u_i += −h (g_n,i / ρ) ∇σ_f at each vertex the `wet` mask marks (empty: all),
/// in frame F_i^t. p = ρ g_n H with film height H = σ_f / ρ (the shallow-water
/// pressure of the paper's ref. [23]), so −∇p/ρ = −(g_n/ρ) ∇σ_f; g_n = |g · n_i|
/// (m/s²), ρ = LiquidParameters::liquidDensity (kg/m³), ∇σ_f the area-weighted
/// average of the P1 face gradients over the one-ring (kg/m³). Reads
/// geometry.positions, frames and vertexNormals; writes state.velocities only.
void applyFilmPressure(const StepContext& ctx, const SurfaceTopology& topology, const ExtrinsicGeometry& geometry,
                       const std::vector<char>& wet, StainState& state);

}  // namespace blot::stain
