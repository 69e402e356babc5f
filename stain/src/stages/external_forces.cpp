// Stage "forces": tangential gravity, linear inertia and Coriolis (paper sec. 4).
//
// Design note: docs/design-notes.md, "stain/src/stages/external_forces.cpp".
#include <blot/stain/stages/external_forces.h>

#include <cmath>

#include <blot/stain/stages/liquid_band.h>

#include "numerics/threads.h"

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
                     StainState& state, const std::vector<int>* among) {
  const PhysicsSwitches& on = ctx.switches;
  const int n = static_cast<int>(state.velocities.size());
  // A static mesh may provide no accelerations at all.
  const bool useInertia = on.linearInertia && geometry.vertexAccelerations.rows() == n;
  if (!on.gravity && !useInertia) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  const Vector3 gravity = on.gravity ? ctx.gravity : Vector3::Zero();
  // With the film's pressure, gravity and the surface's acceleration act on
  // the film through its potential gradient (film_flow.h), and the rest of
  // the band holds the liquid's velocity extended from it: no kick there, or
  // the front's fluxes (the mean of the two ends' velocities) would carry a
  // velocity no friction ever slowed.
  if (on.filmPressure && on.gravity && !allWet) return;
  const int visits = visitCount(n, among);
  threads::runLoop(visits >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
      if (!allWet && !wet[static_cast<size_t>(i)]) continue;
      Vector3 a = gravity;
      if (useInertia) a -= geometry.vertexAccelerations.row(i).transpose();
      const Matrix3& frame = geometry.frames[static_cast<size_t>(i)];
      state.velocities(i) += h * Complex(frame.col(0).dot(a), frame.col(1).dot(a));
    }
  });
}

void clearVelocityWithoutFreeLiquid(const StepContext& ctx, const std::vector<char>& wet, StainState& state,
                                    const std::vector<int>* among) {
  const int n = static_cast<int>(state.velocities.size());
  if (!ctx.switches.velocityOnFreeLiquid || wet.size() != static_cast<size_t>(n)) return;
  const double threshold = ctx.liquid.wetThreshold;
  const int visits = visitCount(n, among);
  threads::runLoop(visits >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
      if (wet[static_cast<size_t>(i)] != LiquidBand::kHoldsLiquid) continue;
      if (!(state.solvent(i) + state.solute(i) > threshold)) state.velocities(i) = Complex(0.0, 0.0);
    }
  });
}

int applyBoundaryWall(const StepContext& ctx, const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic,
                      const std::vector<char>& wet, StainState& state, const std::vector<int>* among) {
  const int n = static_cast<int>(state.velocities.size());
  const std::vector<char>& boundary = topology.vertexIsBoundary();
  const Vector& angles = intrinsic.polarMap.ringAngles;
  const std::vector<int>& offsets = topology.ringOffsets();
  if (!ctx.switches.boundaryWall || boundary.size() != static_cast<size_t>(n) ||
      angles.size() != static_cast<Eigen::Index>(topology.ringNeighbors().size()))
    return 0;
  const bool allWet = wet.empty();
  const double pi = std::acos(-1.0);
  // Serial: boundary vertices are a thin set, a few flops each.
  int changed = 0;
  const int visits = visitCount(n, among);
  for (int k = 0; k < visits; ++k) {
    const int i = visited(k, among);
    if (!boundary[static_cast<size_t>(i)] || (!allWet && !wet[static_cast<size_t>(i)])) continue;
    Complex& u = state.velocities(i);
    if (u == Complex(0.0, 0.0)) continue;
    // The fan [0, γ]: γ is the last ring entry's angle (the second boundary edge).
    const double fan = angles[offsets[static_cast<size_t>(i) + 1] - 1];
    const Complex before = u;
    if (fan < pi && fan > pi - kWallCornerTurning) {
      // A bend of a smooth boundary: free slip along the chord between the
      // two boundary neighbours, u · n ≤ 0 with n the outward bisector.
      const Complex outward = -unitRotation(0.5 * fan);
      const double normal = u.real() * outward.real() + u.imag() * outward.imag();
      if (normal > 0.0) u -= normal * outward;
    } else if (fan < 2.0 * pi) {  // a fan of 2π or more holds every direction
      double direction = std::arg(u);  // (−π, π]
      if (direction < 0.0) direction += 2.0 * pi;
      if (direction > fan) {
        // Outside: the nearest point of the two boundary rays (t ≥ 0) is on
        // the ray with the larger projection, or 0 when neither is positive.
        const Complex last = unitRotation(fan);
        const double alongFirst = u.real();
        const double alongLast = u.real() * last.real() + u.imag() * last.imag();
        if (alongFirst <= 0.0 && alongLast <= 0.0) {
          u = Complex(0.0, 0.0);
        } else if (alongFirst >= alongLast) {
          u = Complex(alongFirst, 0.0);
        } else {
          u = alongLast * last;
        }
      }
    }
    changed += u != before ? 1 : 0;
  }
  return changed;
}

void applyCoriolis(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                   StainState& state, const std::vector<int>* among) {
  const PhysicsSwitches& on = ctx.switches;
  const int n = static_cast<int>(state.velocities.size());
  if (!on.coriolis || geometry.vertexAngularVelocities.rows() != n) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  const bool exact = on.coriolisScheme != CoriolisScheme::Explicit;
  const int visits = visitCount(n, among);
  threads::runLoop(visits >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
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
  });
}

void applyExternalForces(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                         StainState& state) {
  applyBodyForces(ctx, geometry, wet, state);
  applyCoriolis(ctx, geometry, wet, state);
}

void applyHalfFrameRotation(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                            StainState& state, const std::vector<int>* among) {
  const int n = static_cast<int>(state.velocities.size());
  if (geometry.vertexAngularVelocities.rows() != n) return;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  const int visits = visitCount(n, among);
  threads::runLoop(visits >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
      if (!allWet && !wet[static_cast<size_t>(i)]) continue;
      const double omegaN = geometry.vertexAngularVelocities(i, 2);
      if (omegaN != 0.0) state.velocities(i) *= unitRotation(-0.5 * omegaN * h);
    }
  });
}

void applyFrameVelocityChange(const StepContext& ctx, const ExtrinsicGeometry& geometry,
                              const FootVertices& footVertices, const FootWeights& footWeights,
                              const std::vector<char>& wet, StainState& state, const std::vector<int>* among) {
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

  const int visits = visitCount(n, among);
  threads::runLoop(visits >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
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
  });
}

}  // namespace blot::stain
