// advectDensities: exact mass conservation and positivity over 1000 steps of a
// rotating flow with sub-steps, sub-step count against the Courant number, the
// limiter when the sub-step cap is hit, free-stream preservation, centroid
// speed of a translated blob, and flux along (never through) the boundary.
#include <blot/stain/stages/density_advection.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "sanitized_build.h"
#include "stain_stage_test_support.h"

namespace blot::stain {
namespace {

using testing::StageGeometry;
using testing::zeroState;

StepContext contextWithStep(double h) {
  return makeStepContext(h, Vector3(0, 0, -9.8), PhysicsSwitches{}, LiquidParameters{});
}

double totalMass(const StageGeometry& g, const Vector& density) {
  return g.intrinsic.vertexDualAreas.dot(density);
}

void setVelocity(const StageGeometry& g, const std::function<Vector3(const Vector3&)>& field,
                 StainState& state) {
  for (int i = 0; i < g.vertexCount(); ++i) state.velocities(i) = g.toFrame(i, field(g.position(i)));
}

Eigen::Vector2d centroid(const StageGeometry& g, const Vector& density) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (int i = 0; i < g.vertexCount(); ++i)
    sum += g.intrinsic.vertexDualAreas(i) * density(i) * g.position(i).head<2>();
  return sum / totalMass(g, density);
}

// Rotating flow (ω = 1 rad/s) on a disc and on a jittered square, 1000 steps
// at a Courant number above 1: Σ A_i σ_i is conserved to 1e-13 relative for
// both species after every step, no density is ever negative, sub-steps are
// taken, and a rerun is bit-identical.
TEST(DensityAdvection, RotatingFlowConservesMassExactlyAndStaysNonNegative) {
  struct Case {
    const char* name;
    TriangleMesh mesh;
    Vector3 centre;
  };
  const Case cases[] = {{"disc", discMesh(14, 1.0), Vector3::Zero()},
                        {"jittered grid", testing::jitteredGrid(28, 0.3, 9), Vector3(0.5, 0.5, 0.0)}};
  for (const Case& c : cases) {
    StageGeometry g(c.mesh);
    const Vector3 centre = c.centre;
    auto rotation = [&](const Vector3& x) -> Vector3 { return Vector3::UnitZ().cross(x - centre); };
    StainState state = zeroState(g.vertexCount());
    setVelocity(g, rotation, state);
    for (int i = 0; i < g.vertexCount(); ++i) {
      const Vector3 d = g.position(i) - centre - Vector3(0.25, 0.1, 0.0);
      state.solvent(i) = 2.0 * std::exp(-d.squaredNorm() / (2 * 0.08 * 0.08));
      state.solute(i) = d.norm() < 0.15 ? 0.3 : 0.0;  // a sharp-edged spot
    }
    // Courant ≈ 2.5 at the fastest vertex holding liquid.
    const double h = 2.5 * testing::shortestEdge(g) / 0.5;
    const StepContext ctx = contextWithStep(h);
    const double solvent0 = totalMass(g, state.solvent), solute0 = totalMass(g, state.solute);
    StainState rerun = state;
    DensityAdvectionScratch scratch;
    scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
    double worstSolvent = 0.0, worstSolute = 0.0, lowest = 0.0;
    int maxSubsteps = 0;
    // 1000 steps; 80 under the sanitizers, which run this test 30 to 40 times
    // slower (tests/support/sanitized_build.h).
    const int steps = blot::test::stepsForThisBuild(1000, 80);
    for (int step = 0; step < steps; ++step) {
      const DensityAdvectionReport report =
          advectDensities(ctx, g.topology(), g.intrinsic, g.extrinsic, {}, scratch, state);
      maxSubsteps = std::max(maxSubsteps, report.substeps);
      worstSolvent = std::max(worstSolvent, std::abs(totalMass(g, state.solvent) / solvent0 - 1.0));
      worstSolute = std::max(worstSolute, std::abs(totalMass(g, state.solute) / solute0 - 1.0));
      lowest = std::min({lowest, state.solvent.minCoeff(), state.solute.minCoeff()});
    }
    std::printf("%s: %d vertices, max sub-steps %d, mass drift solvent %.2e solute %.2e\n", c.name,
                g.vertexCount(), maxSubsteps, worstSolvent, worstSolute);
    EXPECT_LT(worstSolvent, 1e-13) << c.name;
    EXPECT_LT(worstSolute, 1e-13) << c.name;
    EXPECT_GE(lowest, 0.0) << c.name;
    EXPECT_GE(maxSubsteps, 2) << c.name;
    // The blob has moved (a quarter turn every π/2 s): a real transport, not a no-op.
    EXPECT_GT(state.solvent.maxCoeff(), 0.0);
    for (int step = 0; step < steps; ++step)
      advectDensities(ctx, g.topology(), g.intrinsic, g.extrinsic, {}, scratch, rerun);
    EXPECT_EQ(rerun.solvent, state.solvent) << c.name;
    EXPECT_EQ(rerun.solute, state.solute) << c.name;
  }
}

// A mesh large enough for the parallel path (≥ 4096 vertices), an odd and an
// even number of sub-steps (the sub-steps alternate two buffers), a wet mask
// that leaves the Courant number to the wet region: conservation, positivity.
TEST(DensityAdvection, ParallelPathWithWetMaskConservesMass) {
  StageGeometry g(testing::jitteredGrid(72, 0.25, 21));
  ASSERT_GE(g.vertexCount(), 4096);
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [](const Vector3& x) { return Vector3(0.5 - x.y(), x.x() - 0.5, 0.0); }, state);
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  for (int i = 0; i < g.vertexCount(); ++i) {
    const double r = (g.position(i) - Vector3(0.7, 0.5, 0.0)).norm();
    state.solvent(i) = r < 0.1 ? 1.0 : 0.0;
    state.solute(i) = r < 0.05 ? 0.2 : 0.0;
    wet[static_cast<size_t>(i)] = state.solvent(i) > 0.0;
  }
  const double solvent0 = totalMass(g, state.solvent), solute0 = totalMass(g, state.solute);
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  std::vector<int> substeps;
  for (const double h : {0.05, 0.08, 0.11, 0.14}) {
    const DensityAdvectionReport report =
        advectDensities(contextWithStep(h), g.topology(), g.intrinsic, g.extrinsic, wet, scratch, state);
    substeps.push_back(report.substeps);
    EXPECT_GE(state.solvent.minCoeff(), 0.0);
    EXPECT_GE(state.solute.minCoeff(), 0.0);
  }
  std::printf("parallel path: sub-steps %d %d %d %d\n", substeps[0], substeps[1], substeps[2], substeps[3]);
  EXPECT_LT(std::abs(totalMass(g, state.solvent) / solvent0 - 1.0), 1e-14);
  EXPECT_LT(std::abs(totalMass(g, state.solute) / solute0 - 1.0), 1e-14);
  bool odd = false, even = false;
  for (const int n : substeps) (n % 2 ? odd : even) = true;
  EXPECT_TRUE(odd && even);
}

// The work is restricted to the wet set and its n-ring halo. Against a run on
// the whole mesh with the same number of sub-steps (forced through the cap)
// the result is bit-identical: liquid cannot get further than n rings.
TEST(DensityAdvection, WetRegionRestrictionMatchesTheWholeMeshBitForBit) {
  StageGeometry g(testing::jitteredGrid(40, 0.25, 13));
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [](const Vector3& x) { return Vector3(0.5 - x.y(), x.x() - 0.5, 0.0); }, state);
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  for (int i = 0; i < g.vertexCount(); ++i) {
    const double r = (g.position(i) - Vector3(0.6, 0.45, 0.0)).norm();
    state.solvent(i) = r < 0.12 ? 1.0 + r : 0.0;
    state.solute(i) = r < 0.08 ? 0.3 : 0.0;
    wet[static_cast<size_t>(i)] = state.solvent(i) > 0.0;
  }
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  StainState restricted = state, whole = state;
  StepContext ctx = contextWithStep(0.16);
  const DensityAdvectionReport local =
      advectDensities(ctx, g.topology(), g.intrinsic, g.extrinsic, wet, scratch, restricted);
  ctx.maxAdvectionSubsteps = local.substeps;
  const DensityAdvectionReport global =
      advectDensities(ctx, g.topology(), g.intrinsic, g.extrinsic, {}, scratch, whole);
  std::printf("restricted: %d sub-steps, %d of %d vertices active\n", local.substeps, local.activeVertices,
              g.vertexCount());
  EXPECT_GE(local.substeps, 2);
  EXPECT_EQ(global.substeps, local.substeps);
  EXPECT_LT(local.activeVertices, g.vertexCount() / 2);
  EXPECT_EQ(global.activeVertices, g.vertexCount());
  EXPECT_EQ(restricted.solvent, whole.solvent);
  EXPECT_EQ(restricted.solute, whole.solute);
  EXPECT_NE(restricted.solvent, state.solvent);
  // The scratch marks are cleared: a second restricted call sees the same set.
  StainState again = state;
  EXPECT_EQ(
      advectDensities(contextWithStep(0.16), g.topology(), g.intrinsic, g.extrinsic, wet, scratch, again)
          .activeVertices,
      local.activeVertices);
  EXPECT_EQ(again.solvent, restricted.solvent);
}

// n = ceil(max over wet vertices of h · outflow_i / A_i), one sub-step when
// that is below 1.
TEST(DensityAdvection, SubstepCountFollowsTheCourantNumber) {
  StageGeometry g(testing::jitteredGrid(20, 0.3, 4));
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [](const Vector3& x) { return Vector3(0.4 + 0.3 * x.y(), -0.2, 0.0); }, state);
  state.solvent.setConstant(1.0);
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  for (const double h : {0.002, 0.01, 0.05, 0.2}) {
    StainState s = state;
    const DensityAdvectionReport report =
        advectDensities(contextWithStep(h), g.topology(), g.intrinsic, g.extrinsic, {}, scratch, s);
    double courant = 0.0;
    for (int i = 0; i < g.vertexCount(); ++i)
      courant = std::max(courant, h * scratch.outflowRates(i) / g.intrinsic.vertexDualAreas(i));
    EXPECT_DOUBLE_EQ(report.maxCourant, courant);
    EXPECT_EQ(report.substeps, std::max(1, static_cast<int>(std::ceil(courant)))) << "h " << h;
    EXPECT_EQ(report.limitedVertices, 0);
    EXPECT_GE(s.solvent.minCoeff(), 0.0);
  }
}

// With the sub-step cap at 1 and a Courant number near 4, vertices give what
// they hold and no more: positivity and conservation still hold.
TEST(DensityAdvection, SubstepCapLimitsOutflowWithoutNegativeDensity) {
  StageGeometry g(testing::jitteredGrid(20, 0.3, 8));
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [](const Vector3&) { return Vector3(1.0, 0.5, 0.0); }, state);
  for (int i = 0; i < g.vertexCount(); ++i) state.solvent(i) = 1.0 + std::sin(7.0 * g.position(i).x());
  StepContext ctx = contextWithStep(4.0 * testing::shortestEdge(g));
  ctx.maxAdvectionSubsteps = 1;
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  const double mass0 = totalMass(g, state.solvent);
  int limited = 0;
  for (int step = 0; step < 50; ++step) {
    const DensityAdvectionReport report =
        advectDensities(ctx, g.topology(), g.intrinsic, g.extrinsic, {}, scratch, state);
    EXPECT_EQ(report.substeps, 1);
    EXPECT_GT(report.maxCourant, 1.0);
    limited += report.limitedVertices;
    ASSERT_GE(state.solvent.minCoeff(), 0.0) << "step " << step;
  }
  EXPECT_GT(limited, 0);
  EXPECT_LT(std::abs(totalMass(g, state.solvent) / mass0 - 1.0), 1e-13);
}

// A constant density in a uniform flow on a flat mesh stays constant away from
// the inflow boundary (Σ_j N_ij = 0 at interior vertices: the barycentric cell
// Laplacian of a linear function), after one step at Courant ≈ 0.5. Upwind
// information travels one ring per sub-step, so only vertices more rings away
// from the inflow sides than there were sub-steps are checked, and not the
// vertices on the outflow walls, which collect what cannot leave.
TEST(DensityAdvection, UniformFlowKeepsConstantDensityInTheInterior) {
  StageGeometry g(gridMesh(24, 24, 1.0, 1.0));
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [](const Vector3&) { return Vector3(0.3, 0.2, 0.0); }, state);
  state.solvent.setConstant(1.5);
  const double dx = 1.0 / 24;
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  const DensityAdvectionReport report = advectDensities(contextWithStep(0.5 * dx / 0.3), g.topology(),
                                                        g.intrinsic, g.extrinsic, {}, scratch, state);
  const double margin = (report.substeps + 0.5) * dx;
  int interior = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Vector3 x = g.position(i);
    // Inflow sides lose liquid; the outflow walls (x = 1, y = 1) collect it,
    // and barycentric dual edges (not perpendicular to their primal edge) let
    // that excess reach back one ring per sub-step as well.
    if (std::min(x.x(), x.y()) < margin || std::max(x.x(), x.y()) > 1.0 - margin) continue;
    EXPECT_NEAR(state.solvent(i), 1.5, 1e-13) << "vertex " << i;
    ++interior;
  }
  EXPECT_GT(interior, 300);
}

// A Gaussian blob in the uniform flow U moves its centroid by U t. First-order
// upwind is diffusive (the blob spreads) but, on a regular grid, that
// diffusion is symmetric and does not shift the centroid: tolerance 1 % of
// the distance travelled.
TEST(DensityAdvection, UniformFlowTranslatesBlobCentroidAtFlowSpeed) {
  StageGeometry g(gridMesh(48, 48, 1.0, 1.0));
  const Vector3 flow(0.25, 0.15, 0.0);
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [&](const Vector3&) { return flow; }, state);
  const Eigen::Vector2d start(0.3, 0.35);
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Eigen::Vector2d d = g.position(i).head<2>() - start;
    state.solvent(i) = std::exp(-d.squaredNorm() / (2 * 0.05 * 0.05));
  }
  const Eigen::Vector2d before = centroid(g, state.solvent);
  const double h = 0.02, duration = 1.6;
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  for (int step = 0; step < static_cast<int>(std::lround(duration / h)); ++step)
    advectDensities(contextWithStep(h), g.topology(), g.intrinsic, g.extrinsic, {}, scratch, state);
  const Eigen::Vector2d moved = centroid(g, state.solvent) - before;
  const Eigen::Vector2d expected = duration * flow.head<2>();
  std::printf("blob centroid moved (%.5f, %.5f), expected (%.5f, %.5f)\n", moved.x(), moved.y(), expected.x(),
              expected.y());
  EXPECT_LT((moved - expected).norm(), 0.01 * expected.norm());
}

// Liquid on the bottom boundary row, flow along +x: it slides along the
// boundary (boundary edges carry flux) and never leaves the mesh; a flow into
// the right wall piles the liquid up there without losing any.
TEST(DensityAdvection, BoundaryEdgesCarryFluxAlongButNothingLeavesTheMesh) {
  StageGeometry g(gridMesh(20, 20, 1.0, 1.0));
  StainState state = zeroState(g.vertexCount());
  setVelocity(
      g, [](const Vector3&) { return Vector3(0.5, 0.0, 0.0); }, state);
  const int source = 4;  // vertex (4, 0) on the bottom edge, x = 0.2
  state.solvent(source) = 1.0;
  const double mass0 = totalMass(g, state.solvent);
  DensityAdvectionScratch scratch;
  scratch.resize(g.vertexCount(), g.topology().edgeCount(), g.topology().faceCount());
  const double h = 0.02;
  for (int step = 0; step < 40; ++step)
    advectDensities(contextWithStep(h), g.topology(), g.intrinsic, g.extrinsic, {}, scratch, state);
  const Eigen::Vector2d c = centroid(g, state.solvent);
  std::printf("boundary row: centroid moved %.4f along x (U t = %.4f), y = %.2e\n", c.x() - 0.2, 0.5 * 40 * h,
              c.y());
  EXPECT_NEAR(c.x() - 0.2, 0.5 * 40 * h, 0.05 * 0.5 * 40 * h);  // slid along the boundary
  // Barycentric dual edges are not perpendicular to their primal edges, so an
  // axis-aligned flow also spreads liquid across the flow (first-order upwind
  // diffusion); it stays within about one ring of the boundary.
  EXPECT_GE(c.y(), 0.0);
  EXPECT_LT(c.y(), 1.5 / 20.0);
  EXPECT_LT(std::abs(totalMass(g, state.solvent) / mass0 - 1.0), 1e-14);

  // Into the wall at x = 1: after long enough, everything sits in the last column.
  state.solvent.setConstant(1.0);
  const double full = totalMass(g, state.solvent);
  for (int step = 0; step < 400; ++step)
    advectDensities(contextWithStep(h), g.topology(), g.intrinsic, g.extrinsic, {}, scratch, state);
  double lastColumn = 0.0;
  for (int i = 0; i < g.vertexCount(); ++i)
    if (g.position(i).x() > 1.0 - 1e-9) lastColumn += g.intrinsic.vertexDualAreas(i) * state.solvent(i);
  EXPECT_LT(std::abs(totalMass(g, state.solvent) / full - 1.0), 1e-13);
  EXPECT_GT(lastColumn, 0.99 * full);
  EXPECT_GE(state.solvent.minCoeff(), 0.0);
}

}  // namespace
}  // namespace blot::stain
