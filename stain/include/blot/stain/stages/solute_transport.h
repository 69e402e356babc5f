#pragma once
/// Stage "diffuse", the solute's part in the film model
/// (PhysicsSwitches::soluteWithSolvent; docs/transport.md, "Solute carried by
/// the solvent"): the density diffusion moves the free liquid as one
/// solution, and the dissolved solute goes where that liquid's flux takes it,
/// plus a molecular diffusion D_m of its own inside the liquid.
///
/// The paper diffuses solute with the fabric's tensor exactly as it diffuses
/// solvent (eqs. 4-5). That tensor is a capillary wicking coefficient, about
/// 10⁷ times a molecule's diffusivity in water: it smooths the solute's
/// concentration across the stain within seconds, so nothing carries solute
/// to a drying edge and no tide line forms. Here the wicking flux carries the
/// solution, concentration and all, and only D_m evens out concentrations.
///
/// Symbols (SI): ρ = σ_f + σ_s the free liquid (kg/m²); c = σ_s/ρ the solute's
/// mass fraction; A_i the dual area (m²); L the density stiffness
/// (IntrinsicGeometry::densityStiffness); D_m the solute's molecular
/// diffusivity (LiquidParameters::molecularDiffusivity, m²/s).
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>

#include <vector>

namespace blot::stain {

/// The solute pass's scratch, sized once (resize); a step allocates nothing.
struct SoluteTransportScratch {
  Vector heldLiquid;                  ///< #V: ρ before the diffusion, on the vertices held
  Vector concentrations;              ///< #V: c during a pass (0 elsewhere)
  Vector passed;                      ///< #V: S_i = A_i ρ_i + in_i (kg)
  Vector sentShare;                   ///< #V: θ_i, the share of i's outflow that carries solute
  Vector diagonals;                   ///< #V: S_i + Σ_j d_ij
  Vector couplings;                   ///< per ring entry: what j's c adds to i's solute (kg)
  std::vector<int> vertices;          ///< the pass's vertices, in index order (capacity #V)
  std::vector<char> listed;           ///< #V: 1 on `vertices` during a pass
  std::vector<int> stiffnessEntries;  ///< per ring entry: its position in L's column (−1: none / not filled)
  void resize(int vertexCount, int ringEntries);
};

/// What a pass did (StepProfile reads it).
struct SoluteTransportReport {
  int vertices = 0;        ///< vertices whose concentration was solved for
  int sweeps = 0;          ///< Gauss–Seidel sweeps (the last one changed nothing)
  bool converged = true;   ///< false: stopped at the sweep cap, last iterate used
  double massFactor = 1;   ///< the conserving rescale applied (1 to rounding with exact fluxes)
};

/// Before the density diffusion: remembers ρ_i on `band` and writes the free
/// liquid into the solvent slot, σ_f ← σ_f + σ_s, so that the diffusion
/// (which then leaves σ_s alone: diffuse() skips the solute under
/// soluteWithSolvent) moves the solution as one field.
void holdLiquidForSoluteTransport(const std::vector<int>& band, StainState& state, SoluteTransportScratch& scratch);

/// After the diffusion, which left ρ⁺ in the solvent slot and σ_s as it was:
/// splits ρ⁺ back into σ_f and σ_s. The mass that crossed edge ij is
/// F_ji = h (−L_ij)(ρ⁺_j − ρ⁺_i) (exact for backward Euler; see
/// carryMomentumWithDiffusion). Each vertex is a mixing tank over the step:
/// what it held, A_i ρ_i at c_i⁰ = σ_s,i/ρ_i, and what came in,
/// in_i = Σ_j max(F_ji, 0), each sender's liquid at the sender's c; its
/// outflow leaves at its mixed c_i. So
///
///   S_i c_i − Σ_j θ_j max(F_ji, 0) c_j + Σ_j d_ij (c_i − c_j) = A_i σ_s,i,
///   S_i = A_i ρ_i + in_i,   d_ij = h D_m w_ij min(ρ⁺_i, ρ⁺_j),
///
/// with w_ij = max(0, ½(cot α + cot β)) the isotropic P1 weights (molecular
/// diffusion inside the liquid, its flux −D_m ρ ∇c; no exchange across a side
/// without liquid) and θ_j = min(1, S_j/out_j) (1 with exact fluxes: a tank
/// cannot send more than passed through it). The matrix is an M-matrix,
/// diagonally dominant by rows and columns, so c stays within the range of
/// the concentrations it started from (a uniform c is kept to rounding) and
/// the solute is conserved. One concentration held everywhere is the
/// solution as it is; otherwise symmetric Gauss–Seidel in index order solves
/// it until a sweep changes no c by more than 1e-13 relative (at most 200
/// sweeps). Then σ_s⁺ = c ρ⁺ × the factor that restores the solute's
/// mass exactly (1 to rounding with exact fluxes; the positivity limiter
/// and the restricted solves make fluxes estimates), at most ρ⁺, and
/// σ_f⁺ = ρ⁺ − σ_s⁺. Visits `band` (held before) and `beyondBand` (vertices
/// the diffusion gave liquid past the band: they held none). One thread,
/// deterministic, no allocation.
SoluteTransportReport carrySoluteWithSolvent(const StepContext& ctx, const SurfaceTopology& topology,
                                             const IntrinsicGeometry& intrinsic, const std::vector<int>& band,
                                             const std::vector<int>& beyondBand, SoluteTransportScratch& scratch,
                                             StainState& state);

}  // namespace blot::stain
