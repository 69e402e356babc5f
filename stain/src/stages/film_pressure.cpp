// Stage "pressure": the film-pressure acceleration −∇p_ext/ρ of eq. (3).
//
// Design note: docs/design-notes.md, "stain/src/stages/film_pressure.cpp".
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
