// Soaked vertices filed apart from the wet set (StainSolverDef::soakedApart,
// docs/transport.md "Soaked vertices"): the band, and the work on it, follow
// the free liquid, while the stain stays what the wet-set rule (soaked
// vertices wet, their u cleared every step) gives. A waving flag
// whose stain soaks in within a second, so that most of its wet area is
// soaked while free liquid still runs down to the hem.
#include <blot/coupling/coupled_surface.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "flag_fixture.h"

namespace blot::coupling {
namespace {

constexpr double kFrame = 1.0 / 60;

struct SoakRun {
  stain::StainState state;
  Eigen::VectorXd liquidMasses;   // kg per node at the end
  long bandVertices = 0;          // summed over the steps after the drop
  long soakedSteps = 0;           // steps with soaked vertices filed apart
  double fastest = 0;             // largest |u| on a wet vertex after any step (m/s)
  bool healthy = true;
};

SoakRun runSoakingFlag(bool soakedApart, int frames) {
  test::CoupledFlag flag = test::makeCoupledFlag(49, true);
  flag.stain.liquid.absorptionRate = 1.0;
  flag.stain.soakedApart = soakedApart;
  flag.stain.strainTolerance = 0.02;
  for (cloth::ClothPin& pin : flag.cloth.pins) {
    pin.motion.amplitude = Eigen::Vector3d(0, 0.1, 0);
    pin.motion.frequency = 1.0;
  }
  // One-way: the cloth moves the same in both runs, so the difference is the
  // stain's own. (Two-way, the cloth amplifies any difference: a 1e-9 change
  // of the drop's mass moves the free solvent by 2e-3 in L1 over these 2 s.)
  auto surface = test::makeCoupledSurface(flag, CouplingMode::OneWay);
  SoakRun run;
  for (int k = 0; k < 30; ++k) run.healthy &= surface->step(kFrame).ok();
  surface->stain().addDrop(test::heavyCentreDrop(flag));
  for (int k = 0; k < frames && run.healthy; ++k) {
    const stain::StepReport report = surface->step(kFrame);
    EXPECT_TRUE(report.ok()) << "frame " << k << ": " << report.message;
    run.healthy &= report.ok();
    const stain::StainSolver& s = surface->stain();
    run.bandVertices += s.profile().bandVertices;
    run.soakedSteps += s.profile().soakedVertices > 0 ? 1 : 0;
    const stain::LiquidBand& band = s.band();
    for (int w = 0; w < band.wetCount(); ++w)
      run.fastest = std::max(run.fastest, std::abs(s.state().velocities[band.vertices[static_cast<size_t>(w)]]));
  }
  run.state = surface->stain().state();
  run.liquidMasses = surface->liquidNodeMasses();
  return run;
}

double relativeL1(const stain::Vector& a, const stain::Vector& b) {
  return (a - b).lpNorm<1>() / std::max(a.lpNorm<1>(), 1e-300);
}

// 2 s after the drop (120 steps). Measured: band
// vertices per step 1,318 (wet-set rule) against 356 (apart); relative L1
// differences of the fields 1.5e-3 to 2.8e-3, evaporated mass 7.5e-4;
// fastest wet u 3.299 and 3.297 m/s. The tolerances are a few times those.
TEST(SoakedApart, TheBandFollowsTheFreeLiquidAndTheStainStaysTheWetSetRules) {
  const int frames = 120;
  const SoakRun reference = runSoakingFlag(false, frames);
  const SoakRun apart = runSoakingFlag(true, frames);
  ASSERT_TRUE(reference.healthy && apart.healthy);
  EXPECT_EQ(reference.soakedSteps, 0);
  EXPECT_GT(apart.soakedSteps, frames / 2) << "the stain should have soaked in";

  const double free = relativeL1(reference.state.solvent, apart.state.solvent);
  const double absorbed = relativeL1(reference.state.absorbedSolvent, apart.state.absorbedSolvent);
  const double solute = relativeL1(reference.state.solute + reference.state.absorbedSolute + reference.state.adsorbedSolute,
                                   apart.state.solute + apart.state.absorbedSolute + apart.state.adsorbedSolute);
  const double masses = relativeL1(reference.liquidMasses, apart.liquidMasses);
  const double evaporated = std::abs(reference.state.evaporatedSolvent - apart.state.evaporatedSolvent) /
                            reference.state.evaporatedSolvent;
  std::printf("soaked apart vs the wet-set rule, 2 s after the drop: band vertices per step %.0f vs %.0f; "
              "relative L1 difference: free solvent %.2e, absorbed %.2e, solute %.2e, node masses %.2e; "
              "evaporated %.2e; fastest wet u %.3f vs %.3f m/s\n",
              static_cast<double>(apart.bandVertices) / frames, static_cast<double>(reference.bandVertices) / frames,
              free, absorbed, solute, masses, evaporated, apart.fastest, reference.fastest);
  EXPECT_LT(2 * apart.bandVertices, reference.bandVertices) << "the band should follow the free liquid";
  EXPECT_LT(free, 1e-2);
  EXPECT_LT(absorbed, 1e-2);
  EXPECT_LT(solute, 1e-2);
  EXPECT_LT(masses, 1e-2);
  EXPECT_LT(evaporated, 1e-2);
  // A wet set of the free liquid alone, with soaked vertices treated as dry
  // ones, let the free liquid next to soaked cloth run away (u growing by g h a step); here u stays what the rule gives.
  EXPECT_LT(apart.fastest, 1.25 * reference.fastest + 0.05);
}

}  // namespace
}  // namespace blot::coupling
