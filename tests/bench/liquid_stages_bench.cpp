// Per-step cost of the stages "diffuse", "interact" and "sources" and of the
// positivity limiter and the numeric refactorization, on flat grids of the
// paper's Table 1 sizes (2.5K, 10K, 35K vertices).
//
// Fabric: eigenvalue ratio 10 with the weft at 30° (ratio 1e6 for the
// "StrongAnisotropy" rows), h = 0.01 s, h·D_weft/dx² = 10. State: a spot
// covering about a quarter of the sheet (solvent, solute, velocity).
// Counters: n (vertices), fixes (limiter corrections per step).
// Run: liquid_stages_bench --benchmark_format=json > out.json.
#include <benchmark/benchmark.h>
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/stages/interaction.h>
#include <blot/stain/stages/sources.h>

#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <vector>

#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;

constexpr int kGridCells[] = {49, 99, 186};  // ~2.5K, 10K, 35K vertices
constexpr double kStep = 0.01;               // s
constexpr double kWeftDiffusionSteps = 10;   // h·D_weft / dx²

struct Scene {
  std::unique_ptr<LiquidMesh> mesh;
  DiffusionSystems systems;
  DiffusionScratch scratch;
  StainState state;
  StepContext ctx;

  Scene(int cells, double ratio) {
    const double dx = 1.0 / cells;
    const double weft = kWeftDiffusionSteps * dx * dx / kStep;  // m²/s
    mesh = std::make_unique<LiquidMesh>(gridMesh(cells, cells, 1, 1),
                                        uniformFabric(2 * cells * cells, fabricTensor(weft, weft / ratio),
                                                      fabricTensor(weft, weft / ratio), kPi / 6));
    if (systems.factorize(mesh->intrinsic, kStep) != SolverStatus::Ok) throw std::runtime_error("factorize");
    scratch.resize(mesh->vertexCount());
    state = zeroState(mesh->vertexCount());
    for (int i = 0; i < mesh->vertexCount(); ++i) {
      const double r = (mesh->position(i).head<2>() - Vector2(0.5, 0.5)).norm() / 0.3;
      if (r < 1) {
        state.solvent[i] = 5.0 * (1 - r * r) * (1 - r * r);
        state.solute[i] = 0.1 * state.solvent[i];
        state.velocities[i] = Complex(0.1, 0.05);
      }
    }
    PhysicsSwitches switches;
    ctx = makeStepContext(kStep, Vector3(0, 0, -9.8), switches, LiquidParameters{});
  }
};

Scene& scene(int cells, double ratio) {
  static std::map<std::pair<int, double>, std::unique_ptr<Scene>> scenes;
  auto& slot = scenes[{cells, ratio}];
  if (!slot) slot = std::make_unique<Scene>(cells, ratio);
  return *slot;
}

void diffuseBench(benchmark::State& bench, double ratio) {
  Scene& s = scene(static_cast<int>(bench.range(0)), ratio);
  long fixes = 0;
  for (auto _ : bench) {
    const DiffusionReport report = diffuse(s.ctx, s.mesh->intrinsic, s.systems, s.scratch, s.state);
    if (report.status != SolverStatus::Ok) bench.SkipWithError("diffuse failed");
    fixes += report.limiterCorrectedVertices;
  }
  bench.counters["n"] = s.mesh->vertexCount();
  bench.counters["fixes"] =
      benchmark::Counter(static_cast<double>(fixes), benchmark::Counter::kAvgIterations);
}

void BM_Diffuse(benchmark::State& bench) { diffuseBench(bench, 10.0); }
void BM_DiffuseStrongAnisotropy(benchmark::State& bench) { diffuseBench(bench, 1e6); }

void BM_Refactorize(benchmark::State& bench) {
  Scene& s = scene(static_cast<int>(bench.range(0)), 10.0);
  for (auto _ : bench) {
    if (s.systems.factorize(s.mesh->intrinsic, kStep) != SolverStatus::Ok)
      bench.SkipWithError("factorize failed");
  }
  bench.counters["n"] = s.mesh->vertexCount();
}

void BM_Limiter(benchmark::State& bench) {
  Scene& s = scene(static_cast<int>(bench.range(0)), 1e6);
  // One raw anisotropic step from the spot (its undershoot), limited afresh
  // each iteration: what the limiter does after every solve.
  StepContext raw = s.ctx;
  raw.switches.positivityLimiter = false;
  StainState state = s.state;
  diffuse(raw, s.mesh->intrinsic, s.systems, s.scratch, state);
  Vector field = state.solvent;
  const Vector& areas = s.mesh->areas();
  long fixes = 0;
  for (auto _ : bench) {
    field = state.solvent;
    fixes += limitPositivity(s.mesh->topology, areas, field).first;
    benchmark::DoNotOptimize(field.data());
  }
  bench.counters["n"] = s.mesh->vertexCount();
  bench.counters["fixes"] =
      benchmark::Counter(static_cast<double>(fixes), benchmark::Counter::kAvgIterations);
}

void BM_Interact(benchmark::State& bench) {
  Scene& s = scene(static_cast<int>(bench.range(0)), 10.0);
  StainState state = s.state;
  state.solvent.array() += 1e3;  // wet everywhere for the whole run
  const std::vector<char> allWet;
  for (auto _ : bench) interact(s.ctx, s.mesh->topology, s.mesh->intrinsic, allWet, state);
  bench.counters["n"] = s.mesh->vertexCount();
}

void BM_ApplySources(benchmark::State& bench) {
  Scene& s = scene(static_cast<int>(bench.range(0)), 10.0);
  StainState state = s.state;
  HeldRegion region;
  for (int i = 0; i < s.mesh->vertexCount(); i += 50) region.vertices.push_back(i);
  region.solventDensity = 8.0;
  region.soluteDensity = 0.8;
  const std::vector<HeldRegion> regions = {region};
  for (auto _ : bench) {
    applySources(s.ctx, regions, s.mesh->intrinsic, state);
    state.solvent[0] = 0.0;  // keep one vertex below its held density
  }
  bench.counters["n"] = s.mesh->vertexCount();
}

void sizes(benchmark::internal::Benchmark* b) {
  for (int cells : kGridCells) b->Arg(cells);
  b->Unit(benchmark::kMicrosecond);
}

BENCHMARK(BM_Diffuse)->Apply(sizes);
BENCHMARK(BM_DiffuseStrongAnisotropy)->Apply(sizes);
BENCHMARK(BM_Refactorize)->Apply(sizes);
BENCHMARK(BM_Limiter)->Apply(sizes);
BENCHMARK(BM_Interact)->Apply(sizes);
BENCHMARK(BM_ApplySources)->Apply(sizes);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
