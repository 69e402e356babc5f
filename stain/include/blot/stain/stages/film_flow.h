#pragma once
/// The liquid as a thin viscous film on the fabric (docs/transport.md, "The
/// liquid film"): gravity and hydrostatic pressure as one potential gradient
/// (stage FilmPressure) and the film's friction with the fibres (stage
/// FilmFriction). The paper's momentum equation (eq. 3) has neither, so a
/// film that cannot flow further down accelerates without bound; these two
/// terms make a pool at the bottom of a basin a steady state.
///
/// Symbols (SI): σ_f, σ_s free solvent and solute (kg/m²); ρ the liquid's
/// density (kg/m³); H = (σ_f + σ_s)/ρ the film's thickness (m), defined
/// here once (filmThickness) and used by the pressure, the friction and the
/// energy; g the world gravity, p̈ the surface's acceleration, n the vertex
/// normal; g_n = max(0, −(g − p̈)·n) the effective gravity pressing the
/// film onto the cloth (m/s²); ν the liquid's kinematic viscosity (m²/s); λ
/// the fabric's slip length (m).
///
/// Side convention: the film lies on the side the surface normal points to
/// (the mesh's front face, where a drop lands on a cloth lying face up), so
/// gravity presses it on when (g − p̈)·n < 0. Where gravity pulls the film
/// off the cloth (under an overhang) g_n is 0: no pressure, rather than a
/// negative one that would gather the film into ridges (anti-diffusion).
#include <blot/stain/output_fields.h>
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/stages/liquid_band.h>

#include <vector>

namespace blot::stain {

/// The film's thickness H = (σ_f + σ_s)/ρ at vertex i (m).
inline double filmThickness(const StainState& state, int i, const LiquidParameters& liquid) {
  return (state.solvent[i] + state.solute[i]) / liquid.liquidDensity;
}

/// The film's drag rate k = 3ν/(H(H + 3λ)) (1/s) at thickness H > 0: the
/// depth-averaged momentum equation's −k u, from the half-parabolic profile
/// of a film with no slip at λ below the fibres and a free surface (Nusselt:
/// the steady velocity under a tangential acceleration a is a/k).
/// Infinite (returned as +inf) at H = 0.
double filmDragRate(double thickness, const LiquidParameters& liquid);

/// Whether vertex i takes part in the film terms: it holds free liquid
/// (σ_f + σ_s > 0) and is in the wet set (`wet`: LiquidBand::wetMask, the
/// vertices whose frames the step prepared).
bool isFilmVertex(const StainState& state, const std::vector<char>& wet, int i);

/// The film stages' per-vertex arrays, sized once (#V; no allocation in a step).
struct FilmScratch {
  ComplexVector accelerations;  ///< a_i = −∇φ* in F_i's tangent axes (m/s²)
  Vector heads;                 ///< g_n H at the film vertices (m²/s²)
  void resize(int vertexCount);
};

/// a_i = −∇φ* at each film vertex i of `vertices` (others: 0), in F_i's
/// tangent axes (m/s²), written to scratch.accelerations (#V, entries of other
/// vertices untouched). ∇φ* is the area-weighted mean of the P1 gradients on
/// i's faces, each written with differences φ*_j − φ_i, so a level pool (φ
/// equal at every vertex of i's faces) gives exactly 0. On i's ring the
/// height part uses i's effective gravity g − p̈_i (with linear inertia on),
/// so the surface's acceleration acts through the potential too and a film
/// on a rigidly accelerating cloth is one on a still cloth under g − p̈. Hydrostatic
/// reconstruction at the shoreline (after Audusse et al. 2004): a neighbour
/// j that holds no film counts with φ*_j = min(−g·x_j, φ_i), i.e. dry ground
/// above i's level is a wall at that level and dry ground below is a slope
/// the film runs down. Reads geometry.positions, frames (col 2 the normal)
/// and, when linear inertia acts, vertexAccelerations. Returns max |a_i|.
double filmAccelerations(const StepContext& ctx, const SurfaceTopology& topology, const ExtrinsicGeometry& geometry,
                         const StainState& state, const std::vector<char>& wet, const std::vector<int>& vertices,
                         FilmScratch& scratch);

/// u_i += h a_i at the film vertices of `vertices` (a from filmAccelerations).
void applyFilmPotential(const StepContext& ctx, const FilmScratch& scratch, const std::vector<char>& wet,
                        const std::vector<int>& vertices, StainState& state);

/// u_i ← u_i / (1 + h k(H_i)) at the film vertices of `vertices`: backward
/// Euler on du/dt = −k u, dissipative for any step (|u| only shrinks). u is
/// the liquid's velocity relative to the cloth, so the drag needs no cloth
/// velocity. Band vertices without film (velocity extended from the liquid
/// each step) are not dragged: they carry the liquid's velocity to the
/// advection's foot points, and are written again next step. Returns the
/// kinetic energy the drag took this step, Σ A_i ½ (σ_f + σ_s)(|u|² − |u⁺|²)
/// (J), with `areas` the vertex dual areas.
double applyFilmFriction(const StepContext& ctx, const Vector& areas, const std::vector<char>& wet,
                         const std::vector<int>& vertices, StainState& state);

/// The number of film sub-steps n that keep the film stable at step h. The
/// explicit kick-then-move of a film is stable where
/// (h/n)² g_n H / (ℓ² (1 + hk/n)) ≤ 1/4 at every film vertex (ℓ its
/// shortest edge, LiquidBand::Distances::shortestEdge, k the drag rate): h c/ℓ ≤ 1/2 for shallow water without
/// friction (c = √(g_n H)), h D/ℓ² ≤ 1/4 where friction dominates (the
/// lubrication equation ∂H/∂t = ∇·(D∇H), D = g_n H/k). At least 1, at most
/// `cap`; 1 without the film's pressure.
int filmSubsteps(const StepContext& ctx, const ExtrinsicGeometry& geometry, const StainState& state,
                 const LiquidBand& band, int cap);

/// The free liquid's energy (J): Σ_i A_i (½ σ_i |u_i|² − σ_i g·x_i + ½ ρ g_n,i H_i²)
/// over every vertex (σ = σ_f + σ_s; the pressure part at film vertices
/// only, where g_n is known), with `areas` the vertex dual areas.
struct FilmEnergy {
  double kinetic = 0, gravitational = 0, pressure = 0;
  double total() const { return kinetic + gravitational + pressure; }

  /// Every field, once (output_fields.h): EngineStatistics::liquidEnergy.
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static constexpr void fields(Self& s, Visitor& v) {
    v.field(outputField("kinetic", "kinetic", "J"), s.kinetic);
    v.field(outputField("gravitational", "gravitational", "J"), s.gravitational);
    v.field(outputField("pressure", "pressure", "J"), s.pressure);
  }
};
static_assert(describesEveryMember<FilmEnergy>(), "FilmEnergy changed: list the new field in FilmEnergy::fields");
FilmEnergy filmEnergy(const StepContext& ctx, const ExtrinsicGeometry& geometry, const Vector& areas,
                      const StainState& state, const std::vector<char>& wet);

/// The same energy of every vertex holding free liquid, from the positions
/// alone (#V by 3, m): g_n = max(0, −g·n) with n the area-weighted normal of
/// the vertex's faces (no p̈: the energy in the frame the cloth is at rest
/// in, for a still or slow cloth). For reports between steps (O(#V)).
FilmEnergy liquidEnergy(const Vector3& gravity, double liquidDensity, const SurfaceTopology& topology,
                        const RowVectors3& positions, const Vector& areas, const StainState& state);

}  // namespace blot::stain
