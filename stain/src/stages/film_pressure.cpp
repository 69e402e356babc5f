// Stage "pressure": the film-pressure acceleration −∇p_ext/ρ of eq. (3).
//
// Design note. The paper writes −∇p_ext/ρ in the momentum equation and then
// ignores it ("ignored in our tests"). Without it nothing in the model moves
// liquid from a thick centre towards a thin, drying edge: σ_f and σ_s diffuse
// by the same linear law, so evaporation concentrates the solution but never
// carries solute outward, and a spot dries into a dome, not the ring of
// Fig. 11 (measured in halo_test). With the shallow-water pressure of the
// paper's ref. [23], p = ρ g_n H and H = σ_f/ρ (the paper's own σ_f = Hρ), the
// acceleration is a = −(g_n/ρ) ∇σ_f: liquid flows down the film-height
// gradient, advection (the existing upwind fluxes) carries σ_f and σ_s with
// the same velocity, and the edge, where the film is thinnest and dries first,
// keeps receiving solution from the centre and keeps the solute when it dries:
// the outward capillary flow of a real coffee ring, with gravity standing in
// for the capillary pressure.
// Discretization: per vertex, Σ_T A_T ∇σ_T over the one-ring, with the P1
// gradient A_T ∇σ_T = ½ Σ_k σ_k (N_T × e_k) (e_k the edge opposite corner k,
// counter-clockwise, N_T the unit face normal), divided by Σ_T A_T, then
// projected on the vertex frame's x and y axes. g_n = |g · n_i| so a film on
// the underside of a cloth spreads the same way (the pressure of a film
// depends on its thickness, not on which side it hangs). Explicit (symplectic
// Euler: the new u is what advection uses); stable while the gravity-wave
// Courant number h √(g_n σ_f/ρ) / Δx stays below about 1, which for mm films
// (σ_f ≈ 1 kg/m²) and cm edges holds up to h ≈ 0.1 s. Rejected: an implicit
// (wave-equation) solve, a second factorized system for a term that is off by
// default and far from its limit at the paper's time steps; the pressure of
// absorbed solvent, held in the fibres and not part of the flowing film.
#include <blot/stain/stages/film_pressure.h>

#include <cassert>
#include <cmath>

namespace blot::stain {

void applyFilmPressure(const StepContext& ctx, const SurfaceTopology& topology, const ExtrinsicGeometry& geometry,
                       const std::vector<char>& wet, StainState& state) {
  if (!ctx.switches.filmPressure) return;
  const int n = state.vertexCount();
  assert(wet.empty() || wet.size() == static_cast<size_t>(n));
  const bool allWet = wet.size() != static_cast<size_t>(n);
  const double scale = ctx.h / ctx.liquid.liquidDensity;  // h / ρ (s m³/kg)
  const Triangles& faces = topology.faces();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const RowVectors3& p = geometry.positions;
  const double* sigma = state.solvent.data();
  for (int i = 0; i < n; ++i) {
    if (!allWet && !wet[static_cast<size_t>(i)]) continue;
    Vector3 weightedGradient = Vector3::Zero();  // Σ_T A_T ∇σ_T (kg/m)
    double area = 0.0;
    bool any = false;
    for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      const int a = faces(f, 0), b = faces(f, 1), c = faces(f, 2);
      if (sigma[a] == 0.0 && sigma[b] == 0.0 && sigma[c] == 0.0) continue;
      any = true;
      const Vector3 pa = p.row(a).transpose(), pb = p.row(b).transpose(), pc = p.row(c).transpose();
      const Vector3 doubleAreaNormal = (pb - pa).cross(pc - pa);  // 2 A_T N_T
      const double doubleArea = doubleAreaNormal.norm();
      if (!(doubleArea > 0.0)) continue;
      const Vector3 unitNormal = doubleAreaNormal / doubleArea;
      weightedGradient += 0.5 * unitNormal.cross(sigma[a] * (pc - pb) + sigma[b] * (pa - pc) + sigma[c] * (pb - pa));
      area += 0.5 * doubleArea;
    }
    if (!any || !(area > 0.0)) continue;
    const double normalGravity = std::abs(ctx.gravity.dot(geometry.vertexNormals.row(i).transpose()));
    const Vector3 dv = (-scale * normalGravity / area) * weightedGradient;
    const Matrix3& frame = geometry.frames[static_cast<size_t>(i)];
    state.velocities(i) += Complex(frame.col(0).dot(dv), frame.col(1).dot(dv));
  }
}

}  // namespace blot::stain
