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
//  - Only wet vertices are touched (DESIGN.md: a dry vertex needs no work).
//    The loop is per vertex with independent outputs: OpenMP, deterministic.
#include <blot/stain/external_forces.h>

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

void applyExternalForces(const StepContext& ctx, const ExtrinsicGeometry& geometry,
                         const std::vector<char>& wet, StainState& state) {
  const PhysicsSwitches& on = ctx.switches;
  const int n = static_cast<int>(state.velocities.size());
  const bool useGravity = on.gravity;
  // A static mesh may provide no accelerations/angular velocities at all.
  const bool useInertia = on.linearInertia && geometry.vertexAccelerations.rows() == n;
  const bool useCoriolis = on.coriolis && geometry.vertexAngularVelocities.rows() == n;
  const bool useBodyForce = useGravity || useInertia;
  if (!useBodyForce && !useCoriolis) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  const Vector3 gravity = useGravity ? ctx.gravity : Vector3::Zero();
  const bool exact = on.coriolisScheme == CoriolisScheme::ExactRotation;

#pragma omp parallel for schedule(static) if (n >= kMinParallelVertices)
  for (int i = 0; i < n; ++i) {
    if (!allWet && !wet[static_cast<size_t>(i)]) continue;
    Complex u = state.velocities(i);
    if (useBodyForce) {
      Vector3 a = gravity;
      if (useInertia) a -= geometry.vertexAccelerations.row(i).transpose();
      const Matrix3& frame = geometry.frames[static_cast<size_t>(i)];
      u += h * Complex(frame.col(0).dot(a), frame.col(1).dot(a));
    }
    if (useCoriolis && geometry.vertexAngularVelocities(i, 2) != 0.0) {
      const double omegaN = geometry.vertexAngularVelocities(i, 2);
      if (exact) {
        u *= unitRotation(-2.0 * omegaN * h);
      } else {
        u += -2.0 * h * omegaN * Complex(-u.imag(), u.real());
      }
    }
    state.velocities(i) = u;
  }
}

}  // namespace blot::stain
