// Study (label "study", skipped by CI): error against cost, one CSV per
// experiment in $BLOT_STUDY_OUT (scripts/studies draws them into docs/charts).
//
//  (a) anisotropic diffusion vs the exact Gaussian (GaussianProblem: tensor
//      eigenvalues 1 and 0.1 m²/s, weft at 30°, T = 9e-4 s) over mesh size n
//      and step count; ours = backward Euler through diffuse() with the
//      positivity limiter, against explicit (forward Euler) diffusion at 95 %
//      of its stability limit h = 2/λ_max(M⁻¹L).
//  (b) a blob carried once around by a rigid rotation (1 rev/s) on a disc:
//      shape and mass error vs steps per revolution, ours (sub-stepped upwind)
//      vs the same with one sub-step vs the naive un-limited upwind.
//  (c) paper Fig. 5: centroid of liquid moving in a straight line in the
//      inertial frame on a disc rotating at 2 rad/s, through the StainSolver,
//      vs h, for ExactRotation, SplitRotation, Explicit and no Coriolis.
//  (d) homogenization (eq. 1) vs the refinement K, against a K = 64 solve.
//  (e) diffusion at a game's frame step h = 1/60 s: every method (the
//      factor, CG on the support, RKL2 on the support, forward Euler
//      sub-stepped at 95 % of its limit, and Auto) on one error-against-cost
//      chart, over the diffusivity (h λ_max from ~3 to ~300), for a stain
//      covering a third of a 16.6K grid and a 2 % stain on a 66K grid.
//
// Milliseconds are wall-clock per step (std::chrono), on a shared machine: the
// CSV files record the load average. Assertions check only what must hold
// whatever the timing (orders, conservation), with stated tolerances.
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/fabric/weave_pattern.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "stain_fixture.h"
#include "study_runs.h"
#include "study_support.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;
using test::CsvWriter;
using test::Stopwatch;

// (e) One frame step h = 1/60 s, 30 frames, a Gaussian stain (standard
// deviation `spread`, values below 1e-9 of the peak cut, so its support is
// compact) under the tensor (D, D/10) at 30°. Error: mass-weighted relative L2
// against the semi-discrete solution (Crank–Nicolson + Richardson with 32
// sub-steps a frame: the time-integration error alone) and against the exact
// Gaussian (space + time). Cost: wall-clock per frame including, for the
// factor, its one factorization spread over the 30 frames (the mesh is rigid).
TEST(AccuracyCostStudy, DiffusionAtAGameFrameStep) {
  struct Case {
    int n;
    double spread;
  };
  const double h = 1.0 / 60;
  const int frames = 30;
  CsvWriter csv("diffusion_game_step.csv",
                "case,method,n,vertices,diffusivity,h_lambda,stages_or_iterations,support_rows,ms_per_frame,"
                "time_error,total_error");
  std::printf("  load average %.2f\n", test::loadAverage());
  for (const Case c : {Case{128, 0.05}, Case{256, 0.0125}}) {
    for (const double d : {1e-3, 3e-3, 1e-2, 3e-2, 1e-1}) {
      GaussianProblem problem;
      problem.spread = c.spread;
      problem.weft = d;
      problem.warp = 0.1 * d;
      const int n = c.n;
      const LiquidMesh g(gridMesh(n, n, 1, 1), problem.fabric(2 * n * n));
      Vector initial = problem.exact(g, 0);
      const double cut = 1e-9 * initial.maxCoeff();
      for (Eigen::Index i = 0; i < initial.size(); ++i) {
        if (initial[i] < cut) initial[i] = 0.0;
      }
      const Vector reference = semiDiscreteReference(g, initial, frames * h, frames * 32);
      const Vector exact = problem.exact(g, frames * h);
      const double lambda = test::largestDiffusionEigenvalue(g.intrinsic.densityStiffness, g.areas());
      PhysicsSwitches switches;
      switches.velocityDiffusion = false;
      const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
      const char* caseName = n == 128 ? "third" : "small";
      const auto record = [&](const char* method, int work, int rows, double ms, const Vector& result) {
        const double timeError = relativeL2(g.areas(), result, reference);
        const double totalError = relativeL2(g.areas(), result, exact);
        std::printf("  %s n=%d D=%.0e h*lambda %6.1f %-8s work %3d rows %6d  %8.3f ms/frame  time error %.3e  "
                    "total %.3e\n",
                    caseName, n, d, h * lambda, method, work, rows, ms / frames, timeError, totalError);
        csv << caseName << method << n << g.vertexCount() << d << h * lambda << work << rows << ms / frames
            << timeError << totalError;
        csv.endRow();
        EXPECT_TRUE(result.allFinite()) << method;
      };
      for (const auto& [method, choice] :
           std::vector<std::pair<const char*, DiffusionSolverChoice>>{{"direct", DiffusionSolverChoice::Direct},
                                                                     {"cg", DiffusionSolverChoice::Iterative},
                                                                     {"rkl2", DiffusionSolverChoice::SuperTimeStepping},
                                                                     {"auto", DiffusionSolverChoice::Auto}}) {
        DiffusionSystems systems;
        systems.setSolverChoice(choice);
        DiffusionScratch scratch;
        scratch.resize(g.vertexCount());
        StainState state = zeroState(g.vertexCount());
        state.solvent = initial;
        int work = 0, rows = 0, fallbacks = 0;
        const Stopwatch clock;
        ASSERT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
        for (int k = 0; k < frames; ++k) {
          const DiffusionReport r = diffuse(ctx, g.intrinsic, systems, scratch, state);
          ASSERT_EQ(r.status, SolverStatus::Ok) << method;
          work = std::max({work, r.densityStages, r.densityIterations});
          rows = std::max(rows, r.densityMethod == DiffusionMethod::Direct ? g.vertexCount() : r.densityActiveVertices);
          fallbacks += r.fallbacks;
        }
        const double ms = clock.milliseconds();
        if (fallbacks > 0) std::printf("  (cg fell back to the factor on %d frames)\n", fallbacks);
        record(method, work, rows, ms, state.solvent);
        EXPECT_GE(state.solvent.minCoeff(), 0.0) << method;
      }
      // Forward Euler, as many sub-steps a frame as its limit needs (whole mesh).
      const int substeps = static_cast<int>(std::ceil(h * lambda / (0.95 * 2.0)));
      Vector sigma = initial;
      const Stopwatch clock;
      for (int k = 0; k < frames * substeps; ++k)
        test::explicitDiffusionStep(g.intrinsic.densityStiffness, g.areas(), h / substeps, sigma);
      record("explicit", substeps, g.vertexCount(), clock.milliseconds(), sigma);
    }
  }
}

TEST(AccuracyCostStudy, AnisotropicDiffusionAgainstTheExactGaussian) {
  const GaussianProblem problem;
  // Rows are written at the end grouped by (method, steps), n ascending, so
  // each chart line is a contiguous block of the file.
  struct Row {
    std::string method;
    int n, vertices, steps;
    double h, msPerStep, totalMs, error;
  };
  std::vector<Row> rows;
  std::printf("  load average %.2f\n", test::loadAverage());
  double previousFine = 0;
  for (const int n : {32, 64, 128, 256}) {
    const LiquidMesh g(gridMesh(n, n, 1, 1), problem.fabric(2 * n * n));
    const Vector initial = problem.exact(g, 0), exact = problem.exact(g, problem.endTime());
    PhysicsSwitches switches;
    switches.velocityDiffusion = false;
    for (const int steps : {4, 16, 64, 256}) {
      const double h = problem.endTime() / steps;
      DiffusionSystems systems;
      systems.setSolverChoice(DiffusionSolverChoice::Direct);  // "implicit": the factor, as this chart always showed
      ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
      DiffusionScratch scratch;
      scratch.resize(g.vertexCount());
      StainState state = zeroState(g.vertexCount());
      state.solvent = initial;
      const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
      const Stopwatch clock;
      for (int k = 0; k < steps; ++k) ASSERT_EQ(diffuse(ctx, g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
      const double ms = clock.milliseconds();
      const double error = relativeL2(g.areas(), state.solvent, exact);
      std::printf("  implicit n = %3d  steps %3d  %.4f ms/step  L2 error %.4e\n", n, steps, ms / steps, error);
      rows.push_back({"implicit", n, g.vertexCount(), steps, h, ms / steps, ms, error});
      if (steps == 256) {
        // Space order between successive n at the smallest h (the time error
        // at T/256 is below the space error up to n = 128).
        if (previousFine > 0) {
          const double order = std::log2(previousFine / error);
          std::printf("  observed space order (n = %d / %d, 256 steps): %.2f\n", n / 2, n, order);
          if (n <= 128) {
            EXPECT_GT(order, 1.5);
          }
        }
        previousFine = error;
      }
    }
    // Explicit: as many steps as stability needs.
    const double lambda = test::largestDiffusionEigenvalue(g.intrinsic.densityStiffness, g.areas());
    const int steps = static_cast<int>(std::ceil(problem.endTime() * lambda / (0.95 * 2.0)));
    const double h = problem.endTime() / steps;
    Vector sigma = initial;
    const Stopwatch clock;
    for (int k = 0; k < steps; ++k) test::explicitDiffusionStep(g.intrinsic.densityStiffness, g.areas(), h, sigma);
    const double ms = clock.milliseconds();
    const double error = relativeL2(g.areas(), sigma, exact);
    std::printf("  explicit n = %3d  steps %5d (lambda_max %.3g /s)  %.4f ms/step  L2 error %.4e\n", n, steps, lambda,
                ms / steps, error);
    rows.push_back({"explicit", n, g.vertexCount(), steps, h, ms / steps, ms, error});
    EXPECT_TRUE(sigma.allFinite());
  }
  std::stable_sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) {
    return a.method != b.method ? a.method < b.method : (a.method == "implicit" && a.steps < b.steps);
  });
  CsvWriter csv("diffusion_error_cost.csv", "method,n,vertices,steps,h,ms_per_step,total_ms,l2_error");
  for (const Row& r : rows) {
    csv << r.method << r.n << r.vertices << r.steps << r.h << r.msPerStep << r.totalMs << r.error;
    csv.endRow();
  }
}

TEST(AccuracyCostStudy, BlobAdvectedByARigidRotation) {
  CsvWriter csv("advection_error_cost.csv",
                "method,rings,vertices,steps_per_rev,h,ms_per_step,substeps_per_step,shape_error,mass_error,"
                "min_over_max,growth");
  for (const int rings : {24, 48, 96}) {
    const TriangleMesh mesh = discMesh(rings, 1.0);
    std::map<int, test::RotationAdvectionResult> ours;
    const LiquidMesh g(mesh, isotropicFabric(static_cast<int>(mesh.faces.rows())));
    for (const test::AdvectionMethod method :
         {test::AdvectionMethod::Ours, test::AdvectionMethod::CapOne, test::AdvectionMethod::Naive}) {
      for (const int steps : {25, 50, 100, 200, 400, 800}) {
        test::RotationAdvectionSetup setup;
        setup.steps = steps;
        setup.h = 1.0 / steps;
        setup.method = method;
        const test::RotationAdvectionResult r = test::runRigidRotationAdvection(g, setup);
        std::printf("  %-40s rings %2d  %4d steps/rev  %.4f ms/step  %5.1f sub  shape %.3e  mass %.1e  min/max %.2e\n",
                    test::toString(method), rings, steps, r.msPerStep, r.substepsPerStep, r.shapeError, r.massError,
                    r.health.minOverMax);
        csv << test::toString(method) << rings << r.vertices << steps << setup.h << r.msPerStep << r.substepsPerStep
            << r.shapeError << r.massError << r.health.minOverMax << r.health.growth;
        csv.endRow();
        if (method == test::AdvectionMethod::Ours) {
          EXPECT_LT(r.massError, 1e-12);
          EXPECT_GE(r.health.minOverMax, 0.0);
          ours[steps] = r;
        }
        // Where ours needs one sub-step (Courant <= 1) all three are the same
        // scheme: the naive re-implementation must agree to rounding.
        if (method == test::AdvectionMethod::Naive && ours[steps].substepsPerStep == 1.0) {
          EXPECT_NEAR(r.shapeError, ours[steps].shapeError, 1e-9 * ours[steps].shapeError);
        }
      }
    }
  }
}

TEST(AccuracyCostStudy, CoriolisTrajectoryOnTheRotatingDisc) {
  CsvWriter csv("coriolis_error_cost.csv",
                "method,rings,vertices,h,steps,ms_per_step,final_error,max_error,energy_ratio,ok");
  // Lines: scheme at 48 rings, and ExactRotation at 24 and 96 rings (the
  // error floor at small h is the upwind smear of the blob, first order in dx).
  const std::pair<const char*, int> lines[] = {{"ExactRotation", 48}, {"Explicit", 48}, {"no Coriolis", 48},
                                               {"ExactRotation", 24}, {"ExactRotation", 96}, {"SplitRotation", 48}};
  for (const auto& [method, rings] : lines) {
    for (const double h : {0.04, 0.02, 0.01, 0.005, 0.0025}) {
      test::RotatingDiscSetup setup;
      setup.rings = rings;
      setup.h = h;
      setup.blobCenter = Vector3(0.5, 0, 0);
      setup.inertialVelocity = Vector3(-0.2, 0.2, 0);  // a straight line from (0.5, 0) to (0.19, 0.31)
      setup.coriolis = std::string(method) != "no Coriolis";
      setup.scheme = std::string(method) == "Explicit"        ? CoriolisScheme::Explicit
                     : std::string(method) == "SplitRotation" ? CoriolisScheme::SplitRotation
                                                              : CoriolisScheme::ExactRotation;
      const test::RotatingDiscResult r = test::runRotatingDisc(setup);
      std::printf("  %-14s rings %2d  h = %.4f  %.3f ms/step  final %.4f R  max %.4f R  energy ratio %.3f %s\n", method, rings, h,
                  r.msPerStep, r.finalError, r.maxError, r.energyRatio, r.ok ? "" : r.failure.c_str());
      csv << method << rings << r.vertices << h << r.stepsDone << r.msPerStep << r.finalError << r.maxError << r.energyRatio
          << (r.ok ? 1 : 0);
      csv.endRow();
      if (std::string(method) == "ExactRotation" && rings >= 48) {
        EXPECT_LT(r.maxError, 0.05);
      }
    }
  }
}

TEST(AccuracyCostStudy, HomogenizationAgainstRefinement) {
  CsvWriter csv("homogenization_error_cost.csv", "pattern,cells,K,unknowns,ms,relative_error");
  // Reference: K = 64 (the error at K = 32 is then under-estimated by about
  // a quarter at order 2; orders are quoted from K <= 16).
  for (const char* name : {"plain", "twill-2-1", "rib-knit"}) {
    const WeavePattern pattern = presetWeavePattern(name);
    const Matrix2 reference = homogenize(pattern, 64).effective;
    double previous = 0;
    for (const int k : {2, 4, 8, 16, 32}) {
      const Stopwatch clock;
      const HomogenizationResult r = homogenize(pattern, k);
      const double ms = clock.milliseconds();
      const double error = (r.effective - reference).norm() / reference.norm();
      const int cells = r.vertexCount / (k * k);
      std::printf("  %-10s K = %3d  %7d unknowns  %9.2f ms  relative error %.3e", name, k, r.vertexCount, ms, error);
      if (previous > 0) std::printf("  order %.2f", std::log2(previous / error));
      std::printf("\n");
      previous = error;
      csv << name << cells << k << r.vertexCount << ms << error;
      csv.endRow();
    }
    EXPECT_LT(previous, 0.02) << name;
  }
}

}  // namespace
}  // namespace blot::stain
