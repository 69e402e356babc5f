// Geometry refresh (extrinsic tier) under rigid rotation on grids of the
// paper's Table 1 sizes (2.5K, 10K, 35K vertices), 1 and 2 threads, with the
// warm-started Newton rotation fit (method 0), an SVD at every vertex (1), and
// the known-rigid path that fits nothing (2); plus the per-vertex cost of the
// rotation fits alone.
//
//   geometry_refresh_bench --benchmark_counters_tabular=true
//
// Counters: ns_per_vertex (wall time per vertex), newton_iterations (average
// per vertex), strain (largest edge strain, ~1e-16 for rigid motion).
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>

#include <benchmark/benchmark.h>
#include <omp.h>

#include <cmath>
#include <random>
#include <vector>

namespace blot::stain {
namespace {

constexpr double kStep = 0.01;  // s
const Vector3 kOmega(0.3, -1.2, 2.0);  // rad/s

// A wavy square sheet with about `vertexCount` vertices.
TriangleMesh wavySheet(int vertexCount) {
  const int n = static_cast<int>(std::lround(std::sqrt(static_cast<double>(vertexCount)))) - 1;
  TriangleMesh mesh = gridMesh(n, n, 1.0, 1.0);
  for (Eigen::Index v = 0; v < mesh.vertexPositions.rows(); ++v) {
    const double x = mesh.vertexPositions(v, 0), y = mesh.vertexPositions(v, 1);
    mesh.vertexPositions(v, 2) = 0.1 * std::sin(3 * x) * std::cos(2 * y);
  }
  return mesh;
}

Matrix3 rotationAt(double t) {
  return Eigen::AngleAxisd(kOmega.norm() * t, kOmega.normalized()).toRotationMatrix();
}

// Args: vertices, threads, method (0 Newton fit, 1 SVD fit, 2 known rigid motion: no fit).
void BM_RefreshExtrinsicRigidRotation(benchmark::State& state) {
  const TriangleMesh mesh = wavySheet(static_cast<int>(state.range(0)));
  const int threads = static_cast<int>(state.range(1));
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const int n = topology.vertexCount();
  SurfaceGeometry geometry(topology, mesh.vertexPositions, isotropicFabricField(topology.faceCount(), 1.0, 1.0));
  const int method = static_cast<int>(state.range(2));
  geometry.setRotationFitMethod(method == 1 ? RotationFitMethod::Svd : RotationFitMethod::WarmStartedNewton);
  auto refresh = [&](const RowVectors3& next, int step) {
    return method == 2 ? geometry.refreshExtrinsicRigid(next, rotationAt(step * kStep), kStep)
                       : geometry.refreshExtrinsic(next, kStep);
  };
  const int savedThreads = omp_get_max_threads();
  omp_set_num_threads(threads);
  RowVectors3 next(n, 3);
  int step = 0;
  auto advance = [&] {
    ++step;
    next.noalias() = mesh.vertexPositions * rotationAt(step * kStep).transpose();
  };
  // Two warm-up steps so the constant-velocity extrapolation has its history.
  for (int i = 0; i < 2; ++i) {
    advance();
    refresh(next, step);
  }
  long iterations = 0;
  for (auto _ : state) {
    state.PauseTiming();
    advance();
    state.ResumeTiming();
    benchmark::DoNotOptimize(refresh(next, step));
    iterations += geometry.rotationFitStats().newtonIterations;
  }
  omp_set_num_threads(savedThreads);
  state.counters["vertices"] = n;
  state.counters["ns_per_vertex"] = benchmark::Counter(
      static_cast<double>(n), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["newton_iterations"] =
      static_cast<double>(iterations) / (static_cast<double>(state.iterations()) * n);
  state.counters["strain"] = geometry.maxEdgeStrain();
}
BENCHMARK(BM_RefreshExtrinsicRigidRotation)
    ->ArgNames({"vertices", "threads", "method"})
    ->ArgsProduct({{2500, 10000, 35000}, {1, 2}, {0, 1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A static mesh: the refresh is one comparison of the positions.
void BM_RefreshExtrinsicStatic(benchmark::State& state) {
  const TriangleMesh mesh = wavySheet(static_cast<int>(state.range(0)));
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  SurfaceGeometry geometry(topology, mesh.vertexPositions, isotropicFabricField(topology.faceCount(), 1.0, 1.0));
  for (auto _ : state) benchmark::DoNotOptimize(geometry.refreshExtrinsic(mesh.vertexPositions, kStep));
}
BENCHMARK(BM_RefreshExtrinsicStatic)->Arg(35000)->Unit(benchmark::kMicrosecond);

// The rotation fits alone, on the one-ring covariances of a 35K sheet rotated
// by one step, optionally with each current edge perturbed (noise, m, on edges
// of ~5 mm: a deforming cloth). Guesses: the exact rigid rotation (what the
// constant-velocity extrapolation gives for rigid motion) or the previous
// step's rotation (|ω|h = 0.024 rad off).
struct Covariances {
  std::vector<Matrix3> covariance;
  Eigen::Quaterniond exact, previous;
};

Covariances oneRingCovariances(double noise) {
  const TriangleMesh mesh = wavySheet(35000);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const RowVectors3& rest = mesh.vertexPositions;
  const Matrix3 R = rotationAt(kStep * 11), Rprev = rotationAt(kStep * 10);
  std::mt19937 rng(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  Covariances c;
  c.exact = Eigen::Quaterniond(R);
  c.previous = Eigen::Quaterniond(Rprev);
  for (int i = 0; i < topology.vertexCount(); ++i) {
    Matrix3 C = Matrix3::Zero();
    for (int m = topology.ringOffsets()[static_cast<size_t>(i)]; m < topology.ringOffsets()[static_cast<size_t>(i) + 1]; ++m) {
      const int j = topology.ringNeighbors()[static_cast<size_t>(m)];
      const Vector3 e = (rest.row(j) - rest.row(i)).transpose();
      const Vector3 wobble = noise * Vector3(normal(rng), normal(rng), normal(rng));
      C += (R * e + wobble) * e.transpose();
    }
    c.covariance.push_back(C);
  }
  return c;
}

void setFitCounters(benchmark::State& state, size_t fits, long iterations) {
  state.counters["ns_per_fit"] = benchmark::Counter(
      static_cast<double>(fits), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["iterations"] =
      static_cast<double>(iterations) / (static_cast<double>(state.iterations()) * static_cast<double>(fits));
}

// Arg: noise in µm.
void BM_RotationFitSvd(benchmark::State& state) {
  const Covariances c = oneRingCovariances(1e-6 * static_cast<double>(state.range(0)));
  for (auto _ : state)
    for (const Matrix3& C : c.covariance) benchmark::DoNotOptimize(rotationFromCovariance(C));
  setFitCounters(state, c.covariance.size(), 0);
}
BENCHMARK(BM_RotationFitSvd)->ArgName("noise_um")->Arg(0)->Arg(50)->Unit(benchmark::kMillisecond);

// Args: noise in µm; 0 start from the exact rotation, 1 from the previous step's.
void BM_RotationFitNewton(benchmark::State& state) {
  const Covariances c = oneRingCovariances(1e-6 * static_cast<double>(state.range(0)));
  const Eigen::Quaterniond guess = state.range(1) == 0 ? c.exact : c.previous;
  long iterations = 0;
  for (auto _ : state) {
    for (const Matrix3& C : c.covariance) {
      const RotationFit fit = fitRotation(C, guess);
      iterations += fit.iterations;
      benchmark::DoNotOptimize(fit);
    }
  }
  setFitCounters(state, c.covariance.size(), iterations);
}
BENCHMARK(BM_RotationFitNewton)
    ->ArgNames({"noise_um", "previous_step_guess"})
    ->ArgsProduct({{0, 50}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
