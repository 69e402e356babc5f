#pragma once
/// Stage "diffuse", last part (ctx.switches.diffusiveMomentum): the liquid
/// that the density diffusion moves carries its velocity with it
/// (docs/transport.md, "Momentum carried by the diffusive flux").
///
/// The paper advects u as a field of its own and diffuses the densities
/// without it. Where the density diffusion refills a vertex that advection
/// empties, the two disagree: liquid pressed against the boundary wall
/// diffuses back up the slope every step, advection carries it down again,
/// and the vertex one ring from the wall keeps an ever larger u (g t after
/// t seconds) that moves no liquid: kinetic energy out of nothing. With the
/// mass flux of each edge carrying its upwind velocity, the refilled liquid
/// arrives with the pile's velocity and the vertex's u stays bounded.
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/stages/liquid_band.h>

#include <vector>

namespace blot::stain {

/// carryMomentumWithDiffusion's scratch, sized once (resize); a call
/// refills it without allocating.
struct DiffusiveMomentumScratch {
  ComplexVector values;               ///< #V: the band's new u
  std::vector<int> front;             ///< the front (capacity #V)
  std::vector<char> frontMarks;       ///< #V: 1 on the front during a call
  std::vector<int> stiffnessEntries;  ///< per ring entry: its position in L's column (−1: not filled / none)
  void resize(int vertexCount, int ringEntries);
};

/// After (M + h L_Sf) ρ⁺ = M ρ (ρ = σ_f + σ_s, the free liquid), the mass
/// that crossed from vertex j to vertex i is F_ji = h (−L_ij)(ρ⁺_j − ρ⁺_i)
/// (exact for backward Euler: Σ_j F_ji = A_i (ρ⁺_i − ρ_i); the explicit and
/// the restricted solves and the positivity limiter make it an estimate).
/// At each vertex i whose free liquid passes ctx.liquid.wetThreshold (below
/// it liquid counts as none: a trace keeps the band's extended u), the mass
/// that came in, in_i = Σ_j max(F_ji, 0), brings j's velocity (carried into
/// i's frame, LiquidBand::ringTransports); the liquid i kept,
/// k_i = A_i ρ⁺_i − in_i (= A_i ρ_i − out_i), keeps i's:
///
///     u_i ← (k_i u_i + Σ_j max(F_ji, 0) e^{iθ_ij} u_j) / (k_i + in_i),
///
/// each u_j the velocity j sent: where j kept liquid (k_j > 0), the u it had.
/// A vertex the liquid reached this step (k_i ≤ 0: it passed on all it held
/// and more) is the front: it sent the mix of what it held and what came in,
/// which is its new u,
///
///     u_i ← (A_i ρ_i u_i + Σ_j max(F_ji, 0) e^{iθ_ij} u_j) / (A_i ρ_i + in_i),
///
/// from the u its senders sent (the front is done first, wettest first; the
/// rest reads it). So each new u_i is a convex combination of velocities the
/// liquid had (the largest |u| and the kinetic energy do not grow), a
/// uniform flow on a flat sheet is unchanged, the result does not depend on
/// the numbering, and with exact fluxes (a direct backward Euler solve) the
/// liquid's momentum on a flat sheet is conserved but for the traces.
/// `beyondBand` (optional): vertices the diffusion wrote outside the reach
/// set (StainSolver's list); those of them outside the band whose free
/// liquid passes the threshold had no u any stage defined, so each takes
/// what came in, from the wettest down (the list is reordered: those first,
/// sorted). Other vertices outside the band, and traces, keep their u.
/// Deterministic, one thread, allocates nothing. Returns how many vertices
/// changed.
int carryMomentumWithDiffusion(const StepContext& ctx, const SurfaceTopology& topology,
                               const IntrinsicGeometry& intrinsic, LiquidBand& band, DiffusiveMomentumScratch& scratch,
                               StainState& state, std::vector<int>* beyondBand = nullptr);

}  // namespace blot::stain
