// Tests for stage "diffuse" (stain/src/stages/diffusion.cpp): convergence against the
// exact anisotropic Gaussian, mass conservation, the positivity limiter under
// strong anisotropy, velocity diffusion, factorization reuse, failure handling,
// and zero allocation after the first call (with interact and applySources).
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/stages/interaction.h>
#include <blot/stain/stages/sources.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "allocation_counter.h"  // counts every allocation while gCountAllocations is set (not under ASan)
#include "geometry_test_support.h"
#include "stain_fixture.h"

namespace {
std::atomic<bool>& countAllocations = gCountAllocations;
std::atomic<long>& allocationCount = gAllocations;
}  // namespace

namespace blot::stain {
namespace {

using namespace liquid_testing;

StepContext diffusionContext(double h, bool limiter = true, bool velocity = true) {
  PhysicsSwitches switches;
  switches.positivityLimiter = limiter;
  switches.velocityDiffusion = velocity;
  return makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
}

double observedOrder(double coarseError, double fineError, double ratio) {
  return std::log(coarseError / fineError) / std::log(ratio);
}

// --- Convergence -----------------------------------------------------------

// Spatial order: the time error is removed with a Crank–Nicolson/Richardson
// reference (measured below 6e-6 relative, against spatial errors ≥ 2.5e-3),
// so what is left is the P1/lumped-mass error against the exact Gaussian.
TEST(DiffusionConvergence, AnisotropicGaussianIsSecondOrderInMeshSize) {
  const GaussianProblem problem;
  const int levels[] = {24, 48, 96};
  double errors[3];
  for (int l = 0; l < 3; ++l) {
    const int n = levels[l];
    const LiquidMesh g(gridMesh(n, n, 1, 1), problem.fabric(2 * n * n));
    const Vector computed = semiDiscreteReference(g, problem.exact(g, 0), problem.endTime(), 8);
    errors[l] = relativeL2(g.areas(), computed, problem.exact(g, problem.endTime()));
    std::printf("  space  n = %3d  dx = %.5f  L2 error %.4e", n, 1.0 / n, errors[l]);
    if (l > 0) std::printf("  order %.3f", observedOrder(errors[l - 1], errors[l], 2.0));
    std::printf("\n");
  }
  for (int l = 1; l < 3; ++l) {
    const double order = observedOrder(errors[l - 1], errors[l], 2.0);
    EXPECT_GE(order, 1.8) << "level " << levels[l];
    EXPECT_LE(order, 2.3) << "level " << levels[l];
  }
}

// Temporal order of backward Euler through `diffuse`: errors against the
// semi-discrete solution on the same mesh (so the spatial error cancels).
TEST(DiffusionConvergence, BackwardEulerIsFirstOrderInTimeStep) {
  const GaussianProblem problem;
  const int n = 32;
  const LiquidMesh g(gridMesh(n, n, 1, 1), problem.fabric(2 * n * n));
  const Vector initial = problem.exact(g, 0);
  const double endTime = problem.endTime();
  const Vector reference = semiDiscreteReference(g, initial, endTime, 64);
  const Vector exact = problem.exact(g, endTime);
  const int steps[] = {4, 8, 16, 32};
  double errors[4];
  for (int l = 0; l < 4; ++l) {
    const Vector computed = integrateDiffusion(g, initial, endTime, steps[l], false);
    errors[l] = relativeL2(g.areas(), computed, reference);
    std::printf("  time   h = T/%-3d L2 error vs semi-discrete %.4e (vs exact Gaussian %.4e)", steps[l],
                errors[l], relativeL2(g.areas(), computed, exact));
    if (l > 0) std::printf("  order %.3f", observedOrder(errors[l - 1], errors[l], 2.0));
    std::printf("\n");
  }
  for (int l = 1; l < 4; ++l) {
    const double order = observedOrder(errors[l - 1], errors[l], 2.0);
    EXPECT_GE(order, 0.85) << "steps " << steps[l];
    EXPECT_LE(order, 1.15) << "steps " << steps[l];
  }
}

// --- Conservation and positivity --------------------------------------------

TEST(Diffusion, ConservesMassOnACurvedIrregularMeshWithRandomFabric) {
  TriangleMesh mesh = testing::jitteredIcosphere(3, 0.3, 11);
  const int faces = static_cast<int>(mesh.faces.rows());
  auto [tensors, wefts] = testing::randomFabric(faces, 1e3, 5);
  FabricField fabric;
  fabric.densityTensors = tensors;
  fabric.velocityTensors = tensors;
  fabric.weftDirections = wefts;
  const LiquidMesh g(std::move(mesh), fabric);
  const double h = 0.5;  // h D / dx² up to ~40
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int i = 0; i < g.vertexCount(); ++i) {
    state.solvent[i] = g.position(i).z() > 0.5 ? 1 + unit(rng) : 0.0;  // a cap, zero elsewhere
    state.solute[i] = 0.1 * unit(rng) * state.solvent[i];
  }
  const double solvent0 = totalMass(g.areas(), state.solvent);
  const double solute0 = totalMass(g.areas(), state.solute);
  double worst = 0;
  for (int step = 0; step < 50; ++step) {
    ASSERT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
    worst = std::max(worst, std::abs(totalMass(g.areas(), state.solvent) / solvent0 - 1));
    worst = std::max(worst, std::abs(totalMass(g.areas(), state.solute) / solute0 - 1));
  }
  std::printf("  worst relative mass drift over 50 steps: %.2e\n", worst);
  EXPECT_LE(worst, 1e-13);
}

// Ratio 1e6 with the weft at 30° to the grid: P1 stiffness has positive
// off-diagonals, so backward Euler undershoots. Measure it, then check the
// limiter removes it and keeps the mass.
TEST(Diffusion, StrongAnisotropyUndershootIsRemovedByTheMassConservingLimiter) {
  const int n = 40;
  const double ratio = 1e6;
  const LiquidMesh g(gridMesh(n, n, 1, 1),
                     uniformFabric(2 * n * n, fabricTensor(1, 1 / ratio), fabricTensor(1, 1), kPi / 6));
  const double h = 10.0 / (n * n);  // h D_max / dx² = 10
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  const Vector initial = spot(g, Vector2(0.5, 0.5), 0.15, 2.0);

  for (const bool limiter : {false, true}) {
    StainState state = zeroState(g.vertexCount());
    state.solvent = initial;
    state.solute = 0.1 * initial;
    const double solvent0 = totalMass(g.areas(), state.solvent);
    const double solute0 = totalMass(g.areas(), state.solute);
    double rawMin = 0, worstMin = 0, worstMass = 0, moved = 0;
    int corrected = 0;
    for (int step = 0; step < 20; ++step) {
      const DiffusionReport report =
          diffuse(diffusionContext(h, limiter), g.intrinsic, systems, scratch, state);
      ASSERT_EQ(report.status, SolverStatus::Ok);
      const double peak = state.solvent.maxCoeff();
      rawMin = std::min(rawMin, report.minDensityBeforeLimiter / peak);
      worstMin =
          std::min({worstMin, state.solvent.minCoeff() / peak, state.solute.minCoeff() / (0.1 * peak)});
      worstMass = std::max({worstMass, std::abs(totalMass(g.areas(), state.solvent) / solvent0 - 1),
                            std::abs(totalMass(g.areas(), state.solute) / solute0 - 1)});
      corrected += report.limiterCorrectedVertices;
      moved += report.limiterMovedMass;
    }
    std::printf(
        "  limiter %-3s: raw min/max %.3e, min/max after %.3e, mass drift %.2e, "
        "%d vertex fixes, %.3e kg moved (%.2e of the mass per step)\n",
        limiter ? "on" : "off", rawMin, worstMin, worstMass, corrected, moved,
        moved / 20 / (solvent0 + solute0));
    EXPECT_LT(rawMin, -1e-3) << "the raw solve should undershoot here (the reason for the limiter)";
    EXPECT_LE(worstMass, 1e-13);
    if (limiter) {
      EXPECT_GE(worstMin, -1e-12);
      EXPECT_GT(corrected, 0);
    } else {
      EXPECT_LT(worstMin, -1e-3);
      EXPECT_EQ(corrected, 0);
    }
  }
}

// --- The limiter on its own ------------------------------------------------------

struct LimiterMesh : ::testing::Test {
  const int n = 20;
  LiquidMesh g{gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n)};
  int vertex(int i, int j) const { return j * (n + 1) + i; }
  std::vector<char> ringOrSelf(const std::vector<int>& centers) const {
    std::vector<char> mark(static_cast<size_t>(g.vertexCount()), 0);
    for (int c : centers) {
      mark[static_cast<size_t>(c)] = 1;
      for (int m = g.topology.ringOffsets()[c]; m < g.topology.ringOffsets()[c + 1]; ++m) {
        mark[static_cast<size_t>(g.topology.ringNeighbors()[m])] = 1;
      }
    }
    return mark;
  }
};

TEST_F(LimiterMesh, FixesNegativesFromTheOneRingOnlyAndConservesMass) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> unit(0.1, 1.0);
  Vector sigma(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) sigma[i] = unit(rng);
  const std::vector<int> negatives = {vertex(3, 3), vertex(10, 12), vertex(15, 4), vertex(0, 7)};
  for (int v : negatives) sigma[v] = -0.05;
  const Vector before = sigma;
  const auto [fixed, moved] = limitPositivity(g.topology, g.areas(), sigma);
  EXPECT_EQ(fixed, 4);
  EXPECT_NEAR(moved,
              0.05 * (g.areas()[negatives[0]] + g.areas()[negatives[1]] + g.areas()[negatives[2]] +
                      g.areas()[negatives[3]]),
              1e-17);
  EXPECT_GE(sigma.minCoeff(), 0.0);
  EXPECT_NEAR(totalMass(g.areas(), sigma), totalMass(g.areas(), before),
              1e-15 * totalMass(g.areas(), before));
  const std::vector<char> touched = ringOrSelf(negatives);
  for (int i = 0; i < g.vertexCount(); ++i) {
    if (!touched[static_cast<size_t>(i)]) {
      EXPECT_EQ(sigma[i], before[i]) << "vertex " << i;
    } else {
      EXPECT_LE(sigma[i], std::max(before[i], 0.0)) << "vertex " << i;  // donors only give
    }
  }
}

TEST_F(LimiterMesh, AHoleWithoutPositiveNeighboursTravelsToTheNearestMass) {
  // Mass two rings away from the hole, nothing in its one-ring: the search
  // takes it from the second ring, and only from there.
  Vector sigma = Vector::Zero(g.vertexCount());
  const int hole = vertex(10, 10);
  sigma[hole] = -0.01;
  for (int i = 0; i <= n; ++i) sigma[vertex(i, 12)] = 1.0;  // a row two rings up
  const double mass = totalMass(g.areas(), sigma);
  const auto [fixed, moved] = limitPositivity(g.topology, g.areas(), sigma);
  EXPECT_EQ(fixed, 1);
  EXPECT_NEAR(moved, 0.01 * g.areas()[hole], 1e-15);
  EXPECT_GE(sigma.minCoeff(), 0.0);
  EXPECT_NEAR(totalMass(g.areas(), sigma), mass, 1e-15 * mass);
  for (int i = 0; i <= n; ++i) {
    if (std::abs(i - 10) > 2) {
      EXPECT_EQ(sigma[vertex(i, 12)], 1.0) << "the correction stays local, i = " << i;
    }
  }
}

TEST_F(LimiterMesh, FarFromAnyMassTheGlobalFallbackConservesMass) {
  Vector sigma = Vector::Zero(g.vertexCount());
  sigma[vertex(2, 2)] = -0.01;
  sigma[vertex(18, 18)] = 1.0;  // 16 rings away: beyond the local search (~8 rings)
  const double mass = totalMass(g.areas(), sigma);
  const auto [fixed, moved] = limitPositivity(g.topology, g.areas(), sigma);
  EXPECT_EQ(fixed, 1);
  EXPECT_GT(moved, 0.0);
  EXPECT_GE(sigma.minCoeff(), 0.0);
  EXPECT_NEAR(totalMass(g.areas(), sigma), mass, 1e-15 * std::abs(mass));
}

TEST_F(LimiterMesh, NonNegativeFieldsAreLeftBitIdenticalAndRunsAreDeterministic) {
  Vector sigma = Vector::Zero(g.vertexCount());
  sigma[vertex(4, 4)] = 2.0;
  const Vector before = sigma;
  const auto [fixed, moved] = limitPositivity(g.topology, g.areas(), sigma);
  EXPECT_EQ(fixed, 0);
  EXPECT_EQ(moved, 0.0);
  EXPECT_TRUE((sigma.array() == before.array()).all());

  std::mt19937 rng(4);
  std::uniform_real_distribution<double> value(-0.3, 1.0);
  Vector a(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) a[i] = value(rng);
  Vector b = a;
  limitPositivity(g.topology, g.areas(), a);
  limitPositivity(g.topology, g.areas(), b);
  EXPECT_TRUE((a.array() == b.array()).all());
  EXPECT_GE(a.minCoeff(), 0.0);
}

// --- Velocity ----------------------------------------------------------------------

TEST(Diffusion, UniformVelocityFieldOnAFlatMeshIsUnchanged) {
  const int n = 20;
  const LiquidMesh g(gridMesh(n, n, 1, 1),
                     uniformFabric(2 * n * n, fabricTensor(1, 1), fabricTensor(1, 0.01), 0.5));
  const double h = 1.0;  // h S / dx² = 400: any error in the transport would show
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  const Vector3 world(0.3, -0.7, 0.0);
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Matrix3& frame = g.extrinsic.frames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(world.dot(frame.col(0)), world.dot(frame.col(1)));
  }
  const ComplexVector before = state.velocities;
  ASSERT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
  const double change = (state.velocities - before).cwiseAbs().maxCoeff();
  std::printf("  max |Δu| of a uniform field after one step: %.2e m/s (|u| = %.2f)\n", change, world.norm());
  EXPECT_LE(change, 1e-12 * world.norm());
}

TEST(Diffusion, VelocityEnergyNeverIncreases) {
  TriangleMesh mesh = testing::jitteredIcosphere(3, 0.3, 2);
  const int faces = static_cast<int>(mesh.faces.rows());
  auto [tensors, wefts] = testing::randomFabric(faces, 1e4, 8);
  FabricField fabric;
  fabric.densityTensors = tensors;
  fabric.velocityTensors = 1e-4 * tensors;  // eigenvalues 1e-4 to 1 m²/s
  fabric.weftDirections = wefts;
  const LiquidMesh g(std::move(mesh), fabric);
  const double h = 0.01;
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  std::mt19937 rng(1);
  std::normal_distribution<double> normal;
  for (int i = 0; i < g.vertexCount(); ++i) state.velocities[i] = Complex(normal(rng), normal(rng));
  auto energy = [&] { return (g.areas().array() * state.velocities.array().abs2()).sum(); };
  double previous = energy();
  const double initial = previous;
  for (int step = 0; step < 30; ++step) {
    ASSERT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
    const double current = energy();
    EXPECT_LE(current, previous * (1 + 1e-14)) << "step " << step;
    previous = current;
  }
  std::printf("  velocity energy after 30 steps: %.4f of the initial\n", previous / initial);
  EXPECT_LT(previous, 0.9 * initial);  // and it does dissipate
}

// --- Systems, switches, failures ---------------------------------------------------

// preparePatterns (StainSolver's construction) builds what the first
// assemble would allocate: that assemble then allocates nothing and fills
// the same patterns with the same values as one without it, and nothing is
// analysed or factorized before the first direct solve.
TEST(DiffusionSystems, PreparedPatternsLetTheFirstAssemblyAllocateNothing) {
  const int n = 10;
  const LiquidMesh g(gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n));
  DiffusionSystems prepared, plain;
  prepared.preparePatterns(g.intrinsic);
  EXPECT_EQ(prepared.scalarSystem().nonZeros(), g.intrinsic.densityStiffness.nonZeros());
  EXPECT_EQ(prepared.vectorSystem().nonZeros(), g.intrinsic.velocityStiffness.nonZeros());
  countAllocations = true;
  allocationCount = 0;
  ASSERT_EQ(prepared.assemble(g.intrinsic, 0.01), SolverStatus::Ok);
  countAllocations = false;
  if (kCountsAllocations) {
    EXPECT_EQ(allocationCount.load(), 0);
  }
  ASSERT_EQ(plain.assemble(g.intrinsic, 0.01), SolverStatus::Ok);
  const auto same = [](const auto& a, const auto& b) {
    return a.nonZeros() == b.nonZeros() &&
           std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.cols() + 1, b.outerIndexPtr()) &&
           std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr()) &&
           std::equal(a.valuePtr(), a.valuePtr() + a.nonZeros(), b.valuePtr());
  };
  EXPECT_TRUE(same(prepared.scalarSystem(), plain.scalarSystem()));
  EXPECT_TRUE(same(prepared.vectorSystem(), plain.vectorSystem()));
  // The pattern is L's union with the diagonal (taken as L's own when L
  // holds every diagonal entry, as the one-ring operators do).
  const auto samePattern = [](const auto& a, const auto& b) {
    return a.nonZeros() == b.nonZeros() &&
           std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.cols() + 1, b.outerIndexPtr()) &&
           std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
  };
  SparseMatrix identity(g.vertexCount(), g.vertexCount());
  identity.setIdentity();
  SparseMatrix expected = g.intrinsic.densityStiffness + identity;
  expected.makeCompressed();
  EXPECT_TRUE(samePattern(prepared.scalarSystem(), expected));
  // An L without its diagonal entries gets them added (explicit zeros kept).
  IntrinsicGeometry offDiagonal = g.intrinsic;
  offDiagonal.densityStiffness.prune([](Eigen::Index row, Eigen::Index col, double) { return row != col; });
  offDiagonal.densityStiffness.makeCompressed();
  DiffusionSystems added;
  ASSERT_EQ(added.assemble(offDiagonal, 0.01), SolverStatus::Ok);
  EXPECT_TRUE(samePattern(added.scalarSystem(), expected));
  EXPECT_EQ(prepared.scalarSolver().analysisCount(), 0);
  EXPECT_EQ(prepared.factorizationCount(), 0);
  ASSERT_EQ(prepared.factorize(g.intrinsic, 0.01), SolverStatus::Ok);  // the analysis still runs when needed
  EXPECT_EQ(prepared.scalarSolver().analysisCount(), 1);
}

// The direct solves of DiffusionSystems' public API: the factor is made at
// the first solve after assemble() and only then (lazily, once), a solve of
// (M + h L) x = b satisfies it to round-off, and the in-place pair solve the
// diffusion stage uses gives each right-hand side bitwise what solveScalar
// gives it alone.
TEST(DiffusionSystems, DirectSolvesFactorizeOnceLazilyAndAgreeBitwise) {
  const int n = 12;
  const LiquidMesh g(gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n));
  const double h = 0.01;
  DiffusionSystems systems;
  ASSERT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
  EXPECT_EQ(systems.factorizationCount(), 0) << "assemble factorizes nothing";
  Vector b1(g.vertexCount()), b2(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) {
    b1[i] = std::sin(0.37 * i) + 1.5;
    b2[i] = std::cos(0.11 * i * i);
  }
  Vector x1, x2;
  ASSERT_EQ(systems.solveScalar(b1, x1), SolverStatus::Ok);
  EXPECT_EQ(systems.factorizationCount(), 1) << "the scalar factor only";
  ASSERT_EQ(systems.solveScalar(b2, x2), SolverStatus::Ok);
  EXPECT_EQ(systems.factorizationCount(), 1) << "a second solve reuses the factor";
  const SparseMatrix& A = systems.scalarSystem();
  EXPECT_LE((A * x1 - b1).norm(), 1e-12 * b1.norm());
  EXPECT_LE((A * x2 - b2).norm(), 1e-12 * b2.norm());
  Vector a = b1, b = b2;
  ASSERT_EQ(systems.solveScalarInPlace(a, &b), SolverStatus::Ok);
  EXPECT_TRUE((a.array() == x1.array()).all());
  EXPECT_TRUE((b.array() == x2.array()).all());
  Vector alone = b2;
  ASSERT_EQ(systems.solveScalarInPlace(alone), SolverStatus::Ok);
  EXPECT_TRUE((alone.array() == x2.array()).all());
  // New values (another h): the next solve factorizes again, once.
  ASSERT_EQ(systems.assemble(g.intrinsic, 2 * h), SolverStatus::Ok);
  ASSERT_EQ(systems.solveScalar(b1, x1), SolverStatus::Ok);
  ASSERT_EQ(systems.solveScalar(b2, x2), SolverStatus::Ok);
  EXPECT_EQ(systems.factorizationCount(), 2);
  EXPECT_LE((systems.scalarSystem() * x1 - b1).norm(), 1e-12 * b1.norm());
}

TEST(DiffusionSystems, RefactorizationReusesTheScalarAnalysisForBothSystems) {
  const int n = 10;
  const LiquidMesh g(gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n));
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, 0.01), SolverStatus::Ok);
  ASSERT_EQ(systems.factorize(g.intrinsic, 0.02), SolverStatus::Ok);
  EXPECT_EQ(systems.assembledStep(), 0.02);
  EXPECT_EQ(systems.assemblyCount(), 2);
  EXPECT_EQ(systems.factorizationCount(), 4) << "two systems, factorized twice each";
  EXPECT_EQ(systems.scalarSolver().analysisCount(), 1);
  EXPECT_EQ(systems.vectorSolver().analysisCount(), 0) << "the complex system shares the scalar analysis";
  EXPECT_EQ(systems.scalarSolver().factorizationCount(), 2);
  EXPECT_EQ(systems.vectorSolver().factorizationCount(), 2);
  EXPECT_TRUE(systems.vectorSolver().isFactorized());

  // A step size the systems were not factorized for is refused, state untouched.
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent.setConstant(1.0);
  state.solvent[0] = 5.0;
  const Vector before = state.solvent;
  EXPECT_EQ(diffuse(diffusionContext(0.01), g.intrinsic, systems, scratch, state).status,
            SolverStatus::NotFactorized);
  EXPECT_TRUE((state.solvent.array() == before.array()).all());
}

TEST(Diffusion, SwitchesAndEmptyFieldsAreSkippedAndAFailedSolveKeepsTheState) {
  const int n = 10;
  const LiquidMesh g(gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n));
  const double h = 0.01;
  DiffusionSystems systems;
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent = spot(g, Vector2(0.5, 0.5), 0.3, 1.0);
  state.velocities.setConstant(Complex(0.1, 0.0));
  const StainState original = state;

  // No solute: it stays exactly zero (skipped), solvent diffuses.
  ASSERT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
  EXPECT_TRUE((state.solute.array() == 0.0).all());
  EXPECT_FALSE((state.solvent.array() == original.solvent.array()).all());

  // Switched off: nothing changes, bit for bit.
  state = original;
  StepContext off = diffusionContext(h);
  off.switches.densityDiffusion = false;
  off.switches.velocityDiffusion = false;
  ASSERT_EQ(diffuse(off, g.intrinsic, systems, scratch, state).status, SolverStatus::Ok);
  EXPECT_TRUE((state.solvent.array() == original.solvent.array()).all());
  EXPECT_TRUE((state.velocities.array() == original.velocities.array()).all());

  // A non-finite solute: the solvent solve succeeds first, but nothing is committed.
  state = original;
  state.solute.setConstant(0.01);
  state.solute[7] = std::numeric_limits<double>::quiet_NaN();
  const StainState poisoned = state;
  EXPECT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, state).status,
            SolverStatus::NonFinite);
  EXPECT_TRUE((state.solvent.array() == poisoned.solvent.array()).all());
  EXPECT_TRUE((state.velocities.array() == poisoned.velocities.array()).all());
}

// The direct density solve takes solvent and solute in one pass over the
// factor: each field gets the bits it gets when it is the only one (the tail
// flush, the mass restoration and the limiter are per field).
// An n × n grid with the strong anisotropy of the limiter test above (the
// solves undershoot, so the limiter runs), its systems factorized for direct
// solves at h, and scratch for it.
struct DirectSolveGrid {
  DirectSolveGrid(int n, double h)
      : g(gridMesh(n, n, 1, 1), uniformFabric(2 * n * n, fabricTensor(1, 1e-6), fabricTensor(1, 1), kPi / 6)) {
    systems.setSolverChoice(DiffusionSolverChoice::Direct);
    status = systems.factorize(g.intrinsic, h);
    scratch.resize(g.vertexCount());
  }
  LiquidMesh g;
  DiffusionSystems systems;
  DiffusionScratch scratch;
  SolverStatus status = SolverStatus::Ok;
};

TEST(Diffusion, DirectSolveOfBothDensitiesGivesEachTheBitsOfItsOwnSolve) {
  const int n = 30;
  const double h = 10.0 / (n * n);
  DirectSolveGrid grid(n, h);
  ASSERT_EQ(grid.status, SolverStatus::Ok);
  const LiquidMesh& g = grid.g;
  DiffusionSystems& systems = grid.systems;
  DiffusionScratch& scratch = grid.scratch;
  StainState both = zeroState(g.vertexCount());
  both.solvent = spot(g, Vector2(0.5, 0.5), 0.15, 2.0);
  both.solute = spot(g, Vector2(0.4, 0.6), 0.2, 0.3);
  StainState solventOnly = both, soluteOnly = both;
  solventOnly.solute.setZero();
  soluteOnly.solvent.setZero();
  int corrected = 0;
  for (int step = 0; step < 5; ++step) {
    const DiffusionReport report = diffuse(diffusionContext(h), g.intrinsic, systems, scratch, both);
    ASSERT_EQ(report.status, SolverStatus::Ok);
    EXPECT_EQ(report.densityMethod, DiffusionMethod::Direct);
    corrected += report.limiterCorrectedVertices;
    ASSERT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, solventOnly).status, SolverStatus::Ok);
    ASSERT_EQ(diffuse(diffusionContext(h), g.intrinsic, systems, scratch, soluteOnly).status, SolverStatus::Ok);
    for (int i = 0; i < g.vertexCount(); ++i) {
      ASSERT_EQ(both.solvent[i], solventOnly.solvent[i]) << "step " << step << ", vertex " << i;
      ASSERT_EQ(both.solute[i], soluteOnly.solute[i]) << "step " << step << ", vertex " << i;
    }
  }
  EXPECT_GT(corrected, 0) << "the limiter must have run on both fields";
}

// The direct solve writes whole fields, but lists the vertices it (or the
// limiter after it) changed, and the solver backs up and rescans only those:
// every vertex whose solvent or solute changed, to the bit, or is nonzero
// must be listed, once, and on a mesh larger than the liquid's reach the
// list must be shorter than the mesh.
TEST(Diffusion, DirectDensitySolveListsEveryVertexItWrote) {
  const int n = 60;
  const double h = 0.5 / (n * n);
  DirectSolveGrid grid(n, h);
  ASSERT_EQ(grid.status, SolverStatus::Ok);
  const int vertices = grid.g.vertexCount();
  StainState state = zeroState(vertices);
  state.solvent = spot(grid.g, Vector2(0.5, 0.5), 0.08, 2.0);
  state.solute = spot(grid.g, Vector2(0.45, 0.55), 0.1, 0.3);
  const auto bits = [](double x) {
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
  };
  int corrected = 0;
  for (int step = 0; step < 4; ++step) {
    const StainState before = state;
    const DiffusionReport report = diffuse(diffusionContext(h), grid.g.intrinsic, grid.systems, grid.scratch, state);
    ASSERT_EQ(report.status, SolverStatus::Ok);
    ASSERT_EQ(report.densityMethod, DiffusionMethod::Direct);
    corrected += report.limiterCorrectedVertices;
    ASSERT_GT(report.directSupportVertices, 0);
    ASSERT_LT(report.directSupportVertices, vertices) << "step " << step;
    std::vector<int> listed(static_cast<size_t>(vertices), 0);
    for (int k = 0; k < report.directSupportVertices; ++k) ++listed[static_cast<size_t>(grid.scratch.directSupport[k])];
    for (int i = 0; i < vertices; ++i) {
      ASSERT_LE(listed[static_cast<size_t>(i)], 1) << "vertex " << i << " listed twice";
      const bool written = bits(state.solvent[i]) != bits(before.solvent[i]) ||
                           bits(state.solute[i]) != bits(before.solute[i]) || state.solvent[i] != 0.0 ||
                           state.solute[i] != 0.0;
      if (written) {
        ASSERT_EQ(listed[static_cast<size_t>(i)], 1) << "step " << step << ", vertex " << i;
      }
    }
    for (const char mark : grid.scratch.directMarks) ASSERT_EQ(mark, 0) << "marks are 0 between calls";
  }
  EXPECT_GT(corrected, 0) << "the limiter must have run (its writes are listed too)";
}

// --- Allocation ------------------------------------------------------------------------

// interact, applySources and the limiter allocate nothing; diffuse allocates
// nothing beyond what the CHOLMOD solves it calls do (measured separately:
// CHOLMOD 3.0.14's real simplicial cholmod_solve2 allocates and frees a 4 x n
// block on every call, which the solver wrapper cannot avoid; reported).
TEST(LiquidStages, StagesAllocateNothingOfTheirOwnAfterTheFirstCall) {
  if (!kCountsAllocations) GTEST_SKIP() << "allocations are not counted under AddressSanitizer";
  const int n = 30;
  const LiquidMesh g(gridMesh(n, n, 1, 1),
                     uniformFabric(2 * n * n, fabricTensor(1, 1e-6), fabricTensor(1, 0.1), kPi / 6));
  const double h = 0.01;
  DiffusionSystems systems;
  systems.setSolverChoice(DiffusionSolverChoice::Direct);  // the direct solves' own allocations are counted
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent = spot(g, Vector2(0.5, 0.5), 0.2, 5.0);
  state.solute = 0.1 * state.solvent;
  state.velocities.setConstant(Complex(0.1, 0.05));
  const std::vector<char> wet;  // all
  const std::vector<HeldRegion> regions = {HeldRegion{{0, 1, 2, 33}, 3.0, 0.2}};
  const StepContext ctx = diffusionContext(h);

  // What the three solves of one diffuse call allocate by themselves.
  Vector rhs = Vector::Ones(g.vertexCount()), x(g.vertexCount());
  ComplexVector complexRhs = ComplexVector::Ones(g.vertexCount()), complexX(g.vertexCount());
  systems.scalarSolver().solve(rhs, x);
  systems.vectorSolver().solve(complexRhs, complexX);
  allocationCount = 0;
  countAllocations = true;
  systems.scalarSolver().solve(rhs, x);
  const long perRealSolve = allocationCount.exchange(0);
  systems.vectorSolver().solve(complexRhs, complexX);
  const long perComplexSolve = allocationCount.exchange(0);
  countAllocations = false;
  std::printf("  CHOLMOD allocations per solve: real %ld, complex %ld\n", perRealSolve, perComplexSolve);

  diffuse(ctx, g.intrinsic, systems, scratch, state);  // first calls
  interact(ctx, g.topology, g.intrinsic, wet, state);
  applySources(ctx, regions, g.intrinsic, state);
  long inDiffuse = 0, inOthers = 0;
  int corrected = 0;
  for (int k = 0; k < 5; ++k) {
    allocationCount = 0;
    countAllocations = true;
    corrected += diffuse(ctx, g.intrinsic, systems, scratch, state).limiterCorrectedVertices;
    inDiffuse += allocationCount.exchange(0);
    interact(ctx, g.topology, g.intrinsic, wet, state);
    applySources(ctx, regions, g.intrinsic, state);
    countAllocations = false;
    inOthers += allocationCount.exchange(0);
  }
  Vector field = state.solvent;
  field[100] = -1.0;
  allocationCount = 0;
  countAllocations = true;
  limitPositivity(g.topology, g.areas(), field);
  countAllocations = false;
  EXPECT_EQ(allocationCount.load(), 0) << "limitPositivity";
  EXPECT_GT(corrected, 0) << "the limiter path must be exercised too";
  EXPECT_EQ(inDiffuse, 5 * (2 * perRealSolve + perComplexSolve)) << "diffuse beyond its solves";
  EXPECT_EQ(inOthers, 0) << "interact + applySources";
}

}  // namespace
}  // namespace blot::stain
