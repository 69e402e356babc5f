// Cost of the stain step against wet area on a 140,625-vertex cloth (DESIGN.md:
// "model no more than a scene needs").
//
// Design note. A 1 m square grid (375 x 375 vertices) turns rigidly about a
// tilted axis (so tangential gravity, inertia and Coriolis all act and the
// frames change every step) and carries a stain over a disc covering a given
// fraction of its area, from 0 (dry) to 100 %. Each row reports ms per stain
// step (manual time = StainSolver::stepRigid, the surface positions built
// outside the timer) and the per-phase times of StepProfile, so the fixed
// cost per step (the positions' copy and comparison, the deforming strain
// test; the rollback point and validation once they covered #V) can be told
// from the cost that grows with the wet area (forces, advection,
// diffusion on the Krylov support, interaction). The stain is set directly in
// the state (a uniform film on the disc) instead of with addDrop, whose bump
// would make the wet area depend on the threshold. Two fabrics: diffusivity
// and viscosity 1e-4 m²/s keep max h L_ii / A_i small, so both solves run on
// the liquid's support; 4e-3 and 2e-3 m²/s (the Table 1 flag's) make them
// 40x stiffer, where Auto weighs CG on the support against the whole-mesh
// factorizations by predicted cost (rather than always taking the factors
// there: whole-mesh solves however small the stain). Static rows (no
// motion) show the geometry refresh skipped. Deforming rows (moving = 2)
// add a travelling wave across the grid under the same rotation, z̄ +=
// A sin(k x̄ − Ω t) cos(k ȳ) (A = 3 mm, wavelength 0.5 m, 1 Hz), stepped by
// StainSolver::step (per-vertex rotation fits, the strain test): the path a
// mesh sequence or a Bullet cloth takes. Its slope A k = 0.038 keeps every
// edge within 7.1e-4 of its rest length, under the 1e-3 strain tolerance, so
// no intrinsic rebuild enters the timing. Rejected: the coupled engine (Bullet cloth dominates at 140K and
// would hide the stain's own scaling; table1_bench has that scene).
//
// Run: wet_area_bench --benchmark_counters_tabular=true
//      scripts/wet_area [--update] [BUILD_DIR]  (docs/performance.md table)
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>

#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

namespace blot::stain {
namespace {

constexpr int kCells = 374;          // (374 + 1)² = 140,625 vertices
constexpr double kOmega = 1.0;       // rad/s about the tilted axis
constexpr double kStep = 0.01;       // s
constexpr double kFilm = 0.5;        // kg/m² of free solvent on the wet disc
constexpr double kPi = 3.14159265358979323846;
constexpr double kWaveAmplitude = 0.003;           // m
constexpr double kWaveNumber = 2 * kPi / 0.5;      // rad/m
constexpr double kWaveFrequency = 2 * kPi * 1.0;   // rad/s

using Clock = std::chrono::steady_clock;

long peakResidentKb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, 6, "VmHWM:") == 0) return std::atol(line.c_str() + 6);
  return -1;
}

Matrix3 rotationAt(double t) {
  return Eigen::AngleAxisd(kOmega * t, Vector3(0.4, 0.2, 1.0).normalized()).toRotationMatrix();
}

// The deforming motion's positions at time t (rest: the flat grid).
void deformedAt(const RowVectors3& rest, double t, const Matrix3& R, RowVectors3& out) {
  for (Eigen::Index i = 0; i < rest.rows(); ++i) {
    Vector3 p = rest.row(i).transpose();
    p.z() += kWaveAmplitude * std::sin(kWaveNumber * p.x() - kWaveFrequency * t) * std::cos(kWaveNumber * p.y());
    out.row(i) = (R * p).transpose();
  }
}

// Args: wet area in basis points of the cloth (0..10000), moving (0 static,
// 1 rigid, 2 deforming), all_vertices (1: the per-vertex geometry on every
// vertex, VertexRefresh::AllVertices, as before it followed the band),
// fabric (0: D = ν = 1e-4 m²/s, mild; 1: D = 4e-3, ν = 2e-3 m²/s, stiff).
void BM_WetArea(benchmark::State& state) {
  const double fraction = static_cast<double>(state.range(0)) * 1e-4;
  const bool moving = state.range(1) != 0;
  const bool deforming = state.range(1) == 2;
  const bool stiff = state.range(2) != 0;
  const bool allVertices = state.range(3) != 0;
  const double diffusivity = stiff ? 4e-3 : 1e-4, viscosity = stiff ? 2e-3 : 1e-4;
  TriangleMesh mesh = gridMesh(kCells, kCells, 1.0, 1.0);
  mesh.vertexPositions.col(0).array() -= 0.5;
  mesh.vertexPositions.col(1).array() -= 0.5;
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const SurfaceTopology topology(mesh.faces, n);
  StainSolverDef def;
  applyPhysicsModel(PhysicsModel::Film, def.switches, def.liquid);  // the engine's default model
  def.liquid.evaporationRate = 0.002;
  if (allVertices) def.geometryVertices = VertexRefresh::AllVertices;
  StainSolver solver(topology, mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), diffusivity, viscosity), def);
  const Vector3 axis = Vector3(0.4, 0.2, 1.0).normalized();
  if (deforming) {
    // p(0) and v(0) by a centred difference over ±1 µs.
    const double dt = 1e-6;
    RowVectors3 p0(n, 3), before(n, 3), after(n, 3);
    deformedAt(mesh.vertexPositions, 0.0, Matrix3::Identity(), p0);
    deformedAt(mesh.vertexPositions, -dt, rotationAt(-dt), before);
    deformedAt(mesh.vertexPositions, dt, rotationAt(dt), after);
    solver.setInitialMotion(p0, (after - before) / (2 * dt));
  } else if (moving) {
    RowVectors3 velocities(n, 3);
    for (int i = 0; i < n; ++i)
      velocities.row(i) = (kOmega * axis).cross(Vector3(mesh.vertexPositions.row(i))).transpose();
    solver.setInitialMotion(mesh.vertexPositions, velocities);
  }
  // A uniform film on the disc of area fraction × 1 m² about the centre (the
  // whole cloth at 100 %). A dry row leaves the state alone: a cloth no
  // liquid has been on skips the strain test.
  const double radius = fraction >= 1.0 ? 1.0 : std::sqrt(fraction / kPi);
  if (fraction > 0) {
    StainState& s = solver.mutableState();
    for (int i = 0; i < n; ++i) {
      if (mesh.vertexPositions.row(i).head<2>().norm() <= radius) {
        s.solvent[i] = kFilm;
        s.solute[i] = 0.2 * kFilm;
      }
    }
  }
  int step = 0;
  RowVectors3 next = mesh.vertexPositions;
  auto advance = [&]() {
    ++step;
    const Matrix3 R = moving ? rotationAt(step * kStep) : Matrix3::Identity();
    if (deforming) {
      deformedAt(mesh.vertexPositions, step * kStep, R, next);
    } else if (moving) {
      next.noalias() = mesh.vertexPositions * R.transpose();
    }
    const auto start = Clock::now();
    const StepReport r = deforming ? solver.step(kStep, next) : solver.stepRigid(kStep, next, R);
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (r.status != StepStatus::Ok) state.SkipWithError(("step failed: " + std::string(r.stageName()) + ": " + r.message).c_str());
    return seconds;
  };
  // Warm-up: the first step factorizes; the second and third settle the
  // rotation history (shared-axis fast path) and the wet mask.
  for (int k = 0; k < 3; ++k) advance();

  StepProfile sum;
  double wet = 0, halo = 0, advected = 0, densityRows = 0, velocityRows = 0, geometryVertices = 0, rebuilds = 0;
  unsigned terms = 0;
  int steps = 0;
  for (auto _ : state) {
    state.SetIterationTime(advance());
    const StepProfile& p = solver.profile();
    sum.addTimes(p);
    wet += p.wetVertices;
    halo += p.haloVertices;
    advected += p.advectionVertices;
    densityRows += p.densityDiffusionVertices;
    velocityRows += p.velocityDiffusionVertices;
    geometryVertices += p.geometryVertices;
    rebuilds += p.intrinsicRefreshes;
    sum.diffusionIterations += p.diffusionIterations;
    terms |= p.terms;
    ++steps;
  }
  if (steps == 0) return;
  const double k = 1.0 / steps;
  const double stages = sum.stainTime();
  state.counters["vertices"] = n;
  state.counters["wet_fraction"] = wet * k / n;
  state.counters["wet_vertices"] = wet * k;
  state.counters["halo_vertices"] = halo * k;
  state.counters["advection_vertices"] = advected * k;
  state.counters["density_diffusion_rows"] = densityRows * k;
  state.counters["velocity_diffusion_rows"] = velocityRows * k;
  state.counters["cg_iterations"] = sum.diffusionIterations * k;
  state.counters["geometry_ms"] = sum.time(Stage::Geometry) * k;
  state.counters["band_ms"] = sum.time(Stage::LiquidBand) * k;  // includes the band's per-vertex geometry
  state.counters["geometry_vertices"] = geometryVertices * k;
  state.counters["intrinsic_rebuilds"] = rebuilds;
  state.counters["forces_ms"] = (sum.time(Stage::BodyForces) + sum.time(Stage::FilmPressure) + sum.time(Stage::FilmFriction) + sum.time(Stage::Coriolis)) * k;
  state.counters["advection_ms"] = (sum.time(Stage::AdvectVelocity) + sum.time(Stage::AdvectDensity)) * k;
  state.counters["diffusion_ms"] = sum.time(Stage::Diffuse) * k;
  state.counters["interaction_ms"] = (sum.time(Stage::Interact) + sum.time(Stage::Sources)) * k;
  // The rollback point's copies and the validation (the step's own passes
  // over the vertices it changed).
  state.counters["other_ms"] = (sum.total - stages) * k;
  state.counters["total_ms"] = sum.total * k;
  state.counters["terms"] = terms;
  state.counters["peak_rss_mb"] = peakResidentKb() / 1024.0;
  StepProfile last = solver.profile();
  last.terms = terms;
  state.SetLabel(describeTerms(last));
}

// Rows: Krylov diffusion, moving, 0 % .. 100 %; the same static at 0 and 1 %;
// deforming at 0, 0.1 and 100 %; rigid and deforming at 0 and 0.1 % with the
// geometry on every vertex;
// the direct (stiff) diffusion, moving, at 0.1 %, 10 % and 100 %.
BENCHMARK(BM_WetArea)
    ->ArgNames({"wet_bp", "moving", "stiff", "all_vertices"})
    ->Args({0, 1, 0, 0})
    ->Args({10, 1, 0, 0})
    ->Args({100, 1, 0, 0})
    ->Args({1000, 1, 0, 0})
    ->Args({5000, 1, 0, 0})
    ->Args({10000, 1, 0, 0})
    ->Args({0, 0, 0, 0})
    ->Args({100, 0, 0, 0})
    ->Args({0, 2, 0, 0})
    ->Args({10, 2, 0, 0})
    ->Args({10000, 2, 0, 0})
    ->Args({0, 1, 0, 1})
    ->Args({10, 1, 0, 1})
    ->Args({0, 2, 0, 1})
    ->Args({10, 2, 0, 1})
    ->Args({10, 1, 1, 0})
    ->Args({1000, 1, 1, 0})
    ->Args({10000, 1, 1, 0})
    ->Iterations(20)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
