// Operator assembly and the three solver phases (symbolic analysis, numeric
// factorization, one solve) on flat grids of 2.5K, 10K, 35K and 140K vertices.
//
// Systems, all with the same vertex connectivity:
//  - scalar:       M + hL_S (real N x N), anisotropic stiffness, the diffusion system;
//  - connection:   M + hL_∇ (complex Hermitian N x N), the velocity diffusion system;
//  - connection2N: the same in real 2N x 2N form, for comparison.
// Each in simplicial and supernodal CHOLMOD. The unit square is meshed with
// (n + 1)^2 vertices; h·D/dx² = 50 along the weft (10 across), so the
// stiffness dominates the mass as in a real diffusion step (timings do not
// depend on the values: Cholesky has no pivoting).
// Counters: n (unknowns), nnzA (stored entries, both triangles), nnzL (factor).
// Run: operators_bench --benchmark_format=json > out.json, then
// scripts/bench_table.py out.json (the table in docs/performance.md).
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/numerics/sparse_solver.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/transport.h>

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

namespace blot::stain {
namespace {

// Grid cells per side for ~2.5K, 10K, 35K and 140K vertices.
constexpr int kGridCells[] = {49, 99, 186, 373};

constexpr double kWeftDiffusionSteps = 50.0;  // h·D_weft / dx²
constexpr double kAnisotropy = 5.0;           // D_weft / D_warp

// One grid with everything the operators need, built once per size.
struct GridProblem {
  TriangleMesh mesh;
  SurfaceTopology topology;
  Vector cotanWeights;
  Eigen::MatrixX3d faceAngles;
  Eigen::MatrixX3d faceTensors;
  RowVectors3 faceWeftDirections;
  SparseMatrix scalarSystem;
  ComplexSparseMatrix connectionSystem;
  SparseMatrix connectionSystem2N;

  explicit GridProblem(int cells)
      : mesh(gridMesh(cells, cells, 1.0, 1.0)),
        topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "bench grid") {
    const Vector lengths = edgeLengths(topology, mesh.vertexPositions);
    const Eigen::MatrixX3d cornerAngles = faceCornerAngles(topology, lengths);
    cotanWeights = edgeCotanWeights(topology, lengths, faceAreas(topology, lengths));
    faceAngles = faceTransportAngles(topology, cornerAngles, geodesicPolarMap(topology, cornerAngles));
    const double dx = 1.0 / cells;
    const double hDiffusivity = kWeftDiffusionSteps * dx * dx;  // h·D_weft in m²
    faceTensors.resize(topology.faceCount(), 3);
    faceTensors.col(0).setConstant(hDiffusivity);
    faceTensors.col(1).setZero();
    faceTensors.col(2).setConstant(hDiffusivity / kAnisotropy);
    faceWeftDirections.resize(topology.faceCount(), 3);
    faceWeftDirections.rowwise() = Vector3(std::cos(0.5), std::sin(0.5), 0.0).transpose();

    const SparseMatrix mass = lumpedMassMatrix(vertexDualAreas(topology, faceAreas(topology, lengths)));
    scalarSystem = mass + anisotropicStiffness(topology, mesh.vertexPositions, faceTensors,
                                               faceWeftDirections);
    connectionSystem = mass.cast<Complex>() + connectionLaplacian(topology, mesh.vertexPositions,
                                                                  faceAngles, faceTensors,
                                                                  faceWeftDirections);
    connectionSystem2N = realForm(connectionSystem);
  }
};

const GridProblem& gridProblem(int cells) {
  static std::map<int, std::unique_ptr<GridProblem>> cache;  // benchmark-only cache
  auto& entry = cache[cells];
  if (!entry) entry = std::make_unique<GridProblem>(cells);
  return *entry;
}

enum class System { Scalar, Connection, Connection2N };

void setMatrixCounters(benchmark::State& state, long rows, long nonZeros) {
  state.counters["n"] = static_cast<double>(rows);
  state.counters["nnzA"] = static_cast<double>(nonZeros);
}

// ---------------------------------------------------------------- assembly --

void BM_AssembleCotanLaplacian(benchmark::State& state) {
  const GridProblem& p = gridProblem(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    SparseMatrix L = cotanLaplacian(p.topology, p.cotanWeights);
    benchmark::DoNotOptimize(L.valuePtr());
  }
  setMatrixCounters(state, p.topology.vertexCount(), p.scalarSystem.nonZeros());
}

void BM_AssembleAnisotropicStiffness(benchmark::State& state) {
  const GridProblem& p = gridProblem(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    SparseMatrix L = anisotropicStiffness(p.topology, p.mesh.vertexPositions, p.faceTensors,
                                          p.faceWeftDirections);
    benchmark::DoNotOptimize(L.valuePtr());
  }
  setMatrixCounters(state, p.topology.vertexCount(), p.scalarSystem.nonZeros());
}

void BM_AssembleConnectionLaplacian(benchmark::State& state) {
  const GridProblem& p = gridProblem(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    ComplexSparseMatrix L = connectionLaplacian(p.topology, p.mesh.vertexPositions, p.faceAngles,
                                                p.faceTensors, p.faceWeftDirections);
    benchmark::DoNotOptimize(L.valuePtr());
  }
  setMatrixCounters(state, p.topology.vertexCount(), p.connectionSystem.nonZeros());
}

// ------------------------------------------------------------------ solver --

void requireOk(SolverStatus status) {
  if (status != SolverStatus::Ok) throw std::runtime_error(toString(status));
}

// Phase 0 = analysis, 1 = numeric factorization, 2 = one solve.
template <typename Scalar>
void runSolverPhase(benchmark::State& state, const Eigen::SparseMatrix<Scalar>& A, FactorKind kind,
                    int phase) {
  using VectorType = typename CholeskySolver<Scalar>::VectorType;
  CholeskySolver<Scalar> solver(kind);
  requireOk(solver.analyzePattern(A));
  if (phase == 0) {
    for (auto _ : state) requireOk(solver.analyzePattern(A));
  } else if (phase == 1) {
    for (auto _ : state) requireOk(solver.factorize(A));
  } else {
    requireOk(solver.factorize(A));
    const VectorType rhs = VectorType::Ones(A.rows());
    VectorType x(A.rows());
    for (auto _ : state) {
      requireOk(solver.solve(rhs, x));
      benchmark::DoNotOptimize(x.data());
    }
  }
  setMatrixCounters(state, A.rows(), A.nonZeros());
  state.counters["nnzL"] = static_cast<double>(solver.factorNonZeros());
}

template <System system, FactorKind kind, int phase>
void BM_Solver(benchmark::State& state) {
  const GridProblem& p = gridProblem(static_cast<int>(state.range(0)));
  if constexpr (system == System::Scalar) {
    runSolverPhase(state, p.scalarSystem, kind, phase);
  } else if constexpr (system == System::Connection) {
    runSolverPhase(state, p.connectionSystem, kind, phase);
  } else {
    runSolverPhase(state, p.connectionSystem2N, kind, phase);
  }
}

// The engine's direct density solve: both densities through one pass over L
// (solveInPlacePair), with L's row indices read as 16 bits (short:1, the
// default) or as CHOLMOD's 32 bits (short:0), alternated in one run. The
// right-hand sides are held by a stain on 5 % of the vertices (sparse:1: the
// forward pass skips the columns they do not reach, the backward pass reads
// all of L, as in the engine) or by every vertex (sparse:0).
void BM_SolvePair(benchmark::State& state) {
  const GridProblem& p = gridProblem(static_cast<int>(state.range(0)));
  const SparseMatrix& A = p.scalarSystem;
  RealCholeskySolver solver(FactorKind::Simplicial);
  solver.setShortRowIndices(state.range(1) != 0);
  requireOk(solver.compute(A));
  const Eigen::Index n = A.rows();
  Vector rhsA = Vector::Ones(n), rhsB = Vector::Constant(n, 0.25);
  if (state.range(2) != 0) {
    rhsA.tail(n - n / 20).setZero();
    rhsB.tail(n - n / 20).setZero();
  }
  Vector a(n), b(n);
  for (auto _ : state) {
    a = rhsA;
    b = rhsB;
    requireOk(solver.solveInPlacePair(a, b));
    benchmark::DoNotOptimize(a.data());
    benchmark::DoNotOptimize(b.data());
  }
  setMatrixCounters(state, n, A.nonZeros());
  state.counters["nnzL"] = static_cast<double>(solver.factorNonZeros());
  state.counters["short_rows"] = solver.usesShortRowIndices() ? 1 : 0;
}

// The connection system reuses the scalar system's ordering: this is its
// "analysis" cost in the engine.
void BM_ConnectionShareAnalysis(benchmark::State& state) {
  const GridProblem& p = gridProblem(static_cast<int>(state.range(0)));
  RealCholeskySolver scalar;
  requireOk(scalar.analyzePattern(p.scalarSystem));
  ComplexCholeskySolver connection;
  for (auto _ : state) requireOk(connection.shareAnalysisFrom(scalar));
  setMatrixCounters(state, p.topology.vertexCount(), p.connectionSystem.nonZeros());
  state.counters["nnzL"] = static_cast<double>(connection.factorNonZeros());
}

void gridSizes(benchmark::internal::Benchmark* b) {
  for (int cells : kGridCells) b->Arg(cells);
  b->ArgName("cells")->Unit(benchmark::kMillisecond);
}

BENCHMARK(BM_AssembleCotanLaplacian)->Apply(gridSizes);
BENCHMARK(BM_AssembleAnisotropicStiffness)->Apply(gridSizes);
BENCHMARK(BM_AssembleConnectionLaplacian)->Apply(gridSizes);

#define BLOT_SOLVER_BENCHMARKS(system, kind)                                        \
  BENCHMARK(BM_Solver<System::system, FactorKind::kind, 0>)                         \
      ->Name("BM_Analyze/" #system "/" #kind)                                       \
      ->Apply(gridSizes);                                                            \
  BENCHMARK(BM_Solver<System::system, FactorKind::kind, 1>)                         \
      ->Name("BM_Factorize/" #system "/" #kind)                                     \
      ->Apply(gridSizes);                                                            \
  BENCHMARK(BM_Solver<System::system, FactorKind::kind, 2>)                         \
      ->Name("BM_Solve/" #system "/" #kind)                                         \
      ->Apply(gridSizes)

BLOT_SOLVER_BENCHMARKS(Scalar, Simplicial);
BLOT_SOLVER_BENCHMARKS(Scalar, Supernodal);
BLOT_SOLVER_BENCHMARKS(Connection, Simplicial);
BLOT_SOLVER_BENCHMARKS(Connection, Supernodal);
BLOT_SOLVER_BENCHMARKS(Connection2N, Simplicial);
BLOT_SOLVER_BENCHMARKS(Connection2N, Supernodal);
BENCHMARK(BM_ConnectionShareAnalysis)->Apply(gridSizes);
BENCHMARK(BM_SolvePair)
    ->ArgNames({"cells", "short", "sparse"})
    ->ArgsProduct({{99, 186, 373}, {0, 1}, {1, 0}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
