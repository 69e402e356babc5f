// Tests for stage "interact" (stain/src/stages/interaction.cpp): each law against its
// closed form, the boundary evaporation factor, exact conservation, drying,
// the wet mask, and a spot on a disc run with diffusion + interaction (the
// paper's Fig. 11 ring experiment, without advection).
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/stages/interaction.h>
#include <blot/stain/stages/sources.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;

// Only the named laws on; the rest of the switches as defaults.
StepContext interactionContext(double h, bool absorption, bool adsorption, bool evaporation,
                               const LiquidParameters& liquid = LiquidParameters{}) {
  PhysicsSwitches switches;
  switches.absorption = absorption;
  switches.adsorption = adsorption;
  switches.evaporation = evaporation;
  return makeStepContext(h, Vector3(0, 0, -9.8), switches, liquid);
}

struct InteractionMesh : ::testing::Test {
  const int n = 6;
  LiquidMesh g{gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n)};
  StainState state = zeroState(g.vertexCount());
  const std::vector<char> allWet{};  // empty: every vertex
  double soluteTotal() const {
    return totalMass(g.areas(), state.solute) + totalMass(g.areas(), state.absorbedSolute) +
           totalMass(g.areas(), state.adsorbedSolute);
  }
  double solventTotal() const {
    return totalMass(g.areas(), state.solvent) + totalMass(g.areas(), state.absorbedSolvent) +
           state.evaporatedSolvent;
  }
};

// dσ_p/dt = K_p (σ_sat − σ_p) with ample free solvent: the scheme is implicit
// Euler, so σ_p^n = σ_sat (1 − (1/(1 + K_p h))^n) exactly (up to rounding).
TEST_F(InteractionMesh, AbsorptionFollowsTheImplicitEulerSequenceTowardsSaturation) {
  LiquidParameters liquid;
  liquid.absorptionRate = 0.1;
  liquid.saturationDensity = 4.0;
  const double h = 0.02;
  state.solvent.setConstant(1e3);
  state.solute.setConstant(50.0);
  const StepContext ctx = interactionContext(h, true, false, false, liquid);
  const double factor = 1.0 / (1.0 + liquid.absorptionRate * h);
  double worst = 0.0;
  for (int step = 1; step <= 2000; ++step) {
    interact(ctx, g.topology, g.intrinsic, allWet, state);
    const double expected = liquid.saturationDensity * (1.0 - std::pow(factor, step));
    worst = std::max(worst, std::abs(state.absorbedSolvent[7] / expected - 1.0));
  }
  const double t = 2000 * h;
  std::printf(
      "  σ_p after %g s: %.10f (discrete %.10f, continuous σ_sat(1 − e^{−K_p t}) %.10f); "
      "worst relative deviation from the sequence %.2e\n",
      t, state.absorbedSolvent[7], liquid.saturationDensity * (1 - std::pow(factor, 2000)),
      liquid.saturationDensity * (1 - std::exp(-liquid.absorptionRate * t)), worst);
  EXPECT_LE(worst, 1e-12);
  EXPECT_NEAR(state.absorbedSolvent[7], liquid.saturationDensity * (1 - std::exp(-liquid.absorptionRate * t)),
              1e-3 * liquid.saturationDensity);  // O(h) from the continuous law
  for (int i = 0; i < g.vertexCount(); ++i) {
    EXPECT_NEAR(state.solvent[i] + state.absorbedSolvent[i], 1e3, 1e-12 * 1e3);
    // Absorption takes solute at the free concentration: both pools keep it.
    EXPECT_NEAR(state.absorbedSolute[i] / state.absorbedSolvent[i], 0.05, 1e-14);
    EXPECT_NEAR(state.solute[i] / state.solvent[i], 0.05, 1e-14);
  }
}

TEST_F(InteractionMesh, AbsorptionIsBoundedByTheFreeSolventAndTakesAllItsSolute) {
  state.solvent.setConstant(0.001);  // far less than K_p h/(1 + K_p h) σ_sat = 0.0079
  state.solute.setConstant(0.0004);
  interact(interactionContext(0.02, true, false, false), g.topology, g.intrinsic, allWet, state);
  for (int i = 0; i < g.vertexCount(); ++i) {
    EXPECT_EQ(state.solvent[i], 0.0);
    EXPECT_EQ(state.absorbedSolvent[i], 0.001);
    EXPECT_EQ(state.solute[i], 0.0);
    EXPECT_EQ(state.absorbedSolute[i], 0.0004);
  }
}

// dσ_s,a/dt = K_d (A_d − σ_s,a), discretised like absorption: the same
// geometric approach to the Langmuir equilibrium A_d.
TEST_F(InteractionMesh, LangmuirAdsorptionReachesTheEquilibriumCapacity) {
  LiquidParameters liquid;
  liquid.desorptionRate = 0.5;
  liquid.adsorptionCapacity = 0.5;
  const double h = 0.025;
  state.solvent.setConstant(10.0);
  state.solute.setConstant(100.0);
  state.adsorbedSolute.setConstant(0.1);
  const StepContext ctx = interactionContext(h, false, true, false, liquid);
  const double factor = 1.0 / (1.0 + liquid.desorptionRate * h);
  double worst = 0.0;
  for (int step = 1; step <= 8000; ++step) {
    interact(ctx, g.topology, g.intrinsic, allWet, state);
    const double expected = 0.5 - (0.5 - 0.1) * std::pow(factor, step);
    worst = std::max(worst, std::abs(state.adsorbedSolute[3] / expected - 1.0));
  }
  std::printf("  σ_s,a after %g s: %.12f (A_d = 0.5); worst deviation from the sequence %.2e\n", 8000 * h,
              state.adsorbedSolute[3], worst);
  EXPECT_LE(worst, 1e-12);
  EXPECT_NEAR(state.adsorbedSolute[3], 0.5, 1e-12);  // K_d t = 100: at equilibrium
  EXPECT_NEAR(state.solute[3] + state.adsorbedSolute[3], 100.1, 1e-12);

  // Limited by the dissolved solute there is.
  state.solute.setConstant(1e-6);
  state.adsorbedSolute.setConstant(0.0);
  interact(ctx, g.topology, g.intrinsic, allWet, state);
  EXPECT_EQ(state.solute[3], 0.0);
  EXPECT_EQ(state.adsorbedSolute[3], 1e-6);

  // Above capacity it desorbs back into the solution, but only into solvent.
  state.solute.setConstant(0.0);
  state.adsorbedSolute.setConstant(0.8);
  interact(ctx, g.topology, g.intrinsic, allWet, state);
  EXPECT_NEAR(state.adsorbedSolute[3], 0.8 - (1 - factor) * 0.3, 1e-15);
  EXPECT_NEAR(state.solute[3], (1 - factor) * 0.3, 1e-15);
  state.solvent.setConstant(0.0);
  state.solute.setConstant(0.0);
  state.adsorbedSolute.setConstant(0.8);
  interact(ctx, g.topology, g.intrinsic, allWet, state);
  EXPECT_EQ(state.adsorbedSolute[3], 0.8) << "a dry deposit does not redissolve";
}

// dσ_f/dt = −a K_evap, a = a_evap on mesh-boundary vertices and 1 inside.
TEST_F(InteractionMesh, EvaporationRateCarriesTheBoundaryFactor) {
  LiquidParameters liquid;
  liquid.evaporationRate = 0.01;
  liquid.boundaryEvaporationFactor = 1.2;
  const double h = 0.02;
  const int steps = 500;
  state.solvent.setConstant(5.0);
  const StepContext ctx = interactionContext(h, false, false, true, liquid);
  for (int step = 0; step < steps; ++step) interact(ctx, g.topology, g.intrinsic, allWet, state);
  double expectedEvaporated = 0.0;
  int boundaryCount = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    const bool onBoundary = g.topology.vertexIsBoundary()[static_cast<size_t>(i)] != 0;
    boundaryCount += onBoundary;
    const double depth = steps * (onBoundary ? 1.2 : 1.0) * 0.01 * h;     // kg/m²
    EXPECT_NEAR(state.solvent[i], 5.0 - depth, 1e-12) << "vertex " << i;  // 500 roundings of 5
    expectedEvaporated += depth * g.areas()[i];
  }
  EXPECT_EQ(boundaryCount, 4 * n);
  EXPECT_NEAR(state.evaporatedSolvent, expectedEvaporated, 1e-13 * expectedEvaporated);
  const int corner = 0, inside = 2 * (n + 1) + 2;
  const double rateRatio = (5.0 - state.solvent[corner]) / (5.0 - state.solvent[inside]);
  std::printf("  evaporated depth boundary/interior: %.15f\n", rateRatio);
  EXPECT_NEAR(rateRatio, 1.2, 1e-10);  // a ratio of differences 0.12 of numbers near 5
}

TEST_F(InteractionMesh, EvaporationTakesAbsorbedSolventWhenTheFreeFilmIsGoneAndIsBounded) {
  LiquidParameters liquid;
  liquid.evaporationRate = 0.5;
  const double h = 0.01;  // demand 0.005 (0.006 on the boundary) per step
  const int inside = 2 * (n + 1) + 2;
  state.solvent[inside] = 0.002;
  state.absorbedSolvent[inside] = 0.0025;
  state.solute[inside] = 0.0003;
  const StepContext ctx = interactionContext(h, false, false, true, liquid);
  interact(ctx, g.topology, g.intrinsic, allWet, state);
  EXPECT_EQ(state.solvent[inside], 0.0);
  EXPECT_EQ(state.absorbedSolvent[inside], 0.0);  // 0.002 + 0.0025 < 0.005: all of it
  EXPECT_NEAR(state.evaporatedSolvent, 0.0045 * g.areas()[inside], 1e-18);
  // The free solute has no solvent left: it is a dry deposit now.
  EXPECT_EQ(state.solute[inside], 0.0);
  EXPECT_EQ(state.adsorbedSolute[inside], 0.0003);
  EXPECT_TRUE((state.solvent.array() >= 0).all() && (state.absorbedSolvent.array() >= 0).all());
}

TEST_F(InteractionMesh, EveryLawTogetherConservesSoluteAndSolventExactly) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < g.vertexCount(); ++i) {
    state.solvent[i] = unit(rng) < 0.3 ? 0.0 : 3.0 * unit(rng);
    state.solute[i] = 0.4 * unit(rng) * state.solvent[i];
    state.absorbedSolvent[i] = 2.0 * unit(rng);
    state.absorbedSolute[i] = 0.1 * unit(rng);
    state.adsorbedSolute[i] = 0.7 * unit(rng);  // some above A_d = 0.5
  }
  LiquidParameters liquid;
  liquid.evaporationRate = 0.05;
  const StepContext ctx = interactionContext(0.025, true, true, true, liquid);
  const double solute0 = soluteTotal(), solvent0 = solventTotal();
  double worstSolute = 0.0, worstSolvent = 0.0;
  for (int step = 0; step < 400; ++step) {
    interact(ctx, g.topology, g.intrinsic, allWet, state);
    worstSolute = std::max(worstSolute, std::abs(soluteTotal() / solute0 - 1.0));
    worstSolvent = std::max(worstSolvent, std::abs(solventTotal() / solvent0 - 1.0));
    ASSERT_GE(std::min({state.solvent.minCoeff(), state.solute.minCoeff(), state.absorbedSolvent.minCoeff(),
                        state.absorbedSolute.minCoeff(), state.adsorbedSolute.minCoeff()}),
              0.0);
  }
  std::printf(
      "  400 steps, every law on: solute drift %.2e, solvent (free + absorbed + evaporated) drift %.2e; "
      "free solvent left %.3e kg\n",
      worstSolute, worstSolvent, totalMass(g.areas(), state.solvent));
  EXPECT_LE(worstSolute, 1e-15);
  EXPECT_LE(worstSolvent, 1e-15);
}

TEST_F(InteractionMesh, DryVerticesAreSkippedUnlessTheirFibresStillHoldSolvent) {
  const int wetVertex = 8, dryVertex = 9, dampVertex = 10;
  state.solvent[wetVertex] = 1.0;
  state.solute[dryVertex] = 0.2;            // a deposit on a dry vertex: left alone
  state.absorbedSolvent[dampVertex] = 1.0;  // dry on top, wet fibres: still evaporates
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  wet[wetVertex] = 1;
  interact(interactionContext(0.02, true, true, true), g.topology, g.intrinsic, wet, state);
  EXPECT_LT(state.solvent[wetVertex], 1.0);
  EXPECT_EQ(state.solute[dryVertex], 0.2);
  EXPECT_EQ(state.adsorbedSolute[dryVertex], 0.0);
  EXPECT_NEAR(state.absorbedSolvent[dampVertex], 1.0 - 0.01 * 0.02, 1e-15);

  // Switches off: nothing at all changes.
  const StainState before = state;
  interact(interactionContext(0.02, false, false, false), g.topology, g.intrinsic, wet, state);
  EXPECT_TRUE((state.solvent.array() == before.solvent.array()).all());
  EXPECT_EQ(state.evaporatedSolvent, before.evaporatedSolvent);
}

// The paper's Fig. 11 experiment without advection: a spot on a disc with
// diffusion, absorption, adsorption and evaporation. Finding (measured, and
// what this test pins down): no ring. σ_s and σ_f diffuse by the same linear
// law, so evaporation concentrates the solution but does not move solute; the
// thin edge dries first and deposits little, the centre dries last. A coffee
// ring needs an outward flow towards the evaporating edge (advection), which
// these stages do not produce. Conservation is checked every step.
TEST(InteractionRing, SpotOnADiscWithDiffusionAndInteractionOnlyDepositsMostAtTheCentre) {
  const int rings = 30;
  TriangleMesh mesh = discMesh(rings, 1.0);
  const int faces = static_cast<int>(mesh.faces.rows());
  const double diffusivity = 1e-3;  // m²/s
  const LiquidMesh g(std::move(mesh), uniformFabric(faces, fabricTensor(diffusivity, diffusivity),
                                                    fabricTensor(diffusivity, diffusivity), 0.0));
  StainState state = zeroState(g.vertexCount());
  DropDef drop;
  drop.centerVertex = 0;
  drop.radius = 0.5;
  drop.solventMass = 1.0;
  drop.soluteMass = 0.1;
  addDrop(drop, g.topology, g.intrinsic, g.extrinsic, state);

  LiquidParameters liquid;
  liquid.absorptionRate = 0.02;
  liquid.evaporationRate = 0.2;  // evaporation faster than absorption: the regime that favours a ring
  PhysicsSwitches switches;
  switches.velocityDiffusion = false;
  const double h = 0.02;
  const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, liquid);
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  const std::vector<char> allWet;
  auto solute = [&] {
    return totalMass(g.areas(), state.solute) + totalMass(g.areas(), state.absorbedSolute) +
           totalMass(g.areas(), state.adsorbedSolute);
  };
  auto solvent = [&] {
    return totalMass(g.areas(), state.solvent) + totalMass(g.areas(), state.absorbedSolvent) +
           state.evaporatedSolvent;
  };
  double worstSolute = 0.0, worstSolvent = 0.0;
  int dryStep = -1;
  for (int step = 0; step < 600; ++step) {
    ASSERT_EQ(diffuse(ctx, g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
    interact(ctx, g.topology, g.intrinsic, allWet, state);
    worstSolute = std::max(worstSolute, std::abs(solute() / drop.soluteMass - 1));
    worstSolvent = std::max(worstSolvent, std::abs(solvent() / drop.solventMass - 1));
    if (dryStep < 0 && state.solvent.maxCoeff() <= 0.0) dryStep = step;
  }
  ASSERT_GT(dryStep, 0) << "the stain should have dried";

  // Radial profile of the deposit (all solute pools), area-weighted per ring.
  std::vector<double> deposit(rings + 1, 0.0), area(rings + 1, 0.0);
  for (int i = 0; i < g.vertexCount(); ++i) {
    const int r = static_cast<int>(std::lround(g.position(i).head<2>().norm() * rings));
    deposit[r] += g.areas()[i] * (state.solute[i] + state.absorbedSolute[i] + state.adsorbedSolute[i]);
    area[r] += g.areas()[i];
  }
  for (int r = 0; r <= rings; ++r) deposit[r] /= area[r];
  int edge = 0;  // outermost ring holding at least 1 % of the central deposit
  for (int r = 0; r <= rings; ++r) {
    if (deposit[r] >= 0.01 * deposit[0]) edge = r;
  }
  double rim = 0.0;
  for (int r = edge / 2; r <= edge; ++r) rim = std::max(rim, deposit[r]);
  std::printf("  dried at t = %.2f s; stain edge at r = %.3f; deposit (kg/m²) by radius:", dryStep * h,
              double(edge) / rings);
  for (int r = 0; r <= edge + 1; r += 2) std::printf(" %.2f:%.4f", double(r) / rings, deposit[r]);
  std::printf("\n  rim/centre = %.3f (a ring needs > 1); conservation: solute %.2e, solvent %.2e\n",
              rim / deposit[0], worstSolute, worstSolvent);
  EXPECT_LE(worstSolute, 1e-12);
  EXPECT_LE(worstSolvent, 1e-12);
  EXPECT_LT(rim, deposit[0]);
  for (int r = 1; r <= edge; ++r) EXPECT_LE(deposit[r], deposit[r - 1] * (1 + 1e-2)) << "ring " << r;
}

}  // namespace
}  // namespace blot::stain
