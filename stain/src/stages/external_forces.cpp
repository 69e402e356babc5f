// Stage "forces": tangential gravity, linear inertia and Coriolis (paper sec. 4).
//
// Design note.
//  - Equation: du/dt = tangential part of (g − p̈_i) − 2 ω × u, in the frame
//    F_i^t = [x_i y_i z_i]. The centrifugal and Euler terms vanish because the
//    liquid velocity is measured at the vertex (r = 0, paper sec. 4).
//  - Body force: (g − p̈_i) is a world vector; its tangential part in frame
//    coordinates is simply (x_i · a, y_i · a): projecting on the two tangent
//    axes of an orthonormal frame drops the normal component, so no separate
//    a − (a·n)n is needed. Forward Euler is exact here (the forcing does not
//    depend on u): u += h a_t.
//  - Coriolis: with ω_n = ω_i · z_i (frame coordinates), −2 ω × (u, 0) has the
//    tangential part −2 ω_n (z × u) = −2 ω_n (i u) in complex form (the
//    tangential components of ω only produce a normal force, balanced by the
//    constraint that the liquid stays on the surface). du/dt = −2iω_n u is a
//    pure rotation, integrated exactly: u ← exp(−2iω_n h) u, which keeps |u|.
//    Rejected as default: the explicit update u += −2h ω_n (i u) multiplies |u|
//    by √(1 + 4ω_n²h²) every step (energy gain, "where methods fail"); it is
//    kept behind CoriolisScheme::Explicit for the comparison chart only.
//  - Order: body force first, then the rotation (a Lie splitting; both
//    orders are first order in h, and for ω = 0 the result is exactly u + h a_t).
//  - After the velocity advection the solver replaces exp(−2iω_n h) by the
//    discrete frame change (applyHalfFrameRotation, applyFrameVelocityChange;
//    docs/transport.md). What the step should carry unchanged is the liquid's
//    world velocity V = v + F u. The frame's velocity over [t, t+h] is its
//    chord v^{t+½} = (p^{t+h} − p^t)/h, and the paper's centred p̈ is exactly
//    the chord's change, h p̈ = v^{t+½} − v^{t−½} (uniform step), so after the
//    inertia kick F^t u = V − v^{t+½}. The liquid arriving at vertex i came
//    from the foot y of its backtrack, where V(y) = v^{t+½}(y) + F^t u(y):
//      u_i ← u_advected + tangential F_i^tᵀ (v^{t+½}(y) − v_i^{t+½}),
//    the frame velocity's change along the backtrack (for a rigid motion
//    ω × (y − x_i) ≈ −h ω × u), plus the exact frame increment exp(−iω_n h)
//    about the normal (|u| kept, as the paper's tangential Coriolis keeps it):
//    together the paper's −2ω × u to first order. V at the foot then reaches
//    the vertex unchanged: liquid at rest in an inertial frame stays at rest at
//    any ωh (relative speed the chord speed ω r sinc(ωh/2)), and since V is
//    only interpolated with convex weights, max |V| cannot grow: no energy is
//    created. The increment is turned in two halves, one at the start of the
//    step and one after this term, so u is kept between steps in the step's
//    midpoint frame: a chord points along the motion at the middle of the
//    step, so there the relative velocity of a turning disc is tangential (in
//    F^{t+h} it points inward by ωh/2 and the density advection gathered the
//    whole film at the centre at ωh = 2). Rejected: the split exp(−2iω_n h)
//    after advection (CoriolisScheme::SplitRotation): right to O((ωh)³) per
//    step, but its kick, straight backtrack and rotation compound at large
//    ωh (energy ×9.4 after 50 steps at ωh = 2). Rejected: the exact rigid
//    acceleration −ω×(ω×r) for the centred p̈: the centred p̈ under-estimates
//    the kick by sinc²(ωh/2), which damps; with the exact one the split step
//    reached ×14 instead of ×4.8 after 20 steps (whole disc wet, ωh = 2), and
//    the frame change would no longer conserve V (×3.0).
//  - Only the liquid band is touched (the mask the solver passes; DESIGN.md:
//    a dry vertex needs no work only if no liquid can reach it this step).
//    The band's extended velocities get the same kick as the liquid, so a
//    vertex the liquid reaches late already moves with it (issue 14).
//    The loop is per vertex with independent outputs: OpenMP, deterministic.
#include <blot/stain/stages/external_forces.h>

#include <cmath>

namespace blot::stain {
namespace {

// Below this many vertices the loop runs on one thread: a few flops per
// vertex do not pay for the fork/join (tuned in tests/bench).
constexpr int kMinParallelVertices = 8192;

// exp(i a). For |a| ≤ 1/4 (every Coriolis angle 2|ω|h of a sane step) by the
// Taylor series of cos and sin to a¹⁴/a¹³ in Horner form: truncation below
// 1e-19, so as exact as libm's, at a third of the cost; libm beyond.
inline Complex unitRotation(double a) {
  if (!(std::abs(a) <= 0.25)) return {std::cos(a), std::sin(a)};
  const double b = a * a;
  const double c =
      1.0 + b * (-1.0 / 2 +
                 b * (1.0 / 24 +
                      b * (-1.0 / 720 + b * (1.0 / 40320 + b * (-1.0 / 3628800 + b * (1.0 / 479001600))))));
  const double s =
      a *
      (1.0 + b * (-1.0 / 6 +
                  b * (1.0 / 120 + b * (-1.0 / 5040 + b * (1.0 / 362880 + b * (-1.0 / 39916800 +
                                                                               b * (1.0 / 6227020800.0)))))));
  return {c, s};
}

}  // namespace

void applyBodyForces(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                     StainState& state) {
  const PhysicsSwitches& on = ctx.switches;
  const int n = static_cast<int>(state.velocities.size());
  // A static mesh may provide no accelerations at all.
  const bool useInertia = on.linearInertia && geometry.vertexAccelerations.rows() == n;
  if (!on.gravity && !useInertia) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  const Vector3 gravity = on.gravity ? ctx.gravity : Vector3::Zero();
#pragma omp parallel for schedule(static) if (n >= kMinParallelVertices)
  for (int i = 0; i < n; ++i) {
    if (!allWet && !wet[static_cast<size_t>(i)]) continue;
    Vector3 a = gravity;
    if (useInertia) a -= geometry.vertexAccelerations.row(i).transpose();
    const Matrix3& frame = geometry.frames[static_cast<size_t>(i)];
    state.velocities(i) += h * Complex(frame.col(0).dot(a), frame.col(1).dot(a));
  }
}

void applyCoriolis(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                   StainState& state) {
  const PhysicsSwitches& on = ctx.switches;
  const int n = static_cast<int>(state.velocities.size());
  if (!on.coriolis || geometry.vertexAngularVelocities.rows() != n) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  const bool exact = on.coriolisScheme != CoriolisScheme::Explicit;
#pragma omp parallel for schedule(static) if (n >= kMinParallelVertices)
  for (int i = 0; i < n; ++i) {
    if (!allWet && !wet[static_cast<size_t>(i)]) continue;
    const double omegaN = geometry.vertexAngularVelocities(i, 2);
    if (omegaN == 0.0) continue;
    Complex& u = state.velocities(i);
    if (exact) {
      u *= unitRotation(-2.0 * omegaN * h);
    } else {
      u += -2.0 * h * omegaN * Complex(-u.imag(), u.real());
    }
  }
}

void applyExternalForces(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                         StainState& state) {
  applyBodyForces(ctx, geometry, wet, state);
  applyCoriolis(ctx, geometry, wet, state);
}

void applyHalfFrameRotation(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                            StainState& state) {
  const int n = static_cast<int>(state.velocities.size());
  if (geometry.vertexAngularVelocities.rows() != n) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
#pragma omp parallel for schedule(static) if (n >= kMinParallelVertices)
  for (int i = 0; i < n; ++i) {
    if (!allWet && !wet[static_cast<size_t>(i)]) continue;
    const double omegaN = geometry.vertexAngularVelocities(i, 2);
    if (omegaN != 0.0) state.velocities(i) *= unitRotation(-0.5 * omegaN * h);
  }
}

void applyFrameVelocityChange(const StepContext& ctx, const ExtrinsicGeometry& geometry,
                              const FootVertices& footVertices, const FootWeights& footWeights,
                              const std::vector<char>& wet, StainState& state) {
  const int n = static_cast<int>(state.velocities.size());
  if (geometry.vertexAngularVelocities.rows() != n || footVertices.rows() != n || footWeights.rows() != n ||
      geometry.positions.rows() != n || geometry.nextPositions.rows() != n ||
      geometry.frames.size() != static_cast<size_t>(n))
    return;
  const bool allWet = wet.empty();
  const double h = ctx.h, invH = ctx.invH;
  const RowVectors3& p1 = geometry.positions;
  const RowVectors3& p2 = geometry.nextPositions;
  const auto frameVelocity = [&](int k) -> Vector3 { return (p2.row(k) - p1.row(k)).transpose() * invH; };

#pragma omp parallel for schedule(static) if (n >= kMinParallelVertices)
  for (int i = 0; i < n; ++i) {
    if (!allWet && !wet[static_cast<size_t>(i)]) continue;
    Vector3 change = -frameVelocity(i);
    for (int c = 0; c < 3; ++c) {
      const double w = footWeights(i, c);
      if (w != 0.0) change += w * frameVelocity(footVertices(i, c));
    }
    const Matrix3& frame = geometry.frames[static_cast<size_t>(i)];
    Complex u = state.velocities(i) + Complex(frame.col(0).dot(change), frame.col(1).dot(change));
    const double omegaN = geometry.vertexAngularVelocities(i, 2);
    if (omegaN != 0.0) u *= unitRotation(-0.5 * omegaN * h);
    state.velocities(i) = u;
  }
}

}  // namespace blot::stain
