// The coupled 2.5K-vertex two-way flag: per 1/60 s step, the
// Bullet cloth step, the stain step and the coupling, and in the same loop a
// bare Bullet cloth (same mesh, same ClothDef, no liquid) stepped alongside,
// so both see the same machine load. Target: stain + coupling ≤ 0.25 × bare Bullet.
//  - Arg strain: the stain's strainTolerance in per mille (1 = the default
//    1e-3, which on a Bullet cloth rebuilds the stain's intrinsic tier and
//    refactorizes every step; 20 = 2%, what the coupled tests use; 50 = 5%,
//    the Bullet scenes' default; 1000 =
//    never rebuild, to show what the rebuilds cost).
//  - Arg free_velocity: PhysicsSwitches::velocityOnFreeLiquid (1, the default:
//    u = 0 at soaked vertices without free liquid; 0: their u keeps
//    accumulating the forces).
// Counters (ms per step, wall clock, mean over the timed steps): bullet,
// stain, coupling, bare (the bare Bullet step), ratio = (stain + coupling) /
// bare, rebuilds = fraction of steps that rebuilt the stain's intrinsic tier,
// substeps = density-advection sub-steps per step, band = the liquid band's
// vertices per step (both set by the fastest velocity in the wet set),
// healthy = both cloths healthy at the end.
// Run: coupled_flag_bench --benchmark_counters_tabular=true
#include <blot/coupling/coupled_surface.h>

#include <benchmark/benchmark.h>

#include <chrono>

#include "flag_fixture.h"

namespace blot::coupling {
namespace {

constexpr double kFrame = 1.0 / 60;

void BM_CoupledFlag(benchmark::State& state) {
  test::CoupledFlag flag = test::makeCoupledFlag(49, true);
  flag.stain.strainTolerance = 1e-3 * static_cast<double>(state.range(0));
  flag.stain.switches.velocityOnFreeLiquid = state.range(1) != 0;
  auto coupled = test::makeCoupledSurface(flag, CouplingMode::TwoWay);
  cloth::BulletCloth bare(flag.cloth);
  // Settle 0.5 s, add a heavy stain (as heavy as the cloth), let it spread 0.5 s.
  for (int k = 0; k < 30; ++k) {
    coupled->step(kFrame);
    bare.advance(kFrame);
  }
  stain::DropDef drop;
  drop.centerVertex = flag.center();
  drop.radius = 0.25;
  drop.solventMass = 0.15;
  drop.soluteMass = 0.015;
  coupled->stain().addDrop(drop);
  for (int k = 0; k < 30; ++k) {
    coupled->step(kFrame);
    bare.advance(kFrame);
  }
  double bullet = 0, stainMs = 0, coupling = 0, bareMs = 0;
  long steps = 0, rebuilds = 0;
  long substeps = 0, band = 0;
  for (auto _ : state) {
    coupled->step(kFrame);
    const auto start = std::chrono::steady_clock::now();
    bare.advance(kFrame);
    bareMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const CoupledStepTimes& t = coupled->lastTimes();
    bullet += t.cloth;
    stainMs += t.stain;
    coupling += t.coupling;
    rebuilds += coupled->stain().profile().intrinsicRefreshes;
    substeps += coupled->stain().profile().advectionSubsteps;
    band += coupled->stain().profile().bandVertices;
    ++steps;
  }
  const double n = static_cast<double>(steps);
  state.counters["bullet"] = bullet / n;
  state.counters["stain"] = stainMs / n;
  state.counters["coupling"] = coupling / n;
  state.counters["bare"] = bareMs / n;
  state.counters["ratio"] = (stainMs + coupling) / bareMs;
  state.counters["rebuilds"] = static_cast<double>(rebuilds) / n;
  state.counters["substeps"] = static_cast<double>(substeps) / n;
  state.counters["band"] = static_cast<double>(band) / n;
  state.counters["wet"] = coupled->stain().profile().wetVertices;
  state.counters["healthy"] = coupled->motion().isHealthy() && bare.isHealthy() ? 1 : 0;
}
BENCHMARK(BM_CoupledFlag)
    ->ArgNames({"strain", "free_velocity"})
    ->ArgsProduct({{1, 20, 50, 1000}, {0, 1}})
    ->Iterations(300)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::coupling

BENCHMARK_MAIN();
