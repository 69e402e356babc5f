// The full stain step (StainSolver::step) per phase, on meshes of the paper's
// Table 1 sizes, under rigid rotation, every physics term on.
//
// Meshes: flat grids gridMesh(n, n, 1, 1) of 2,500, 10,000 and 34,969
// vertices, and the Stanford bunny (CGAL's bunny00.off, 37,706 vertices).
// Fabric: anisotropic (ratio 10, weft at 30° on the grids, along each face's
// first edge on the bunny), D_weft = 2e-3 size² m²/s (size = the largest
// distance from the centroid, 0.71 on the unit grids), so h·D_weft/dx² ≈ 0.024
// on the 2.5K grid and ≈ 0.35 on the 35K grid at h = 0.01 s: every system
// is mild enough for the restricted CG (diffusion.h).
// Motion: rotation at 1.5 rad/s about a tilted axis through the centroid,
// positions set analytically each step; gravity −z (grids) or −y (bunny).
// Liquid: "drop" = one drop whose radius covers ~10 % of the area, with
// solute and an initial velocity; "wet" = the whole surface wet.
// Geometry path: "rigid" uses StainSolver::stepRigid (the rotation is known),
// "fitted" uses step (per-vertex Kabsch fits and the strain test).
//
// Reported time: StepProfile::total (manual time, the step alone). Counters:
// per-phase means (ms) from StepProfile, n (vertices), wet (fraction of
// vertices holding liquid), substeps (density-advection sub-steps), fixes
// (vertices the positivity limiter corrected per step), cgIters (conjugate-
// gradient iterations per step, density + velocity; 0 = direct solves), and
// allocs (malloc/calloc/realloc calls per step, counted across the timed
// steps after 3 warm-up steps; the first step factorizes and allocates).
//
// Run: stain_step_bench --benchmark_format=json > step.json
//      (or --benchmark_counters_tabular=true for a readable table).
#include <benchmark/benchmark.h>
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>
#include <omp.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "mesh_fixture.h"

#include "allocation_counter.h"  // counts every allocation while gCountAllocations is set

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kStep = 0.01;   // s, the paper's time step
constexpr double kOmega = 1.5;   // rad/s
constexpr int kWarmupSteps = 3;  // the first step assembles (and factorizes what it solves directly)

enum MeshId { kGrid2500 = 0, kGrid10000 = 1, kGrid35000 = 2, kBunny = 3 };
enum Liquid { kDrop = 0, kWet = 1 };
enum GeometryPath { kRigid = 0, kFitted = 1 };

TriangleMesh makeMesh(int id) {
  switch (id) {
    case kGrid2500: return gridMesh(49, 49, 1, 1);
    case kGrid10000: return gridMesh(99, 99, 1, 1);
    case kGrid35000: return gridMesh(186, 186, 1, 1);
    default: return loadMesh(test::externalMesh("bunny00.off"));
  }
}

struct Scene {
  TriangleMesh mesh;
  std::unique_ptr<SurfaceTopology> topology;
  std::unique_ptr<StainSolver> solver;
  Vector3 center, axis;
  RowVectors3 centered, next;  // rest shape about the centre; positions at t + h
  int steps = 0;

  Scene(int id, int liquid) : mesh(makeMesh(id)) {
    const int n = static_cast<int>(mesh.vertexPositions.rows());
    const int faces = static_cast<int>(mesh.faces.rows());
    topology = std::make_unique<SurfaceTopology>(mesh.faces, n, "stain step bench");
    center = mesh.vertexPositions.colwise().mean().transpose();
    centered = mesh.vertexPositions.rowwise() - center.transpose();
    const double size = centered.rowwise().norm().maxCoeff();
    const bool grid = id != kBunny;

    FabricField fabric;
    fabric.densityTensors.resize(faces, 3);
    fabric.velocityTensors.resize(faces, 3);
    fabric.weftDirections.resize(faces, 3);
    const double d = 2e-4 * size * size;
    for (int f = 0; f < faces; ++f) {
      fabric.densityTensors.row(f) << 10 * d, 0, d;
      fabric.velocityTensors.row(f) << d, 0, d;
      if (grid) {
        fabric.weftDirections.row(f) << std::cos(kPi / 6), std::sin(kPi / 6), 0;
      } else {
        fabric.weftDirections.row(f) =
            mesh.vertexPositions.row(mesh.faces(f, 1)) - mesh.vertexPositions.row(mesh.faces(f, 0));
      }
    }
    StainSolverDef def;
    def.gravity = grid ? Vector3(0, 0, -9.8) : Vector3(0, -9.8, 0);
    solver = std::make_unique<StainSolver>(*topology, mesh.vertexPositions, fabric, def);
    axis = (grid ? Vector3(0.3, 0.2, 1.0) : Vector3(0.2, 1.0, 0.1)).normalized();
    RowVectors3 velocities(n, 3);
    for (int i = 0; i < n; ++i) velocities.row(i) = (kOmega * axis).cross(Vector3(centered.row(i).transpose())).transpose();
    solver->setInitialMotion(mesh.vertexPositions, velocities);
    next = mesh.vertexPositions;

    const double area = solver->geometry().intrinsic().vertexDualAreas.sum();
    DropDef drop;
    if (liquid == kDrop) {
      // The vertex nearest the centroid (grids) or the top (bunny).
      int c = 0;
      for (int i = 1; i < n; ++i) {
        const bool better = grid ? centered.row(i).norm() < centered.row(c).norm()
                                 : mesh.vertexPositions(i, 1) > mesh.vertexPositions(c, 1);
        if (better) c = i;
      }
      drop.centerVertex = c;
      drop.radius = std::sqrt(0.1 * area / kPi);
      drop.velocity = Vector3(0.05, 0.02, 0.0) * size;
    } else {
      drop.centerVertex = 0;
      drop.radius = 10 * size;  // every vertex, bump nearly flat
    }
    drop.solventMass = 0.5 * area * (liquid == kDrop ? 0.1 : 1.0);  // ~0.5 kg/m² where wet
    drop.soluteMass = 0.1 * drop.solventMass;
    solver->addDrop(drop);
  }

  Matrix3 rotationAt(double t) const { return Eigen::AngleAxisd(kOmega * t, axis).toRotationMatrix(); }

  StepReport advance(int path) {
    ++steps;
    const Matrix3 R = rotationAt(steps * kStep);
    next.noalias() = centered * R.transpose();
    next.rowwise() += center.transpose();
    gCountAllocations.store(true);
    const StepReport r = path == kRigid ? solver->stepRigid(kStep, next, R) : solver->step(kStep, next);
    gCountAllocations.store(false);
    return r;
  }
};

// Args: mesh id, liquid, threads, geometry path, adaptive threads (0: every
// step on `threads`; 1: the default, all of them or one, whichever measured
// faster, StainSolverDef::adaptiveThreads).
void stainStep(benchmark::State& bench) {
  const int id = static_cast<int>(bench.range(0));
  const int liquid = static_cast<int>(bench.range(1));
  const int threads = static_cast<int>(bench.range(2));
  const int path = static_cast<int>(bench.range(3));
  const bool adaptive = bench.range(4) != 0;
  Scene scene(id, liquid);
  scene.solver->setThreadCount(threads);  // the solver's own count, not OpenMP's process default
  scene.solver->setAdaptiveThreads(adaptive);
  for (int k = 0; k < kWarmupSteps; ++k) {
    const StepReport r = scene.advance(path);
    if (r.status != StepStatus::Ok) {
      bench.SkipWithError(("warm-up step failed in " + std::string(r.stageName()) + ": " + r.message).c_str());
      return;
    }
  }
  StepProfile sum;
  double wet = 0, fixes = 0, cg = 0, used = 0;
  gAllocations.store(0);
  for (auto _ : bench) {
    const StepReport r = scene.advance(path);
    if (r.status != StepStatus::Ok) {
      bench.SkipWithError(("step failed in " + std::string(r.stageName()) + ": " + r.message).c_str());
      break;
    }
    const StepProfile& p = scene.solver->profile();
    bench.SetIterationTime(p.total * 1e-3);
    sum.addTimes(p);
    sum.advectionSubsteps += p.advectionSubsteps;
    wet += p.wetVertices;
    fixes += p.limiterCorrectedVertices;
    cg += p.diffusionIterations;
    used += p.threads;
  }
  const auto mean = [](double value) { return benchmark::Counter(value, benchmark::Counter::kAvgIterations); };
  const int n = scene.solver->state().vertexCount();
  bench.counters["n"] = n;
  bench.counters["threads"] = threads;
  bench.counters["used"] = mean(used);  // threads a step used, mean
  bench.counters["geometry"] = mean(sum.time(Stage::Geometry));
  bench.counters["forces"] = mean(sum.time(Stage::BodyForces) + sum.time(Stage::FilmPressure) + sum.time(Stage::FilmFriction) + sum.time(Stage::Coriolis));
  bench.counters["advectVelocity"] = mean(sum.time(Stage::AdvectVelocity));
  bench.counters["advectDensity"] = mean(sum.time(Stage::AdvectDensity));
  bench.counters["diffuse"] = mean(sum.time(Stage::Diffuse));
  bench.counters["interact"] = mean(sum.time(Stage::Interact));
  bench.counters["total"] = mean(sum.total);
  bench.counters["substeps"] = mean(sum.advectionSubsteps);
  bench.counters["wet"] = mean(wet / n);
  bench.counters["fixes"] = mean(fixes);
  bench.counters["cgIters"] = mean(cg);
  bench.counters["allocs"] = mean(static_cast<double>(gAllocations.load()));
  static const char* const kMeshNames[] = {"grid2.5K", "grid10K", "grid35K", "bunny37K"};
  bench.SetLabel(std::string(kMeshNames[id]) + (liquid == kDrop ? " drop" : " wet") +
                 (path == kRigid ? " rigid" : " fitted"));
}

void stainStepArgs(benchmark::internal::Benchmark* b) {
  // Two threads fixed (adapt 0) and adaptive (adapt 1, the default).
  for (int id : {kGrid2500, kGrid10000, kGrid35000, kBunny})
    for (int liquid : {kDrop, kWet}) {
      b->Args({id, liquid, 1, kRigid, 0});
      for (int adapt : {0, 1}) b->Args({id, liquid, 2, kRigid, adapt});
    }
  // The generic (fitted) geometry path, for comparison; on two threads too
  // from 10K vertices, where the per-vertex stages and the CG run in parallel.
  for (int id : {kGrid2500, kGrid10000, kGrid35000, kBunny}) b->Args({id, kDrop, 1, kFitted, 0});
  for (int id : {kGrid10000, kGrid35000}) {
    b->Args({id, kWet, 1, kFitted, 0});
    for (int liquid : {kDrop, kWet})
      for (int adapt : {0, 1}) b->Args({id, liquid, 2, kFitted, adapt});
  }
}

BENCHMARK(stainStep)
    ->ArgNames({"mesh", "liquid", "threads", "path", "adapt"})
    ->Apply(stainStepArgs)
    ->UseManualTime()
    ->Iterations(40)
    ->Unit(benchmark::kMillisecond);

// The same step over 2,048 steps: long enough for adaptive threads to reach
// their longest hold (probes after 32, 64, ..., 1,024 steps), so the mean
// shows what the probes cost in a long run and not only in the first 40
// steps. One thread, two fixed, two adaptive, on meshes where a step is short.
void stainStepLong(benchmark::State& bench) { stainStep(bench); }
void stainStepLongArgs(benchmark::internal::Benchmark* b) {
  for (const auto& [id, liquid] : {std::pair{kGrid2500, kWet}, std::pair{kGrid10000, kDrop}}) {
    b->Args({id, liquid, 1, kRigid, 0});
    for (int adapt : {0, 1}) b->Args({id, liquid, 2, kRigid, adapt});
  }
}
BENCHMARK(stainStepLong)
    ->ArgNames({"mesh", "liquid", "threads", "path", "adapt"})
    ->Apply(stainStepLongArgs)
    ->UseManualTime()
    ->Iterations(2048)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::stain

BENCHMARK_MAIN();
