// advectVelocity: uniform fields stay uniform (flat, jittered, any Courant
// number), linear fields are reproduced exactly through the strip walk,
// high Courant numbers stay bounded and never leave the mesh, curved surfaces
// turn the field as the covariant derivative says, wet mask, determinism.
#include <blot/stain/stages/velocity_advection.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "stain_stage_test_support.h"

namespace blot::stain {
namespace {

using testing::StageGeometry;
using testing::zeroState;

StepContext contextWithStep(double h) {
  return makeStepContext(h, Vector3(0, 0, -9.8), PhysicsSwitches{}, LiquidParameters{});
}

double maxSpeed(const ComplexVector& u) { return u.cwiseAbs().maxCoeff(); }

// A uniform (parallel) field on a flat jittered grid is unchanged, at Courant
// numbers below 1 (ring only) and far above (strip walk, boundary stops).
TEST(VelocityAdvection, UniformFieldOnFlatJitteredGridIsUnchanged) {
  StageGeometry g(testing::jitteredGrid(24, 0.3, 11));
  const Vector3 uniform(0.3, -0.2, 0.0);
  const double dx = testing::shortestEdge(g);
  for (const double courant : {0.4, 7.0}) {
    const double h = courant * dx / uniform.norm();
    StainState state = zeroState(g.vertexCount());
    for (int i = 0; i < g.vertexCount(); ++i) state.velocities(i) = g.toFrame(i, uniform);
    const ComplexVector before = state.velocities;
    VelocityAdvectionScratch scratch;
    scratch.resize(g.vertexCount());
    const VelocityAdvectionReport report =
        advectVelocity(contextWithStep(h), g.topology(), g.intrinsic, {}, scratch, state);
    EXPECT_LT((state.velocities - before).cwiseAbs().maxCoeff(), 1e-12) << "Courant " << courant;
    EXPECT_EQ(report.cappedWalks, 0);
    if (courant > 5) {
      EXPECT_GT(report.stripSteps, g.vertexCount());
      EXPECT_GT(report.boundaryStops, 0);
    }
  }
}

// A linear field U(x) = U0 + A x on a flat mesh: P1 interpolation is exact, and
// the unfolded strip is the plane itself, so every vertex whose straight
// backtrack x_i − h U(x_i) stays inside the square gets exactly U(foot), at a
// Courant number above 5.
TEST(VelocityAdvection, LinearFieldIsReproducedExactlyThroughTheStripWalk) {
  StageGeometry g(testing::jitteredGrid(30, 0.3, 5));
  Eigen::Matrix2d A;
  A << 0.2, -0.5, 0.4, 0.1;
  const Eigen::Vector2d u0(0.6, 0.35);
  auto field = [&](const Eigen::Vector2d& x) -> Eigen::Vector2d { return u0 + A * x; };
  const double dx = testing::shortestEdge(g);
  double fastest = 0.0;
  for (int i = 0; i < g.vertexCount(); ++i)
    fastest = std::max(fastest, field(g.position(i).head<2>()).norm());
  const double h = 8.0 * dx / fastest * 0.9;  // Courant ≈ 7 at the fastest vertex
  StainState state = zeroState(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Eigen::Vector2d v = field(g.position(i).head<2>());
    state.velocities(i) = g.toFrame(i, Vector3(v.x(), v.y(), 0.0));
  }
  const ComplexVector before = state.velocities;
  VelocityAdvectionScratch scratch;
  scratch.resize(g.vertexCount());
  const VelocityAdvectionReport report =
      advectVelocity(contextWithStep(h), g.topology(), g.intrinsic, {}, scratch, state);
  int checked = 0, maxCourantSeen = 0;
  double worst = 0.0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Eigen::Vector2d x = g.position(i).head<2>();
    const Eigen::Vector2d foot = x - h * field(x);
    if (foot.minCoeff() < 1e-9 || foot.maxCoeff() > 1.0 - 1e-9) continue;
    const Eigen::Vector2d expected = field(foot);
    const Vector3 got = g.toWorld(i, state.velocities(i));
    worst = std::max(worst, (got.head<2>() - expected).norm());
    maxCourantSeen = std::max(maxCourantSeen, static_cast<int>(h * field(x).norm() / dx));
    ++checked;
  }
  EXPECT_LT(worst, 1e-12);
  EXPECT_GT(checked, g.vertexCount() / 3);
  EXPECT_GE(maxCourantSeen, 5);
  EXPECT_GT(report.stripSteps, 0);
  EXPECT_EQ(report.cappedWalks, 0);
  // Every result is a convex combination of rotated inputs.
  EXPECT_LE(maxSpeed(state.velocities), maxSpeed(before) * (1 + 1e-14));
}

// A rotating field on a disc at Courant number 6: repeated advection keeps
// max |u| non-increasing, stays finite, walks the strip and stops at the rim.
TEST(VelocityAdvection, HighCourantRotationStaysBoundedAndInsideTheMesh) {
  StageGeometry g(discMesh(12, 1.0));
  const double omega = 2.0;
  const double dx = testing::shortestEdge(g);
  const double h = 6.0 * dx / omega;  // Courant 6 at the rim (|u| = ω r)
  StainState state = zeroState(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Vector3 x = g.position(i);
    state.velocities(i) = g.toFrame(i, Vector3(-omega * x.y(), omega * x.x(), 0.0));
  }
  VelocityAdvectionScratch scratch;
  scratch.resize(g.vertexCount());
  double previousMax = maxSpeed(state.velocities);
  int strip = 0, stops = 0;
  for (int step = 0; step < 20; ++step) {
    const VelocityAdvectionReport report =
        advectVelocity(contextWithStep(h), g.topology(), g.intrinsic, {}, scratch, state);
    strip += report.stripSteps;
    stops += report.boundaryStops;
    EXPECT_EQ(report.cappedWalks, 0);
    ASSERT_TRUE(state.velocities.allFinite());
    const double currentMax = maxSpeed(state.velocities);
    EXPECT_LE(currentMax, previousMax * (1 + 1e-14)) << "step " << step;
    previousMax = currentMax;
  }
  EXPECT_GT(strip, 0);
  EXPECT_GT(stops, 0);
}

// Exact geodesic semi-Lagrangian step on the unit sphere: follow the great
// circle from x in direction −u for length L = h|u| to the foot y, evaluate
// the field there and parallel transport it back along the same great circle
// (the component normal to the circle's plane is kept, the one along the
// circle's tangent goes to the tangent at x).
Vector3 exactSphereBacktrack(const Vector3& x, const Vector3& u, double h,
                             const std::function<Vector3(const Vector3&)>& field) {
  const double speed = u.norm();
  if (speed == 0.0) return field(x);
  const Vector3 t = -u / speed;
  const double length = h * speed;
  const Vector3 y = std::cos(length) * x + std::sin(length) * t;
  const Vector3 tangentAtFoot = -std::sin(length) * x + std::cos(length) * t;
  const Vector3 binormal = x.cross(t);
  const Vector3 v = field(y);
  return v.dot(tangentAtFoot) * t + v.dot(binormal) * binormal;
}

// On the unit sphere, advect the rotation field U = ω ẑ × x and compare the
// change u_new − u with the exact geodesic semi-Lagrangian change (which is
// −h ∇_U U + O(h²): the tangential centripetal part). Within the ring
// (Courant 0.25) and through the strip walk (Courant 3), the discrete change
// must match to a few per cent of its size; a wrong transport sign is off by
// a factor ~80 and a missing strip transport by order one.
TEST(VelocityAdvection, RotationFieldOnSphereTurnsLikeTheExactGeodesicBacktrack) {
  StageGeometry g(icosphereMesh(5));
  const double omega = 1.0;
  auto field = [&](const Vector3& x) -> Vector3 { return omega * Vector3::UnitZ().cross(x.normalized()); };
  for (const double courant : {0.25, 3.0}) {
    const double h = courant * testing::shortestEdge(g) / omega;
    StainState state = zeroState(g.vertexCount());
    for (int i = 0; i < g.vertexCount(); ++i) state.velocities(i) = g.toFrame(i, field(g.position(i)));
    const ComplexVector before = state.velocities;
    VelocityAdvectionScratch scratch;
    scratch.resize(g.vertexCount());
    const VelocityAdvectionReport report =
        advectVelocity(contextWithStep(h), g.topology(), g.intrinsic, {}, scratch, state);
    double errorSquared = 0.0, changeSquared = 0.0;
    for (int i = 0; i < g.vertexCount(); ++i) {
      const Vector3 x = g.position(i).normalized();
      const Vector3 u = g.toWorld(i, before(i));
      const Vector3 exactChange = exactSphereBacktrack(x, u, h, field) - u;
      const Vector3 change = g.toWorld(i, state.velocities(i) - before(i));
      errorSquared += (change - exactChange).squaredNorm();
      changeSquared += exactChange.squaredNorm();
    }
    const double relative = std::sqrt(errorSquared / changeSquared);
    std::printf("sphere rotation field, Courant %.2f: relative error of the change %.3e, strip steps %d\n",
                courant, relative, report.stripSteps);
    EXPECT_LT(relative, 0.05) << "Courant " << courant;
    if (courant > 1) {
      EXPECT_GT(report.stripSteps, g.vertexCount());
    }
  }
}

TEST(VelocityAdvection, DryVerticesKeepTheirVelocityAndResultsAreDeterministic) {
  StageGeometry g(testing::jitteredGrid(16, 0.3, 3));
  const double h = 3.0 * testing::shortestEdge(g);
  StainState state = zeroState(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Vector3 x = g.position(i);
    state.velocities(i) = g.toFrame(i, Vector3(std::sin(3 * x.y()), std::cos(2 * x.x()), 0.0));
  }
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  for (size_t i = 0; i < wet.size(); i += 2) wet[i] = 1;
  StainState first = state, second = state;
  VelocityAdvectionScratch scratch;
  scratch.resize(g.vertexCount());
  advectVelocity(contextWithStep(h), g.topology(), g.intrinsic, wet, scratch, first);
  advectVelocity(contextWithStep(h), g.topology(), g.intrinsic, wet, scratch, second);
  int changed = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    EXPECT_EQ(first.velocities(i), second.velocities(i));
    if (!wet[static_cast<size_t>(i)]) {
      EXPECT_EQ(first.velocities(i), state.velocities(i));
    }
    if (first.velocities(i) != state.velocities(i)) ++changed;
  }
  EXPECT_GT(changed, g.vertexCount() / 4);
}

}  // namespace
}  // namespace blot::stain
