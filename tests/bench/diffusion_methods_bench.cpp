// One density + velocity diffusion solve (stage "diffuse", limiter on) by each
// method DiffusionSystems offers, at a game's frame step h = 1/60 s on a
// 256 x 256 grid (66K vertices): the factor (its numeric factorization done
// in set-up, so the row is the steady-state solve of a rigid mesh), CG on the
// support, RKL2 on the support, and Auto (docs/performance.md, "The cheapest
// solver"). Arguments: spot radius in % of the side (10: ~3 % wet, 45: ~60 %),
// and h D_weft / dx² × 100 (the tensor is (D, D/10) at 30°; max h L_ii / A_i
// is ~3.3× that ratio). Counters: rows (the solve's rows), work (RKL2 stages
// or CG iterations of the density solve), method (DiffusionMethod).
// Run: diffusion_methods_bench --benchmark_format=json > out.json.
#include <benchmark/benchmark.h>
#include <blot/stain/stages/diffusion.h>

#include <memory>
#include <stdexcept>
#include <tuple>

#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;

constexpr int kCells = 256;
constexpr double kStep = 1.0 / 60;

struct Scene {
  std::unique_ptr<LiquidMesh> mesh;
  DiffusionSystems systems;
  DiffusionScratch scratch;
  StainState initial, state;
  StepContext ctx;

  Scene(DiffusionSolverChoice choice, double radius, double stiffness) {
    const double dx = 1.0 / kCells;
    const double weft = stiffness * dx * dx / kStep;  // m²/s
    mesh = std::make_unique<LiquidMesh>(gridMesh(kCells, kCells, 1, 1),
                                        uniformFabric(2 * kCells * kCells, fabricTensor(weft, 0.1 * weft),
                                                      fabricTensor(0.5 * weft, 0.05 * weft), kPi / 6));
    systems.setSolverChoice(choice);
    const SolverStatus status = choice == DiffusionSolverChoice::Direct ? systems.factorize(mesh->intrinsic, kStep)
                                                                        : systems.assemble(mesh->intrinsic, kStep);
    if (status != SolverStatus::Ok) throw std::runtime_error("assemble");
    scratch.resize(mesh->vertexCount());
    initial = zeroState(mesh->vertexCount());
    initial.solvent = spot(*mesh, Vector2(0.5, 0.5), radius, 1.0);
    initial.solute = 0.1 * initial.solvent;
    for (int i = 0; i < mesh->vertexCount(); ++i)
      if (initial.solvent[i] > 0) initial.velocities[i] = Complex(0.1, -0.05 * initial.solvent[i]);
    state = initial;
    PhysicsSwitches switches;
    ctx = makeStepContext(kStep, Vector3(0, 0, -9.8), switches, LiquidParameters{});
  }
};

// One scene alive at a time (a 66K mesh and, for the factor, its factor).
Scene& scene(DiffusionSolverChoice choice, int radiusPercent, int stiffnessPercent) {
  static std::tuple<int, int, int> key{-1, -1, -1};
  static std::unique_ptr<Scene> current;
  const std::tuple<int, int, int> wanted{static_cast<int>(choice), radiusPercent, stiffnessPercent};
  if (!current || key != wanted) {
    current.reset();
    current = std::make_unique<Scene>(choice, radiusPercent / 100.0, stiffnessPercent / 100.0);
    key = wanted;
  }
  return *current;
}

void run(benchmark::State& bench, DiffusionSolverChoice choice) {
  Scene& s = scene(choice, static_cast<int>(bench.range(0)), static_cast<int>(bench.range(1)));
  DiffusionReport r;
  for (auto _ : bench) {
    bench.PauseTiming();
    s.state.solvent = s.initial.solvent;
    s.state.solute = s.initial.solute;
    s.state.velocities = s.initial.velocities;
    bench.ResumeTiming();
    r = diffuse(s.ctx, s.mesh->intrinsic, s.systems, s.scratch, s.state);
    if (r.status != SolverStatus::Ok) bench.SkipWithError(toString(r.status));
  }
  bench.counters["rows"] =
      r.densityMethod == DiffusionMethod::Direct ? s.mesh->vertexCount() : r.densityActiveVertices;
  bench.counters["work"] = r.densityStages + r.densityIterations;
  bench.counters["method"] = static_cast<int>(r.densityMethod);
}

void Direct(benchmark::State& s) { run(s, DiffusionSolverChoice::Direct); }
void Cg(benchmark::State& s) { run(s, DiffusionSolverChoice::Iterative); }
void Rkl2(benchmark::State& s) { run(s, DiffusionSolverChoice::SuperTimeStepping); }
void Auto(benchmark::State& s) { run(s, DiffusionSolverChoice::Auto); }

// {spot radius %, h D / dx² × 100}
#define BLOT_DIFFUSION_ARGS \
  ->Args({10, 25})->Args({10, 100})->Args({10, 400})->Args({45, 25})->Args({45, 100})->Args({45, 400}) \
  ->Unit(benchmark::kMillisecond)
BENCHMARK(Direct) BLOT_DIFFUSION_ARGS;
BENCHMARK(Cg) BLOT_DIFFUSION_ARGS;
BENCHMARK(Rkl2) BLOT_DIFFUSION_ARGS;
BENCHMARK(Auto) BLOT_DIFFUSION_ARGS;

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
