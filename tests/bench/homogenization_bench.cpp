// Homogenization cost: a 32x32-cell tile of random SPD tensors on the uniform
// mesh at K = 4 (16,384 unknowns) and K = 8 (65,536) and refined until the
// bounds meet; a 32x32-cell woven tile (random interlacing, the default pair
// coefficients) to a 1 % gap; each preset and the 1:100 / 1:1000 chessboards
// to a 1 % gap; and a Homogenizer cache hit (what a second patch with the same
// pattern pays).
//
//   homogenization_bench --benchmark_counters_tabular=true
//
// Counters: unknowns (vertices of the final mesh), K (uniform K, or the graded
// mesh's intervals per cell side), levels (meshes solved), gap, converged.
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <string>
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

// 32 x 32 cells: 16 x 16 thread crossings, warp or weft on top at random; fixed seed.
WeavePattern wovenTile32() {
  std::mt19937 rng(7u);
  std::vector<std::string> cells(32, std::string(32, 'G'));
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 16; ++j) {
      cells[2 * i][2 * j] = (rng() & 1u) ? 'W' : 'F';
      cells[2 * i][2 * j + 1] = 'F';
      cells[2 * i + 1][2 * j] = 'W';
    }
  }
  return weavePatternFromCells(cells, defaultPairCoefficients(), "woven 32x32");
}

WeavePattern chessboard(double contrast) {
  const Matrix2 a = Matrix2::Identity(), b = contrast * Matrix2::Identity();
  return WeavePattern(2, 2, {a, b, b, a}, "chessboard");
}

void setCounters(benchmark::State& state, const HomogenizationResult& r) {
  state.counters["unknowns"] = r.vertexCount;
  state.counters["K"] = r.subdivisions;
  state.counters["levels"] = r.levels;
  state.counters["gap"] = r.gap;
  state.counters["converged"] = r.converged ? 1 : 0;
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
BENCHMARK(BM_HomogenizeTile32)->Arg(kAutoSubdivisions)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);

void BM_HomogenizeWovenTile32(benchmark::State& state) {
  const WeavePattern tile = wovenTile32();
  HomogenizationResult r;
  for (auto _ : state) {
    r = homogenize(tile);
    benchmark::DoNotOptimize(r.effective.data());
  }
  setCounters(state, r);
}
BENCHMARK(BM_HomogenizeWovenTile32)->Unit(benchmark::kMillisecond);

void BM_HomogenizeChessboard(benchmark::State& state) {
  const WeavePattern board = chessboard(static_cast<double>(state.range(0)));
  HomogenizationResult r;
  for (auto _ : state) {
    r = homogenize(board);
    benchmark::DoNotOptimize(r.effective.data());
  }
  setCounters(state, r);
}
BENCHMARK(BM_HomogenizeChessboard)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond)->Iterations(1);

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
