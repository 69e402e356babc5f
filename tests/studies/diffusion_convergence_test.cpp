// Study (label "study", skipped by CI): the long version of the diffusion
// convergence tests in tests/stain/diffusion_test.cpp, and a table of how far
// the raw implicit solve undershoots below zero under strong anisotropy.
//
// Problem (GaussianProblem in tests/support/stain_fixture.h): unit-mass Gaussian of
// standard deviation 0.06 in [0,1]², constant tensor eigenvalues (1, 0.1) m²/s
// with the weft at 30° to the grid, run to T = 9e-4 s; the exact solution is the
// Gaussian of covariance Σ0 + 2DT.
#include <blot/stain/stages/diffusion.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;

double observedOrder(double coarse, double fine, double ratio) {
  return std::log(coarse / fine) / std::log(ratio);
}

TEST(DiffusionConvergenceStudy, SpaceFourLevels) {
  const GaussianProblem problem;
  const int levels[] = {32, 64, 128, 256};
  double previous = 0.0;
  for (int n : levels) {
    const auto start = std::chrono::steady_clock::now();
    const LiquidMesh g(gridMesh(n, n, 1, 1), problem.fabric(2 * n * n));
    const Vector computed = semiDiscreteReference(g, problem.exact(g, 0), problem.endTime(), 16);
    const double error = relativeL2(g.areas(), computed, problem.exact(g, problem.endTime()));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("  space  n = %3d (%6d vertices)  L2 error %.4e", n, g.vertexCount(), error);
    if (previous > 0) {
      const double order = observedOrder(previous, error, 2.0);
      std::printf("  order %.3f", order);
      EXPECT_GE(order, 1.8);
      EXPECT_LE(order, 2.3);
    }
    std::printf("  (%.1f s)\n", seconds);
    previous = error;
  }
}

TEST(DiffusionConvergenceStudy, TimeSevenLevels) {
  const GaussianProblem problem;
  const int n = 64;
  const LiquidMesh g(gridMesh(n, n, 1, 1), problem.fabric(2 * n * n));
  const Vector initial = problem.exact(g, 0);
  const Vector reference = semiDiscreteReference(g, initial, problem.endTime(), 256);
  const Vector exact = problem.exact(g, problem.endTime());
  std::printf("  spatial error of the semi-discrete solution at n = %d: %.4e\n", n,
              relativeL2(g.areas(), reference, exact));
  double previous = 0.0;
  for (int steps = 2; steps <= 128; steps *= 2) {
    const Vector computed = integrateDiffusion(g, initial, problem.endTime(), steps, false);
    const double error = relativeL2(g.areas(), computed, reference);
    std::printf("  time   h = T/%-3d  L2 error vs semi-discrete %.4e (vs exact %.4e)", steps, error,
                relativeL2(g.areas(), computed, exact));
    if (previous > 0) {
      const double order = observedOrder(previous, error, 2.0);
      std::printf("  order %.3f", order);
      if (steps >= 8) {  // the first levels are pre-asymptotic (orders 0.83, 0.90)
        EXPECT_GE(order, 0.85);
        EXPECT_LE(order, 1.15);
      }
    }
    std::printf("\n");
    previous = error;
  }
}

// Most negative density (relative to the maximum) of the raw backward-Euler
// solve over 20 steps from a smooth spot on a 40x40 grid, by eigenvalue ratio,
// weft angle and h D_max / dx²; and what the limiter moves.
TEST(DiffusionConvergenceStudy, AnisotropyUndershootTable) {
  const int n = 40;
  std::printf("  angle  ratio   hD/dx²   raw min/max   limiter moved per step (of the mass)\n");
  for (const double angle : {0.0, kPi / 6, kPi / 4}) {
    for (const double ratio : {1e2, 1e4, 1e6}) {
      for (const double courant : {0.1, 1.0, 10.0, 100.0}) {
        const LiquidMesh g(gridMesh(n, n, 1, 1),
                           uniformFabric(2 * n * n, fabricTensor(1, 1 / ratio), fabricTensor(1, 1), angle));
        const double h = courant / (n * n);
        DiffusionSystems systems;
        ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
        DiffusionScratch scratch;
        scratch.resize(g.vertexCount());
        StainState state = zeroState(g.vertexCount());
        for (int i = 0; i < g.vertexCount(); ++i) {
          const double r = (g.position(i).head<2>() - Vector2(0.5, 0.5)).norm() / 0.15;
          state.solvent[i] = r < 1 ? (1 - r * r) * (1 - r * r) : 0.0;
        }
        const double mass = totalMass(g.areas(), state.solvent);
        PhysicsSwitches switches;
        switches.velocityDiffusion = false;
        const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
        double worst = 0, moved = 0;
        for (int step = 0; step < 20; ++step) {
          const DiffusionReport report = diffuse(ctx, g.intrinsic, systems, scratch, state);
          ASSERT_EQ(report.status, SolverStatus::Ok);
          worst = std::min(worst, report.minDensityBeforeLimiter / state.solvent.maxCoeff());
          moved += report.limiterMovedMass;
        }
        std::printf("  %4.0f°  %5.0e  %6.1f   %11.3e   %.2e\n", angle * 180 / kPi, ratio, courant, worst,
                    moved / 20 / mass);
        EXPECT_GE(state.solvent.minCoeff(), 0.0);
        EXPECT_NEAR(totalMass(g.areas(), state.solvent), mass, 1e-13 * mass);
      }
    }
  }
}

}  // namespace
}  // namespace blot::stain
