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
  ComplexVector values;               ///< #V: the band's new u until the pass ends
  std::vector<int> order;             ///< the vertices past the band, wettest first (capacity #V)
  std::vector<char> done;             ///< #V: 1 on those mixed so far during a call
  std::vector<int> stiffnessEntries;  ///< per ring entry: its position in L's column (−1: not filled / none)
  void resize(int vertexCount, int ringEntries);
};

/// After (M + h L_Sf) ρ⁺ = M ρ (ρ = σ_f + σ_s, the free liquid), the mass
/// that crossed from vertex j to vertex i is F_ji = h (−L_ij)(ρ⁺_j − ρ⁺_i)
/// (exact for backward Euler: Σ_j F_ji = A_i (ρ⁺_i − ρ_i); the explicit and
/// the restricted solves and the positivity limiter make it an estimate).
/// Each vertex holding free liquid after the diffusion mixes what it held
/// before it, A_i ρ_i = A_i ρ⁺_i − in_i + out_i (at least A_i × wetThreshold,
/// so that u moves continuously from the band's extended value as liquid
/// first arrives), at its own u, with what came in, in_i = Σ_j max(F_ji, 0),
/// each sender's liquid at its u:
///
///     u_i ← (A_i ρ_i u_i + Σ_j max(F_ji, 0) (e^{iθ_ij} u_j + Δv_ji)) / (A_i ρ_i + in_i),
///
/// every u_j from before the pass (the result depends neither on the
/// numbering nor on the order, and is continuous in the densities).
/// e^{iθ_ij} carries j's frame into i's (LiquidBand::ringTransports); on a
/// moving cloth (`moving`: the extrinsic tier of a surface that moved this
/// step, else null) u is relative to the cloth, and Δv_ji is the difference
/// of the two vertices' surface velocities (chord over the step) in i's
/// frame at t + h, as the band's extension and the advection's frame change
/// add it. So every new u_i is a convex combination of velocities the liquid
/// had (neither the largest world speed nor the kinetic energy grows), a
/// uniform flow, on a still or a moving cloth, is unchanged, and the
/// liquid's momentum is conserved but for liquid that crossed two edges in
/// the step (a sender's u is the one it had, not the mix it passed on).
/// `beyondBand` (optional): vertices the diffusion wrote outside the reach
/// set (StainSolver's list); those of them outside the band that hold free
/// liquid had no u any stage defined: their own liquid counts for nothing,
/// each takes what came in (no Δv: their frames are not this step's), the
/// wettest first so that one two vertices past the band reads the one
/// between as it now is. Other vertices outside the band keep their u.
/// Deterministic, one thread, allocates nothing. Returns how many vertices
/// changed.
int carryMomentumWithDiffusion(const StepContext& ctx, const SurfaceTopology& topology,
                               const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry* moving, LiquidBand& band,
                               DiffusiveMomentumScratch& scratch, StainState& state,
                               const std::vector<int>* beyondBand = nullptr);

}  // namespace blot::stain
