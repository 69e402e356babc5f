#pragma once
/// Stage "diffuse", the velocity's part in the film model
/// (PhysicsSwitches::massWeightedViscosity; docs/transport.md, "The in-plane
/// viscosity, weighted by mass"): the fabric's in-plane viscosity exchanges
/// momentum between neighbouring parcels of liquid in proportion to the
/// liquid there, not to the area.
///
/// The paper diffuses u with (M + h L_v) u⁺ = M u, M the dual areas, L_v the
/// connection Laplacian with the velocity tensor S_v: a vertex with a trace of
/// fast liquid next to a thick still pool gives the pool as much speed per
/// unit area as it loses, so ½ Σ A ρ |u|² can grow. Weighted by the liquid's
/// mass, with the coupling of an edge limited by its thinner end,
///
///   (M_ρ + h K_ρ) u⁺ = M_ρ u,   (M_ρ)_ii = A_i ρ_i,
///   (K_ρ)_ij = ρ̄_ij (L_v)_ij,   (K_ρ)_ii = Σ_j ρ̄_ij |(L_v)_ij|,   ρ̄_ij = min(ρ_i, ρ_j),
///
/// conserves the momentum Σ A ρ u of a flat film, keeps a parallel field
/// (a uniform flow) as it is, and is dissipative for any step: K_ρ is
/// Hermitian with a dominant diagonal, so with E = ½ uᴴ M_ρ u,
///   E(u) − E(u⁺) = h u⁺ᴴ K_ρ u⁺ + ½ (u⁺ − u)ᴴ M_ρ (u⁺ − u) ≥ 0,
/// the dissipation returned. An edge to a vertex without free liquid couples
/// nothing (the film's edge is free of stress).
///
/// Symbols (SI): ρ = σ_f + σ_s the free liquid (kg/m²); A_i the dual area
/// (m²); u in each vertex's frame (m/s); L_v IntrinsicGeometry::velocityStiffness.
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>

#include <vector>

namespace blot::stain {

/// diffuseFilmVelocity's scratch, sized once (resize); a call allocates nothing.
struct FilmViscosityScratch {
  std::vector<int> vertices;   ///< the film vertices of a call, in index order (capacity #V)
  std::vector<int> position;   ///< #V: index into `vertices`, −1 elsewhere
  std::vector<int> entries;    ///< per ring entry: its position in L_v's column (−1: none / not filled)
  ComplexVector x, r, z, p, q; ///< CG vectors, #V (only the first |vertices| entries used)
  Vector mass;                 ///< #V: A_i ρ_i
  Vector diagonal;             ///< #V: A_i ρ_i + h Σ_j ρ̄_ij |L_ij|
  ComplexVector couplings;     ///< compressed rows of the film: h ρ̄_ij L_ij (capacity: ring entries)
  std::vector<int> columns;    ///< their columns (positions in `vertices`)
  std::vector<int> rowStarts;  ///< #V + 1: where each row starts
  void resize(int vertexCount, int ringEntries);
};

/// What a call did (StepProfile reads it).
struct FilmViscosityReport {
  int vertices = 0;          ///< rows of the solve (film vertices)
  int iterations = 0;        ///< CG iterations
  bool converged = true;     ///< false: stopped at the cap, the last iterate kept
  double dissipation = 0;    ///< E(u) − E(u⁺) (J), ≥ 0
};

/// Solves the system above for u on the film vertices among `candidates`
/// (those holding free liquid, ρ > 0), by conjugate gradients with Jacobi's
/// preconditioner from u, until the residual is below 1e-11 of the right-hand
/// side (max norms; at most 500 iterations). Other vertices keep their u.
/// One thread, deterministic, no allocation.
FilmViscosityReport diffuseFilmVelocity(const StepContext& ctx, const SurfaceTopology& topology,
                                        const IntrinsicGeometry& intrinsic, const std::vector<int>& candidates,
                                        FilmViscosityScratch& scratch, StainState& state);

}  // namespace blot::stain
