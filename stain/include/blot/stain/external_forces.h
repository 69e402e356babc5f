#pragma once
/// Stage "forces" (paper sec. 4): tangential gravity, linear inertia −Fᵀp̈ and
/// Coriolis −2ω×u, applied to the velocity of wet vertices.
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/surface_geometry.h>

namespace blot::stain {

/// u_i += h · tangential part, in frame F_i^t, of (g − p̈_i) (each term as
/// switched on), then the Coriolis term: with ω_n = ω_i·z (frame coordinates),
/// ExactRotation multiplies u_i by exp(−2iω_n h) (|u| preserved), Explicit adds
/// −2h ω_n (i u_i) (|u| grows by √(1 + 4ω_n²h²) each step; comparison only).
/// `wet` (#V, nonzero = wet) restricts the work; pass an empty vector for all.
void applyExternalForces(const StepContext& ctx, const ExtrinsicGeometry& geometry,
                         const std::vector<char>& wet, StainState& state);

}  // namespace blot::stain
