// The iterative path of the diffusion stage: Jacobi-PCG restricted to the
// liquid's Krylov support for the densities, symmetric Gauss–Seidel PCG on
// the wet region (the band) for the velocity, with the factorization as the
// fallback. What must
// hold whichever method runs: the same solution to the CG tolerance, mass to
// rounding, no negative density, bit-identical results for 1 and 2 threads.
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>
#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "same_bits.h"
#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;

StepContext context(double h, bool limiter = true) {
  PhysicsSwitches switches;
  switches.positivityLimiter = limiter;
  return makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
}

// The band's velocity solved exactly: (M + h L) restricted to the band's
// rows, the values of their neighbours outside it moved to the right-hand
// side, by a sparse LDLᴴ (Eigen's, independent of CHOLMOD and of the CG).
ComplexVector bandReference(const DiffusionSystems& systems, const Vector& areas, const ComplexVector& u0,
                            const std::vector<char>& band) {
  const ComplexSparseMatrix& A = systems.vectorSystem();
  const int n = static_cast<int>(A.rows());
  std::vector<int> place(static_cast<size_t>(n), -1);
  int rows = 0;
  for (int i = 0; i < n; ++i)
    if (band[static_cast<size_t>(i)]) place[static_cast<size_t>(i)] = rows++;
  std::vector<Eigen::Triplet<Complex>> entries;
  ComplexVector rhs(rows);
  for (int j = 0; j < n; ++j) {
    if (place[static_cast<size_t>(j)] < 0) continue;
    rhs[place[static_cast<size_t>(j)]] = areas[j] * u0[j];
  }
  for (int j = 0; j < n; ++j) {  // column j holds A(i, j)
    for (ComplexSparseMatrix::InnerIterator it(A, j); it; ++it) {
      const int i = static_cast<int>(it.row());
      if (place[static_cast<size_t>(i)] < 0) continue;
      if (place[static_cast<size_t>(j)] >= 0) {
        entries.emplace_back(place[static_cast<size_t>(i)], place[static_cast<size_t>(j)], it.value());
      } else {
        rhs[place[static_cast<size_t>(i)]] -= it.value() * u0[j];
      }
    }
  }
  ComplexSparseMatrix restricted(rows, rows);
  restricted.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<ComplexSparseMatrix> ldlt(restricted);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  const ComplexVector x = ldlt.solve(rhs);
  ComplexVector out = u0;
  for (int i = 0; i < n; ++i)
    if (place[static_cast<size_t>(i)] >= 0) out[i] = x[place[static_cast<size_t>(i)]];
  return out;
}

// max over the band of |u − reference| / max over the band of |reference|.
double bandError(const ComplexVector& u, const ComplexVector& reference, const std::vector<char>& band) {
  double error = 0.0, scale = 0.0;
  for (Eigen::Index i = 0; i < u.size(); ++i) {
    if (!band[static_cast<size_t>(i)]) continue;
    error = std::max(error, std::abs(u[i] - reference[i]));
    scale = std::max(scale, std::abs(reference[i]));
  }
  return error / scale;
}

// 60x60 grid, anisotropic (ratio 10, weft at 30°): D_weft = 1e-3 m²/s; at
// h = 0.05 s, h D / dx² ≈ 0.18 per direction (max h L_ii / A_i ≈ 0.4).
LiquidMesh anisotropicGrid() {
  const int n = 60;
  return LiquidMesh(gridMesh(n, n, 1, 1),
                    uniformFabric(2 * n * n, fabricTensor(1e-3, 1e-4), fabricTensor(1e-4, 1e-4), kPi / 6));
}

TEST(KrylovDiffusion, MatchesTheDirectSolveConservesMassAndStaysOnTheLiquid) {
  const LiquidMesh g = anisotropicGrid();
  const double h = 0.05;
  DiffusionSystems iterative, direct;
  iterative.setSolverChoice(DiffusionSolverChoice::Iterative);
  direct.setSolverChoice(DiffusionSolverChoice::Direct);
  ASSERT_EQ(iterative.factorize(g.intrinsic, h), SolverStatus::Ok);
  ASSERT_EQ(direct.factorize(g.intrinsic, h), SolverStatus::Ok);
  ASSERT_TRUE(iterative.scalarIterative() && iterative.vectorIterative());
  ASSERT_FALSE(direct.scalarIterative() || direct.vectorIterative());
  std::printf("  max h L_ii / A_i: density %.3f, velocity %.3f\n", iterative.scalarStiffnessRatio(),
              iterative.vectorStiffnessRatio());

  DiffusionScratch scratchA, scratchB;
  scratchA.resize(g.vertexCount());
  scratchB.resize(g.vertexCount());
  StainState a = zeroState(g.vertexCount());
  a.solvent = spot(g, Vector2(0.4, 0.5), 0.15, 2.0);
  a.solute = spot(g, Vector2(0.45, 0.5), 0.1, 0.3);
  for (int i = 0; i < g.vertexCount(); ++i)
    if (a.solvent[i] > 0) a.velocities[i] = Complex(0.1 * a.solvent[i], -0.05);
  StainState b = a;
  const double solvent0 = totalMass(g.areas(), a.solvent), solute0 = totalMass(g.areas(), a.solute);

  double worstDifference = 0, worstMass = 0, worstVelocity = 0;
  int iterations = 0;
  for (int step = 0; step < 20; ++step) {
    // Limiter off: it visits negative vertices in a different order for the
    // two methods (active list vs index order), which moves the undershoot's
    // mass differently; the solves themselves are compared here.
    const DiffusionReport ra = diffuse(context(h, false), g.intrinsic, iterative, scratchA, a);
    const DiffusionReport rb = diffuse(context(h, false), g.intrinsic, direct, scratchB, b);
    ASSERT_EQ(ra.status, SolverStatus::Ok);
    ASSERT_EQ(rb.status, SolverStatus::Ok);
    ASSERT_EQ(ra.densityMethod, DiffusionMethod::ConjugateGradient) << "step " << step;
    ASSERT_EQ(ra.velocityMethod, DiffusionMethod::ConjugateGradient) << "step " << step;
    EXPECT_EQ(rb.densityMethod, DiffusionMethod::Direct);
    EXPECT_EQ(ra.fallbacks, 0);
    iterations += ra.densityIterations;
    const double scale = b.solvent.cwiseAbs().maxCoeff();
    worstDifference = std::max({worstDifference, (a.solvent - b.solvent).cwiseAbs().maxCoeff() / scale,
                                (a.solute - b.solute).cwiseAbs().maxCoeff() / b.solute.cwiseAbs().maxCoeff()});
    worstVelocity = std::max(worstVelocity, (a.velocities - b.velocities).cwiseAbs().maxCoeff() /
                                                b.velocities.cwiseAbs().maxCoeff());
    worstMass = std::max({worstMass, std::abs(totalMass(g.areas(), a.solvent) - solvent0) / solvent0,
                          std::abs(totalMass(g.areas(), a.solute) - solute0) / solute0});
  }
  std::printf("  20 steps: CG iterations per step %.1f, max |CG − direct| / max: densities %.2e, velocity %.2e; "
              "mass error %.2e\n",
              iterations / 20.0, worstDifference, worstVelocity, worstMass);
  EXPECT_LE(worstDifference, 1e-7);  // CG tolerance 1e-9 in the residual, times κ, over 20 steps
  EXPECT_LE(worstVelocity, 1e-7);
  EXPECT_LE(worstMass, 1e-13);
  // Nothing was computed far from the liquid: the corner is exactly dry (the
  // direct solve leaves a tiny non-zero value there).
  EXPECT_EQ(a.solvent[0], 0.0);
  EXPECT_EQ(a.solute[0], 0.0);
}

TEST(KrylovDiffusion, AutoChoosesTheFactorForStiffSystemsAndTheSupportForMildOnes) {
  const LiquidMesh g = anisotropicGrid();
  DiffusionSystems systems;  // Auto
  ASSERT_EQ(systems.factorize(g.intrinsic, 0.05), SolverStatus::Ok);
  EXPECT_LE(systems.scalarStiffnessRatio(), kIterativeStiffnessRatio);
  EXPECT_TRUE(systems.scalarIterative());
  EXPECT_TRUE(systems.scalarCgAllowed());
  EXPECT_GT(systems.scalarStages(), 0);
  ASSERT_EQ(systems.factorize(g.intrinsic, 5.0), SolverStatus::Ok);  // h D / dx² ≈ 18
  EXPECT_GT(systems.scalarStiffnessRatio(), kIterativeStiffnessRatio);
  EXPECT_FALSE(systems.scalarIterative());

  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent = spot(g, Vector2(0.5, 0.5), 0.2, 1.0);
  const double mass = totalMass(g.areas(), state.solvent);
  const DiffusionReport r = diffuse(context(5.0), g.intrinsic, systems, scratch, state);
  ASSERT_EQ(r.status, SolverStatus::Ok);
  EXPECT_EQ(r.densityMethod, DiffusionMethod::Direct);
  EXPECT_EQ(r.densityIterations, 0);
  EXPECT_NEAR(totalMass(g.areas(), state.solvent), mass, 1e-13 * mass);
}

// The velocity on the band (a fixed domain): Auto lets CG compete with the
// factor up to kBandIterativeStiffnessRatio, and StainSolver charges the
// factor for the band over the whole mesh it needs. A small band is cheaper
// by CG, a band over the whole mesh by the factor; without a band (the
// support grows with the solve) the densities' ratio applies.
TEST(KrylovDiffusion, AutoSolvesAStiffVelocityOnASmallBandByCgAndOnTheWholeMeshByTheFactor) {
  const int n = 160;  // 25.6K vertices
  const LiquidMesh fine(gridMesh(n, n, 1, 1),
                        uniformFabric(2 * n * n, fabricTensor(1e-3, 1e-4), fabricTensor(1e-3, 1e-3), kPi / 6));
  DiffusionSystems systems;  // Auto
  ASSERT_EQ(systems.factorize(fine.intrinsic, 0.7), SolverStatus::Ok);
  EXPECT_GT(systems.vectorStiffnessRatio(), kIterativeStiffnessRatio);
  EXPECT_LE(systems.vectorStiffnessRatio(), kBandIterativeStiffnessRatio);
  EXPECT_GT(systems.assembledStep() * systems.vectorSpectralBound(), kRklAutoStepStiffness);
  EXPECT_TRUE(systems.vectorIterative());
  EXPECT_TRUE(systems.vectorCgAllowed());
  EXPECT_FALSE(systems.scalarIterative()) << "the densities keep the factor at this ratio";
  const int vertices = fine.vertexCount();
  std::vector<char> band(static_cast<size_t>(vertices), 0);
  int rows = 0;
  for (int i = 0; i < vertices; ++i) {
    if ((fine.position(i) - Vector3(0.5, 0.5, 0.0)).norm() < 0.1) {
      band[static_cast<size_t>(i)] = 1;
      ++rows;
    }
  }
  EXPECT_LT(velocityCostOnBand(systems, rows), velocityCostByFactor(systems, vertices - rows));
  EXPECT_GT(velocityCostOnBand(systems, vertices), velocityCostByFactor(systems, 0));

  DiffusionScratch scratch;
  scratch.resize(vertices);
  StainState state = zeroState(vertices);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  for (int i = 0; i < vertices; ++i) state.velocities[i] = Complex(normal(rng), normal(rng));
  const ComplexVector before = state.velocities;
  StainState onBand = state;
  const DiffusionReport r = diffuse(context(0.7), fine.intrinsic, systems, scratch, onBand, &band);
  ASSERT_EQ(r.status, SolverStatus::Ok);
  EXPECT_EQ(r.velocityMethod, DiffusionMethod::ConjugateGradient);
  EXPECT_GT(r.velocityIterations, 0);
  EXPECT_LE(r.velocityIterations, kMaxIterations);
  EXPECT_EQ(r.velocityActiveVertices, rows);
  // The symmetric Gauss–Seidel preconditioner on this stiff band (max h
  // L_ii / A_i ≈ 107): the restricted system's solution to 1e-7, in 34
  // iterations where Jacobi's needed 87 (and 34 → 16–17 on Table 1's bunny).
  const double error = bandError(onBand.velocities, bandReference(systems, fine.areas(), before, band), band);
  std::printf("  stiff band (%d rows, max h L_ii / A_i = %.1f): %d iterations, error %.2e\n", rows,
              systems.vectorStiffnessRatio(), r.velocityIterations, error);
  EXPECT_LT(error, 1e-7);
  EXPECT_LT(r.velocityIterations, 50);
  for (int i = 0; i < vertices; ++i) {
    if (!band[static_cast<size_t>(i)]) {
      ASSERT_EQ(onBand.velocities[i], before[i]) << i;
    }
  }
  StainState byFactor = state;
  const DiffusionReport f =
      diffuse(context(0.7), fine.intrinsic, systems, scratch, byFactor, &band, /*velocityByFactor=*/true);
  ASSERT_EQ(f.status, SolverStatus::Ok);
  EXPECT_EQ(f.velocityMethod, DiffusionMethod::Direct);
  StainState noBand = state;
  const DiffusionReport w = diffuse(context(0.7), fine.intrinsic, systems, scratch, noBand);
  ASSERT_EQ(w.status, SolverStatus::Ok);
  EXPECT_EQ(w.velocityMethod, DiffusionMethod::Direct) << "without a band the densities' ratio applies";
  EXPECT_TRUE(noBand.velocities == byFactor.velocities);
}

TEST(KrylovDiffusion, VelocityIsDiffusedOnTheWetRegionWithDryValuesFixed) {
  const LiquidMesh g = anisotropicGrid();
  const double h = 0.05;
  DiffusionSystems systems;
  systems.setSolverChoice(DiffusionSolverChoice::Iterative);
  ASSERT_EQ(systems.factorize(g.intrinsic, h), SolverStatus::Ok);
  ASSERT_TRUE(systems.vectorIterative());
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  for (int i = 0; i < g.vertexCount(); ++i) state.velocities[i] = Complex(normal(rng), normal(rng));
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  int wetCount = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    if (g.position(i).x() < 0.5) {
      wet[static_cast<size_t>(i)] = 1;
      ++wetCount;
    }
  }
  const ComplexVector before = state.velocities;
  const DiffusionReport r = diffuse(context(h), g.intrinsic, systems, scratch, state, &wet);
  ASSERT_EQ(r.status, SolverStatus::Ok);
  EXPECT_EQ(r.velocityMethod, DiffusionMethod::ConjugateGradient);
  EXPECT_EQ(r.velocityActiveVertices, wetCount);
  const double error = bandError(state.velocities, bandReference(systems, g.areas(), before, wet), wet);
  std::printf("  wet region: %d iterations, error against the restricted system's exact solution %.2e\n",
              r.velocityIterations, error);
  EXPECT_LT(error, 1e-8);
  EXPECT_LE(r.velocityIterations, 4);  // Jacobi's: 6
  double energyBefore = 0, energyAfter = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    if (wet[static_cast<size_t>(i)]) {
      energyBefore += g.areas()[i] * std::norm(before[i]);
      energyAfter += g.areas()[i] * std::norm(state.velocities[i]);
    } else {
      EXPECT_EQ(state.velocities[i], before[i]) << "dry vertex " << i << " must keep its velocity";
    }
  }
  std::printf("  wet-region velocity energy after one step: %.4f of before\n", energyAfter / energyBefore);
  EXPECT_LT(energyAfter, 0.9 * energyBefore);  // a rough field diffuses
}

// The whole step on a rotating n x n grid with a drop, every term on, CG on
// (max h L_ii / A_i ≈ 0.5 at n = 40).
StainState runRotatingDrop(int n, int threads, int steps, MassBudget* worst, double* lowest, long* cgIterations,
                           int* fewestCgRows = nullptr, double diffusivityScale = 1.0, double dropRadius = 0.3) {
  omp_set_num_threads(threads);
  const TriangleMesh mesh = gridMesh(n, n, 1, 1);
  const int faces = static_cast<int>(mesh.faces.rows());
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "krylov test grid");
  const double d = diffusivityScale;
  const FabricField fabric =
      uniformFabric(faces, fabricTensor(2e-3 * d, 2e-4 * d), fabricTensor(2e-4 * d, 2e-4 * d), kPi / 6);
  StainSolverDef def;
  def.diffusionSolver = DiffusionSolverChoice::Iterative;  // the CG path (Auto would take RKL2 here)
  StainSolver solver(topology, mesh.vertexPositions, fabric, def);
  const Vector3 center = mesh.vertexPositions.colwise().mean().transpose();
  const RowVectors3 centered = mesh.vertexPositions.rowwise() - center.transpose();
  const Vector3 axis = Vector3(0.3, 0.2, 1.0).normalized();
  const double omega = 1.5, h = 0.01;
  RowVectors3 velocities(centered.rows(), 3);
  for (Eigen::Index i = 0; i < centered.rows(); ++i)
    velocities.row(i) = (omega * axis).cross(Vector3(centered.row(i).transpose())).transpose();
  solver.setInitialMotion(mesh.vertexPositions, velocities);
  DropDef drop;
  drop.centerPoint = center;
  drop.radius = dropRadius;  // 0.3: ~1/4 of the area
  drop.solventMass = 0.02;
  drop.soluteMass = 0.002;
  drop.velocity = Vector3(0.05, 0.02, 0);
  solver.addDrop(drop);
  RowVectors3 next = mesh.vertexPositions;
  for (int step = 1; step <= steps; ++step) {
    const Matrix3 R = Eigen::AngleAxisd(omega * step * h, axis).toRotationMatrix();
    next.noalias() = centered * R.transpose();
    next.rowwise() += center.transpose();
    const StepReport report = solver.stepRigid(h, next, R);
    EXPECT_EQ(report.status, StepStatus::Ok) << report.stageName() << ": " << report.message;
    if (report.status != StepStatus::Ok) break;
    *cgIterations += solver.profile().diffusionIterations;
    if (fewestCgRows != nullptr) {  // [0] density, [1] velocity
      fewestCgRows[0] = std::min(fewestCgRows[0], solver.profile().densityDiffusionVertices);
      fewestCgRows[1] = std::min(fewestCgRows[1], solver.profile().velocityDiffusionVertices);
    }
    const MassBudget b = solver.massBudget();
    worst->freeSolvent = std::max(worst->freeSolvent, b.solventError());
    worst->freeSolute = std::max(worst->freeSolute, b.soluteError());
    const StainState& s = solver.state();
    const double scale = std::max(s.solvent.cwiseAbs().maxCoeff(), s.solute.cwiseAbs().maxCoeff());
    *lowest = std::min({*lowest, s.solvent.minCoeff() / scale, s.solute.minCoeff() / scale});
  }
  return solver.state();
}

// A drop on a 40 x 40 grid stretched along x by 0.3 % a step (past the strain
// tolerance, so the metric and the systems are rebuilt every step). The
// numeric factorization is lazy: with CG on both systems nothing is ever
// factorized; with direct solves each system is factorized once per assembly.
struct StretchedRun {
  int steps = 0, assemblies = 0, factorizations = 0, stepsWithFactorization = 0, cgSteps = 0;
  int densityDirectSteps = 0, velocityDirectSteps = 0;
  int velocitySolveSteps = 0;  // steps that solved u (by the factor or on the band)
  int directSteps = 0;         // steps with a direct solve of either system
};
StretchedRun runStretchedDrop(double diffusivityScale,
                              DiffusionSolverChoice choice = DiffusionSolverChoice::Auto) {
  const int n = 40;
  const TriangleMesh mesh = gridMesh(n, n, 1, 1);
  const int faces = static_cast<int>(mesh.faces.rows());
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "stretched grid");
  const double d = diffusivityScale;
  const FabricField fabric =
      uniformFabric(faces, fabricTensor(2e-3 * d, 2e-4 * d), fabricTensor(2e-4 * d, 2e-4 * d), kPi / 6);
  StainSolverDef def;
  def.diffusionSolver = choice;
  StainSolver solver(topology, mesh.vertexPositions, fabric, def);
  DropDef drop;
  drop.centerPoint = Vector3(0.5, 0.5, 0);
  drop.radius = 0.2;
  drop.solventMass = 0.02;
  drop.soluteMass = 0.002;
  drop.velocity = Vector3(0.05, 0.02, 0);
  solver.addDrop(drop);
  StretchedRun run;
  RowVectors3 next = mesh.vertexPositions;
  for (int step = 1; step <= 20; ++step) {
    next.col(0) = mesh.vertexPositions.col(0) * (1.0 + 0.003 * step);
    const StepReport report = solver.step(0.01, next);
    EXPECT_EQ(report.status, StepStatus::Ok) << report.stageName() << ": " << report.message;
    if (report.status != StepStatus::Ok) break;
    const StepProfile& p = solver.profile();
    ++run.steps;
    run.assemblies += p.ran(StepTerm::SystemAssembly);
    run.factorizations += p.factorizations;
    run.stepsWithFactorization += p.ran(StepTerm::Factorization);
    EXPECT_EQ(p.ran(StepTerm::Factorization), p.factorizations > 0);
    EXPECT_TRUE(p.factorizations == 0 || p.ran(StepTerm::SystemAssembly)) << "a factor only after new values";
    run.densityDirectSteps += p.ran(StepTerm::DensityDiffusionDirect);
    run.velocityDirectSteps += p.ran(StepTerm::VelocityDiffusionDirect);
    run.velocitySolveSteps += p.ran(StepTerm::VelocityDiffusionDirect) || p.ran(StepTerm::VelocityDiffusionKrylov);
    run.directSteps += p.ran(StepTerm::DensityDiffusionDirect) || p.ran(StepTerm::VelocityDiffusionDirect);
    run.cgSteps += p.ran(StepTerm::DensityDiffusionKrylov) && p.ran(StepTerm::VelocityDiffusionKrylov);
  }
  return run;
}

TEST(KrylovDiffusion, ACgOnlyRunFactorizesNothingAndADirectRunOncePerAssembly) {
  const StretchedRun cg = runStretchedDrop(1.0, DiffusionSolverChoice::Iterative);  // max h L_ii / A_i ≈ 0.5: CG
  EXPECT_EQ(cg.steps, 20);
  EXPECT_EQ(cg.assemblies, 20) << "the stretch must trip the strain test every step";
  EXPECT_EQ(cg.cgSteps, 20);
  EXPECT_EQ(cg.factorizations, 0);
  EXPECT_EQ(cg.stepsWithFactorization, 0);

  // Densities stiff (h λ past kRklAutoStepStiffness), velocity still mild
  // (Auto: RKL2 on the band): only the scalar system is factorized, once per
  // assembly that solves. The spread drop soaks in (14 steps of 20 hold
  // free liquid here): a step without free liquid solves nothing.
  const StretchedRun mixed = runStretchedDrop(400.0);
  EXPECT_EQ(mixed.assemblies, 20);
  EXPECT_GE(mixed.densityDirectSteps, 10);
  EXPECT_EQ(mixed.velocityDirectSteps, 0);
  EXPECT_EQ(mixed.factorizations, mixed.densityDirectSteps);
  EXPECT_EQ(mixed.stepsWithFactorization, mixed.directSteps);

  // Both stiff: one factor for each system that a step solves directly (the
  // free densities need no solve on some steps). The velocity takes the
  // factor on the steps whose band covers the mesh (3 and 4: the reach set
  // is the wet set's one ring, so on step 2 the band still leaves a ring
  // out); on the others (the free liquid spreading, then small again: the
  // fibres take it everywhere it spread, and none is free after step 7), CG
  // on the band is predicted cheaper than the factor and a band over the
  // whole mesh. (At 1000× the band's Gauss–Seidel CG is predicted cheaper
  // than the factor on every step: 3000×.)
  const StretchedRun direct = runStretchedDrop(3000.0);
  EXPECT_EQ(direct.steps, 20);
  EXPECT_EQ(direct.assemblies, 20);
  EXPECT_GT(direct.densityDirectSteps, 0);
  EXPECT_GE(direct.velocityDirectSteps, 2);
  EXPECT_GT(direct.velocitySolveSteps, direct.velocityDirectSteps) << "the first step solves u by CG on the band";
  EXPECT_EQ(direct.factorizations, direct.densityDirectSteps + direct.velocityDirectSteps)
      << "each system once per assembly that a direct solve used, never twice";
  EXPECT_EQ(direct.stepsWithFactorization, direct.directSteps);
}

TEST(KrylovDiffusion, StainStepConservesMassForAThousandSteps) {
  MassBudget worst;
  double lowest = 0;
  long iterations = 0;
  const int previous = omp_get_max_threads();
  runRotatingDrop(40, 1, 1000, &worst, &lowest, &iterations);
  omp_set_num_threads(previous);
  std::printf("  1000 steps: CG iterations per step %.1f; worst solvent error %.2e, solute %.2e; min %.2e of max\n",
              iterations / 1000.0, worst.freeSolvent, worst.freeSolute, lowest);
  // The drop soaks in: once no vertex holds free liquid above the wet
  // threshold, a step moves nothing and solves nothing (419 iterations in
  // all when measured).
  EXPECT_GT(iterations, 200) << "the CG path should have run";
  EXPECT_LE(worst.freeSolvent, 1e-12);
  EXPECT_LE(worst.freeSolute, 1e-12);
  EXPECT_GE(lowest, -1e-12);
}

TEST(KrylovDiffusion, StainStepIsBitIdenticalForOneAndTwoThreads) {
  // 5,041 vertices, a quarter wet: the geometry refresh runs in parallel; the
  // CG's active rows (~1,500-2,500) stay below kKrylovParallelRows.
  MassBudget worst1, worst2;
  double lowest1 = 0, lowest2 = 0;
  long iterations1 = 0, iterations2 = 0;
  const int previous = omp_get_max_threads();
  const StainState one = runRotatingDrop(70, 1, 40, &worst1, &lowest1, &iterations1);
  const StainState two = runRotatingDrop(70, 2, 40, &worst2, &lowest2, &iterations2);
  omp_set_num_threads(previous);
  EXPECT_GT(iterations1, 40);
  EXPECT_EQ(iterations1, iterations2);
  EXPECT_TRUE(testing::sameBits(one, two));
}

TEST(KrylovDiffusion, ThreadedCgIsBitIdenticalForOneAndTwoThreads) {
  // 22,801 vertices, a drop over almost all of the sheet, diffusivities / 10
  // (max h L_ii / A_i ≈ 0.7, so Auto picks CG): every step's density and
  // velocity CG runs on more than kKrylovParallelRows active rows (4 steps:
  // absorption then shrinks the free liquid's support), so with two
  // threads its chunks run in parallel; the chunked sums must give the
  // one-thread bits.
  MassBudget worst1, worst2;
  double lowest1 = 0, lowest2 = 0;
  long iterations1 = 0, iterations2 = 0;
  int rows1[2] = {1 << 30, 1 << 30}, rows2[2] = {1 << 30, 1 << 30};
  const int previous = omp_get_max_threads();
  const StainState one = runRotatingDrop(151, 1, 4, &worst1, &lowest1, &iterations1, rows1, 0.1, 0.7);
  const StainState two = runRotatingDrop(151, 2, 4, &worst2, &lowest2, &iterations2, rows2, 0.1, 0.7);
  omp_set_num_threads(previous);
  std::printf("  fewest CG rows in a step: density %d, velocity %d (threaded from %d); CG iterations %ld\n", rows1[0],
              rows1[1], kKrylovParallelRows, iterations1);
  EXPECT_GE(rows1[0], kKrylovParallelRows) << "the threaded density CG must run on every step";
  EXPECT_GE(rows1[1], kKrylovParallelRows) << "the threaded velocity CG must run on every step";
  EXPECT_EQ(rows1[0], rows2[0]);
  EXPECT_EQ(rows1[1], rows2[1]);
  EXPECT_GT(iterations1, 4);
  EXPECT_EQ(iterations1, iterations2);
  EXPECT_LE(worst1.freeSolvent, 1e-12);
  EXPECT_LE(worst1.freeSolute, 1e-12);
  EXPECT_TRUE(testing::sameBits(one, two));
}

}  // namespace
}  // namespace blot::stain
