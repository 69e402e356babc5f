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
//
// The intrinsic rebuild on deforming Bullet cloth ("a metric refresh
// that costs what changed"): the two-way flag and the tablecloth scenes
// (assets/scenes/two_way_flag.json, tablecloth.json) are run through the
// Engine at strain tolerance 2e-2 (the Bullet scenes' default then) and the
// positions of every step are kept. Then
//  - BM_IntrinsicRebuildTrips (one iteration): at every rebuild of the run,
//    how many edges and faces exceed the tolerance against the lengths of the
//    previous build (and half of it), and how many faces a partial rebuild of
//    those would have to touch (the one-rings of their vertices: the vertex
//    angle sums rescale every transport angle of the ring).
//  - BM_IntrinsicRebuildPart: each part of SurfaceGeometry::refreshIntrinsic
//    and of DiffusionSystems::assemble on the positions of the last rebuild,
//    so each part's share of a rebuild is a ratio in one run; the two
//    operators both assembled anew (the first build) and refilled (every
//    later whole rebuild).
//  - BM_IntrinsicRefreshReplay: the run's positions replayed into a
//    SurfaceGeometry, whole (IntrinsicRefresh::Full) or partial rebuilds timed.
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/transport.h>
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/stain_solver.h>

#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
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


// --- The intrinsic rebuild on deforming cloth -------------------------------

constexpr const char* kRebuildScenes[] = {"two_way_flag", "tablecloth"};
constexpr int kRebuildSteps = 240;  // 2 s at the scenes' h = 1/120 s
// The strain tolerance of these runs: 2e-2, the Bullet scenes' default when
// this was measured (now 5e-2, docs/accuracy.md "Strain tolerance").
constexpr double kRebuildTolerance = 2e-2;

// Per-trip counts, summed over the rebuilds of the run.
struct TripCounts {
  long trips = 0;
  double edgesOver = 0, facesOver = 0, facesOverHalf = 0, ringFaces = 0, rows = 0;
  double maxFacesOver = 0;
};

struct RebuildCapture {
  std::unique_ptr<engine::Engine> engine;
  RowVectors3 positions;  // t + h of the last step that rebuilt
  std::vector<RowVectors3> sequence;  // t + h of every step
  double tolerance = 0, h = 0;
  int steps = 0;
  TripCounts counts;
  int edges = 0, faces = 0, vertices = 0;
};

// Counts what changed past `tolerance` between two builds' edge lengths.
void countTrip(const SurfaceTopology& topology, const Vector& before, const Vector& after, double tolerance,
               TripCounts& counts) {
  const int faceCount = topology.faceCount();
  std::vector<char> edgeOver(static_cast<size_t>(topology.edgeCount()), 0), edgeOverHalf = edgeOver;
  int edgesOver = 0;
  for (int e = 0; e < topology.edgeCount(); ++e) {
    const double strain = std::abs(after(e) / before(e) - 1.0);
    edgeOver[static_cast<size_t>(e)] = strain > tolerance;
    edgeOverHalf[static_cast<size_t>(e)] = strain > 0.5 * tolerance;
    edgesOver += edgeOver[static_cast<size_t>(e)];
  }
  std::vector<char> vertexTouched(static_cast<size_t>(topology.vertexCount()), 0);
  int facesOver = 0, facesOverHalf = 0;
  for (int f = 0; f < faceCount; ++f) {
    bool over = false, overHalf = false;
    for (int k = 0; k < 3; ++k) {
      over = over || edgeOver[static_cast<size_t>(topology.faceEdges()(f, k))];
      overHalf = overHalf || edgeOverHalf[static_cast<size_t>(topology.faceEdges()(f, k))];
    }
    facesOver += over;
    facesOverHalf += overHalf;
    if (over)
      for (int k = 0; k < 3; ++k) vertexTouched[static_cast<size_t>(topology.faces()(f, k))] = 1;
  }
  int ringFaces = 0, rows = 0;
  for (int f = 0; f < faceCount; ++f) {
    bool touched = false;
    for (int k = 0; k < 3; ++k) touched = touched || vertexTouched[static_cast<size_t>(topology.faces()(f, k))];
    ringFaces += touched;
  }
  for (const char t : vertexTouched) rows += t;
  ++counts.trips;
  counts.edgesOver += edgesOver;
  counts.facesOver += facesOver;
  counts.facesOverHalf += facesOverHalf;
  counts.ringFaces += ringFaces;
  counts.rows += rows;
  counts.maxFacesOver = std::max(counts.maxFacesOver, static_cast<double>(facesOver));
}

const RebuildCapture& rebuildCapture(int scene) {
  static std::map<int, RebuildCapture> captures;
  auto found = captures.find(scene);
  if (found != captures.end()) return found->second;
  RebuildCapture& c = captures[scene];
  engine::EngineDef def =
      engine::loadScene(std::string(BLOT_ASSETS_DIR) + "/scenes/" + kRebuildScenes[scene] + ".json").engine;
  def.stain.threads = 1;
  def.stain.strainTolerance = kRebuildTolerance;
  def.stain.intrinsicRefresh = IntrinsicRefresh::Full;  // the trips counted against whole rebuilds
  c.engine = std::make_unique<engine::Engine>(def);
  c.tolerance = def.stain.strainTolerance;
  c.h = def.timeStep;
  const StainSolver& solver = c.engine->surface().stain();
  const SurfaceTopology& topology = c.engine->topology();
  Vector built = solver.geometry().intrinsic().edgeLengths;
  for (int step = 0; step < kRebuildSteps; ++step) {
    c.engine->advanceSteps(1);
    c.sequence.push_back(solver.geometry().extrinsic().nextPositions);
    if (solver.profile().intrinsicRefreshes == 0) continue;
    const Vector& now = solver.geometry().intrinsic().edgeLengths;
    countTrip(topology, built, now, c.tolerance, c.counts);
    built = now;
    c.positions = solver.geometry().extrinsic().nextPositions;
  }
  if (c.positions.rows() == 0) c.positions = solver.geometry().extrinsic().nextPositions;
  c.steps = kRebuildSteps;
  c.edges = topology.edgeCount();
  c.faces = topology.faceCount();
  c.vertices = topology.vertexCount();
  return c;
}

// Arg: scene (0 two-way flag, 1 tablecloth). Counters are means per rebuild
// as fractions of the mesh's edges / faces / vertices.
void BM_IntrinsicRebuildTrips(benchmark::State& state) {
  const RebuildCapture& c = rebuildCapture(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(c.counts.trips);
  const double trips = std::max<double>(1, static_cast<double>(c.counts.trips));
  state.counters["tolerance"] = c.tolerance;
  state.counters["rebuilds_per_step"] = static_cast<double>(c.counts.trips) / c.steps;
  state.counters["edges_over"] = c.counts.edgesOver / trips / c.edges;
  state.counters["faces_over"] = c.counts.facesOver / trips / c.faces;
  state.counters["max_faces_over"] = c.counts.maxFacesOver / c.faces;
  state.counters["faces_over_half"] = c.counts.facesOverHalf / trips / c.faces;
  state.counters["ring_faces"] = c.counts.ringFaces / trips / c.faces;
  state.counters["rows"] = c.counts.rows / trips / c.vertices;
}
BENCHMARK(BM_IntrinsicRebuildTrips)->ArgName("scene")->DenseRange(0, 1)->Iterations(1);

enum RebuildPart {
  kLengths, kAngles, kAreas, kCotan, kDualAreas, kPolarMap, kEdgeTransport, kFaceTransport,
  kDensityStiffness, kConnectionLaplacian, kWholeRefresh, kAssemble, kDensityRefill, kConnectionRefill,
  kBothRefillFromLengths, kPartCount
};
constexpr const char* kPartNames[] = {"edge lengths", "corner angles", "face areas", "cotan weights", "dual areas",
                                      "polar map", "edge transport", "face transport", "density stiffness",
                                      "connection Laplacian", "refreshIntrinsic", "assemble M+hL",
                                      "density stiffness refilled", "connection Laplacian refilled",
                                      "both refilled from lengths (a whole rebuild's)"};

// Args: scene, part (RebuildPart). Label: the part's name.
void BM_IntrinsicRebuildPart(benchmark::State& state) {
  const RebuildCapture& c = rebuildCapture(static_cast<int>(state.range(0)));
  const auto part = static_cast<RebuildPart>(state.range(1));
  const SurfaceTopology& topology = c.engine->topology();
  const FabricField& fabric = c.engine->surface().stain().geometry().fabric();
  const RowVectors3& p = c.positions;
  const Vector lengths = edgeLengths(topology, p);
  const Eigen::MatrixX3d angles = faceCornerAngles(topology, lengths);
  const Vector areas = faceAreas(topology, lengths);
  const PolarMap polar = geodesicPolarMap(topology, angles);
  const Eigen::MatrixX3d faceTransport = faceTransportAngles(topology, angles, polar);
  // A geometry built on these positions (its first build uses the rest wefts:
  // isotropic here, so the weft plays no part).
  SurfaceGeometry geometry(topology, p, fabric, c.tolerance);
  DiffusionSystems systems;
  systems.assemble(geometry.intrinsic(), c.h);
  // What a whole rebuild after the first does with the two operators: the
  // same values written into the existing matrices (refill*).
  const OneRingEntries entries = oneRingFaceEntries(topology);
  SparseMatrix stiffness = geometry.intrinsic().densityStiffness;
  ComplexSparseMatrix connection = geometry.intrinsic().velocityStiffness;
  for (auto _ : state) {
    switch (part) {
      case kLengths: benchmark::DoNotOptimize(edgeLengths(topology, p)); break;
      case kAngles: benchmark::DoNotOptimize(faceCornerAngles(topology, lengths)); break;
      case kAreas: benchmark::DoNotOptimize(faceAreas(topology, lengths)); break;
      case kCotan: benchmark::DoNotOptimize(edgeCotanWeights(topology, lengths, areas)); break;
      case kDualAreas: benchmark::DoNotOptimize(vertexDualAreas(topology, areas)); break;
      case kPolarMap: benchmark::DoNotOptimize(geodesicPolarMap(topology, angles)); break;
      case kEdgeTransport: benchmark::DoNotOptimize(edgeTransportAngles(topology, polar)); break;
      case kFaceTransport: benchmark::DoNotOptimize(faceTransportAngles(topology, angles, polar)); break;
      case kDensityStiffness:
        benchmark::DoNotOptimize(anisotropicStiffness(topology, p, fabric.densityTensors, fabric.weftDirections));
        break;
      case kConnectionLaplacian:
        benchmark::DoNotOptimize(
            connectionLaplacian(topology, p, faceTransport, fabric.velocityTensors, fabric.weftDirections));
        break;
      case kWholeRefresh: geometry.refreshIntrinsic(); break;
      case kAssemble: benchmark::DoNotOptimize(systems.assemble(geometry.intrinsic(), c.h)); break;
      case kDensityRefill:
        refillAnisotropicStiffness(topology, p, fabric.densityTensors, fabric.weftDirections, entries, stiffness);
        benchmark::DoNotOptimize(stiffness.valuePtr());
        break;
      case kConnectionRefill:
        refillConnectionLaplacian(topology, p, faceTransport, fabric.velocityTensors, fabric.weftDirections, entries,
                                  connection);
        benchmark::DoNotOptimize(connection.valuePtr());
        break;
      case kBothRefillFromLengths:
        refillStiffnessAndConnectionFromLengths(topology, lengths, areas, fabric.densityTensors, faceTransport,
                                                fabric.velocityTensors,
                                                c.engine->surface().stain().geometry().faceWeftCoefficients(), entries,
                                                stiffness, connection);
        benchmark::DoNotOptimize(connection.valuePtr());
        break;
      case kPartCount: break;
    }
  }
  state.SetLabel(std::string(kRebuildScenes[state.range(0)]) + ": " + kPartNames[part]);
  state.counters["vertices"] = c.vertices;
}
BENCHMARK(BM_IntrinsicRebuildPart)
    ->ArgNames({"scene", "part"})
    ->ArgsProduct({{0, 1}, benchmark::CreateDenseRange(0, kPartCount - 1, 1)})
    ->Unit(benchmark::kMicrosecond);

// The rebuilds of a whole run, replayed: the scene's positions step by step
// into a SurfaceGeometry at the scene's tolerance, and on each trip
// refreshIntrinsic plus DiffusionSystems::assemble (assembleColumns after a
// partial refresh, as StainSolver does) timed (manual time: the extrinsic
// refresh between is not). Args: scene, mode (0 Full, 1 Partial,
// 2 Region around the vertices within 0.15 m of the mesh's centre, a stand-in
// for a wet patch). Full and Partial trip on the whole-mesh test. Region
// trips on the test around that patch, as the engine pairs them (scene key
// intrinsic_refresh "region" needs strain_test "around-liquid"): under the
// whole-mesh test a region refresh leaves the lengths outside it unmeasured,
// and the test then tripped on nearly every step (0.996 a step against Full's
// 0.567 on the two-way flag, measured with an earlier form of the step). So Region rebuilds on other steps:
// compare rebuilds_per_step × us_per_rebuild.
// One iteration = one step of the run (wrapping around with a fresh geometry).
// Counters: rebuilds_per_step, us_per_rebuild (0 when it never trips),
// faces_per_rebuild (share of #F whose stiffness block was recomputed),
// edges_per_rebuild (share of #E re-measured).
void BM_IntrinsicRefreshReplay(benchmark::State& state) {
  const RebuildCapture& c = rebuildCapture(static_cast<int>(state.range(0)));
  const IntrinsicRefresh modes[3] = {IntrinsicRefresh::Full, IntrinsicRefresh::Partial, IntrinsicRefresh::Region};
  const IntrinsicRefresh mode = modes[state.range(1)];
  const SurfaceTopology& topology = c.engine->topology();
  const FabricField& fabric = c.engine->surface().stain().geometry().fabric();
  const RowVectors3& rest = c.engine->definition().mesh.vertexPositions;
  std::vector<int> region;
  const Eigen::RowVector3d centre = rest.colwise().mean();
  for (int v = 0; v < topology.vertexCount(); ++v)
    if ((rest.row(v) - centre).norm() < 0.15) region.push_back(v);
  std::unique_ptr<SurfaceGeometry> geometry;
  DiffusionSystems systems;
  size_t k = 0;
  long rebuilds = 0, steps = 0;
  double seconds = 0, faces = 0, edges = 0;
  for (auto _ : state) {
    if (k == 0) {
      geometry = std::make_unique<SurfaceGeometry>(topology, rest, fabric, c.tolerance);
      geometry->setIntrinsicRefresh(mode);
      geometry->setRefreshRegion(region.data(), static_cast<int>(region.size()));
      geometry->prepareWholeRebuilds();  // as the solver does on a deforming surface
      systems.assemble(geometry->intrinsic(), c.h);
    }
    const bool aroundRegion = mode == IntrinsicRefresh::Region;
    bool trip = geometry->refreshExtrinsic(c.sequence[k], c.h, !aroundRegion);
    if (aroundRegion) trip = geometry->strainExceededAround(region.data(), static_cast<int>(region.size()));
    k = (k + 1) % c.sequence.size();
    ++steps;
    double elapsed = 0;
    if (trip) {
      const auto start = std::chrono::steady_clock::now();
      geometry->refreshIntrinsic();
      if (geometry->lastRefreshPartial()) {  // as StainSolver: M + h L refilled in the changed columns
        const std::vector<int>& v1 = geometry->refreshedVertices();
        const std::vector<int>& v2 = geometry->reassembledConnectionVertices();
        systems.assembleColumns(geometry->intrinsic(), c.h, v1.data(), static_cast<int>(v1.size()), v2.data(),
                                static_cast<int>(v2.size()));
      } else {
        systems.assemble(geometry->intrinsic(), c.h);
      }
      elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      ++rebuilds;
      faces += static_cast<double>(geometry->refreshedFaceCount()) / topology.faceCount();
      edges += static_cast<double>(geometry->refreshedEdgeCount()) / topology.edgeCount();
    }
    seconds += elapsed;
    state.SetIterationTime(elapsed);
  }
  const double r = std::max<double>(1, static_cast<double>(rebuilds));
  const char* modeNames[3] = {": full", ": partial", ": region"};
  state.SetLabel(std::string(kRebuildScenes[state.range(0)]) + modeNames[state.range(1)]);
  state.counters["rebuilds_per_step"] = static_cast<double>(rebuilds) / static_cast<double>(steps);
  state.counters["us_per_rebuild"] = 1e6 * seconds / r;
  state.counters["faces_per_rebuild"] = faces / r;
  state.counters["edges_per_rebuild"] = edges / r;
}
BENCHMARK(BM_IntrinsicRefreshReplay)
    ->ArgNames({"scene", "mode"})
    ->ArgsProduct({{0, 1}, {0, 1, 2}})
    ->Iterations(4 * kRebuildSteps)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

// The per-vertex extrinsic geometry on a deforming cloth (VertexRefresh::
// OnDemand, as in a step): the captured run replayed into a SurfaceGeometry,
// each step's refresh (and rebuild, when the strain test trips) untimed, then
// the vertices prepared (timed): what the liquid band pays per vertex, one
// fitted slot (t + h; t was fitted the step before), ω and p̈. Args: scene,
// list (0: every vertex in index order; 1: the 500 vertices nearest the rest
// shape's centroid, a band's pattern: rows of a few dozen, the moving middle
// of the cloth). Counters: ns_per_vertex, newton_per_fit, svd_per_fit.
const std::vector<int>& centreDisc(int scene, const RowVectors3& rest) {
  static std::map<int, std::vector<int>> discs;
  std::vector<int>& disc = discs[scene];
  if (!disc.empty()) return disc;
  const Eigen::RowVector3d centre = rest.colwise().mean();
  std::vector<std::pair<double, int>> byDistance;
  for (int i = 0; i < rest.rows(); ++i) byDistance.push_back({(rest.row(i) - centre).squaredNorm(), i});
  std::sort(byDistance.begin(), byDistance.end());
  for (size_t k = 0; k < std::min<size_t>(500, byDistance.size()); ++k) disc.push_back(byDistance[k].second);
  return disc;
}

void BM_PrepareVerticesDeforming(benchmark::State& state) {
  const int scene = static_cast<int>(state.range(0));
  const RebuildCapture& c = rebuildCapture(scene);
  const SurfaceTopology& topology = c.engine->topology();
  const FabricField& fabric = c.engine->surface().stain().geometry().fabric();
  const RowVectors3& rest = c.engine->definition().mesh.vertexPositions;
  const std::vector<int>& disc = centreDisc(scene, rest);
  std::unique_ptr<SurfaceGeometry> geometry;
  size_t k = 0;
  double seconds = 0, prepared = 0, fits = 0, iterations = 0, fallbacks = 0;
  for (auto _ : state) {
    if (k == 0) {
      geometry = std::make_unique<SurfaceGeometry>(topology, rest, fabric, c.tolerance);
      geometry->setVertexRefresh(VertexRefresh::OnDemand);
    }
    if (geometry->refreshExtrinsic(c.sequence[k], c.h)) geometry->refreshIntrinsic();
    k = (k + 1) % c.sequence.size();
    const auto start = std::chrono::steady_clock::now();
    if (state.range(1) == 0) {
      geometry->prepareAllVertices();
    } else {
      geometry->prepareVertices(disc);
    }
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    seconds += elapsed;
    state.SetIterationTime(elapsed);
    prepared += geometry->preparedVertexCount();
    fits += geometry->rotationFitStats().fittedVertices;
    iterations += static_cast<double>(geometry->rotationFitStats().newtonIterations);
    fallbacks += geometry->rotationFitStats().svdFallbacks;
  }
  state.SetLabel(kRebuildScenes[scene]);
  state.counters["ns_per_vertex"] = 1e9 * seconds / std::max(1.0, prepared);
  state.counters["fits_per_vertex"] = fits / std::max(1.0, prepared);
  state.counters["newton_per_fit"] = iterations / std::max(1.0, fits);
  state.counters["svd_per_fit"] = fallbacks / std::max(1.0, fits);
}
BENCHMARK(BM_PrepareVerticesDeforming)
    ->ArgNames({"scene", "list"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Iterations(4 * kRebuildSteps)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
