// Homogenization cost: a 32x32-cell tile of random SPD tensors at the default
// K (4: 16,384 unknowns) and at K = 8 (65,536), each preset at its default K,
// and a Homogenizer cache hit (what a second patch with the same pattern pays).
//
//   homogenization_bench --benchmark_counters_tabular=true
//
// Counters: unknowns (torus vertices = rows·cols·K²), K.
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

namespace blot::stain {
namespace {

// 32 x 32 cells, eigenvalues log-uniform in [1, e^5], random orientations; fixed seed.
WeavePattern randomTile32() {
  std::mt19937 rng(20240611u);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Matrix2> tensors;
  for (int i = 0; i < 32 * 32; ++i) {
    const double a = std::exp(5.0 * unit(rng)), b = std::exp(5.0 * unit(rng)), angle = 3.14159 * unit(rng);
    Matrix2 q;
    q << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
    tensors.push_back(q * Vector2(a, b).asDiagonal() * q.transpose());
  }
  return WeavePattern(32, 32, tensors, "random 32x32");
}

void setCounters(benchmark::State& state, const HomogenizationResult& r) {
  state.counters["unknowns"] = r.vertexCount;
  state.counters["K"] = r.subdivisions;
}

void BM_HomogenizeTile32(benchmark::State& state) {
  const WeavePattern tile = randomTile32();
  const int K = static_cast<int>(state.range(0));
  HomogenizationResult r;
  for (auto _ : state) {
    r = homogenize(tile, K);
    benchmark::DoNotOptimize(r.effective.data());
  }
  setCounters(state, r);
}
BENCHMARK(BM_HomogenizeTile32)->Arg(kAutoSubdivisions)->Arg(8)->Unit(benchmark::kMillisecond);

void BM_HomogenizePreset(benchmark::State& state) {
  const WeavePreset preset = weavePresets()[static_cast<size_t>(state.range(0))];
  const WeavePattern pattern = presetWeavePattern(preset.name);
  state.SetLabel(preset.name);
  HomogenizationResult r;
  for (auto _ : state) {
    r = homogenize(pattern);
    benchmark::DoNotOptimize(r.effective.data());
  }
  setCounters(state, r);
}
BENCHMARK(BM_HomogenizePreset)->DenseRange(0, 5)->Unit(benchmark::kMillisecond);

void BM_HomogenizerCacheHit(benchmark::State& state) {
  const WeavePattern tile = randomTile32();
  Homogenizer homogenizer;
  homogenizer.homogenize(tile);
  for (auto _ : state) benchmark::DoNotOptimize(homogenizer.homogenize(tile).effective.data());
}
BENCHMARK(BM_HomogenizerCacheHit)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
