// Explicit super-time-stepping of the diffusion (RKL2, stain/src/numerics/
// super_time_stepping.h) and the per-solve method choice of diffuse():
// the stability polynomial and its interval, second order in time against
// the exact solution of the semi-discrete equation M σ' = −L σ (dense
// eigen-decomposition), stability at and beyond the stated limit, the band
// restriction against a whole-mesh RKL2 step, mass to rounding, positivity
// with the limiter, bit-identical results for 1 and 2 threads, no allocation
// per step, and what Auto chooses.
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "allocation_counter.h"  // counts malloc/calloc/realloc while gCountAllocations is set
#include "numerics/compensated_sum.h"
#include "numerics/super_time_stepping.h"
#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;
using namespace diffusion_internal;

StepContext context(double h, bool limiter) {
  PhysicsSwitches switches;
  switches.positivityLimiter = limiter;
  switches.velocityDiffusion = false;
  return makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
}

// n x n cells on the unit square, anisotropic (ratio 10, weft at 30°), D_weft = `weft` m²/s.
LiquidMesh anisotropicGrid(int n, double weft) {
  return LiquidMesh(gridMesh(n, n, 1, 1), uniformFabric(2 * n * n, fabricTensor(weft, 0.1 * weft),
                                                        fabricTensor(0.1 * weft, 0.1 * weft), kPi / 6));
}

// R_s(z): the RKL2 recursion applied to the scalar equation y' = λy, z = τλ.
double amplification(int s, double z) {
  double y0 = 1.0, g0 = z, previous2 = 1.0;
  double previous = y0 + rkl2Coefficients(s, 1).muTilde * g0;
  for (int j = 2; j <= s; ++j) {
    const Rkl2Stage c = rkl2Coefficients(s, j);
    const double next = c.mu * previous + c.nu * previous2 + (1 - c.mu - c.nu) * y0 + c.muTilde * z * previous +
                        c.gammaTilde * g0;
    previous2 = previous;
    previous = next;
  }
  return previous;
}

TEST(SuperTimeStepping, StabilityPolynomialIsSecondOrderAndBoundedOnItsInterval) {
  for (int s : {2, 3, 4, 7, 16, 40, kMaxRklStages}) {
    const double limit = 0.5 * (s * s + s - 2);
    double worst = 0;
    for (int k = 0; k <= 20000; ++k) worst = std::max(worst, std::abs(amplification(s, -limit * k / 20000.0)));
    EXPECT_LE(worst, 1.0 + 1e-12) << "s = " << s;
    // Second order: R(z) − e^z = O(z³).
    for (double z : {-1e-2, -1e-3}) {
      EXPECT_LE(std::abs(amplification(s, z) - std::exp(z)), 2.0 * s * s * std::abs(z * z * z)) << s << " " << z;
      EXPECT_GT(std::abs(amplification(s, z) - (1 + z)), 0.4 * z * z) << "not first order only";
    }
    // Past the interval it grows: at once for even s (R = 1 at the end of the
    // interval), within a quarter of it for odd s (R = 1 − 2b_s there).
    EXPECT_GT(std::abs(amplification(s, -limit * (s % 2 == 0 ? 1.02 : 1.25))), 1.0) << "s = " << s;
    // The chosen stage count covers τλ and one fewer would not.
    const int chosen = rkl2Stages(limit * 0.999);
    EXPECT_EQ(chosen, s <= kMaxRklStages ? s : 0);
  }
  EXPECT_EQ(rkl2Stages(0.0), 2);
  EXPECT_EQ(rkl2Stages(1e9), 0);
  EXPECT_EQ(rkl2Stages(std::nan("")), 0);
}

// The exact solution of M σ' = −L σ from a dense generalized eigen-decomposition
// (L V = M V Λ, Vᵀ M V = I): σ(t) = V e^{−Λt} Vᵀ M σ0.
struct ExactSemiDiscrete {
  Eigen::MatrixXd vectors;
  Eigen::VectorXd values;
  Vector areas;
  explicit ExactSemiDiscrete(const LiquidMesh& g) : areas(g.areas()) {
    const Eigen::MatrixXd L = Eigen::MatrixXd(g.intrinsic.densityStiffness);
    const Eigen::MatrixXd M = g.areas().asDiagonal();
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> solver(L, M);
    vectors = solver.eigenvectors();
    values = solver.eigenvalues();
  }
  Vector at(const Vector& sigma0, double t) const {
    const Eigen::VectorXd coefficients = vectors.transpose() * areas.cwiseProduct(sigma0);
    return vectors * ((-values * t).array().exp().matrix().cwiseProduct(coefficients));
  }
  double largest() const { return values.maxCoeff(); }
};

double massNorm(const Vector& areas, const Vector& v) { return std::sqrt(areas.dot(v.cwiseAbs2())); }

// The complex bound's vector square roots (two entries at a time) give the
// scalar loop's bits: random complex patterns whose columns hold 0 to 9
// entries (odd and even counts, so the pairs' tail runs too), moduli from
// 1e-3 to 1e3, compressed and not.
TEST(SuperTimeStepping, ComplexBoundIsBitwiseTheScalarSum) {
  std::mt19937 random(11);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::uniform_int_distribution<int> count(0, 9);
  const int n = 400;
  std::vector<Eigen::Triplet<Complex>> entries;
  for (int j = 0; j < n; ++j) {
    const int k = count(random);
    for (int m = 0; m < k; ++m) {
      const double scale = std::pow(10.0, 3.0 * uniform(random));
      entries.emplace_back((j + 37 * m) % n, j, Complex(scale * uniform(random), scale * uniform(random)));
    }
  }
  ComplexSparseMatrix L(n, n);
  L.setFromTriplets(entries.begin(), entries.end());
  Vector areas(n);
  for (int i = 0; i < n; ++i) areas[i] = 1e-4 * (1.5 + uniform(random));
  const auto scalarBound = [&](const ComplexSparseMatrix& A) {
    double bound = 0.0;
    for (int j = 0; j < n; ++j) {
      double sum = 0.0;
      for (ComplexSparseMatrix::InnerIterator it(A, j); it; ++it)
        sum += std::sqrt(it.value().real() * it.value().real() + it.value().imag() * it.value().imag());
      bound = std::max(bound, sum / areas[j]);
    }
    return bound;
  };
  int sumsChecked = 0;
  for (const bool compressed : {true, false}) {
    ComplexSparseMatrix A = L;
    if (!compressed) A.uncompress();
    const double expected = scalarBound(A), got = spectralBound(A, areas);
    EXPECT_EQ(std::memcmp(&expected, &got, sizeof(double)), 0) << std::hexfloat << got << " vs " << expected;
    // Every column, not only the largest: the sums themselves.
    for (int j = 0; j < n; ++j) {
      const int begin = A.outerIndexPtr()[j];
      const int end = compressed ? A.outerIndexPtr()[j + 1] : begin + A.innerNonZeroPtr()[j];
      double reference = 0.0;
      for (int p = begin; p < end; ++p) reference += boundModulus(A.valuePtr()[p]);
      const double sum = columnModulusSum(A.valuePtr(), begin, end);
      ASSERT_EQ(std::memcmp(&reference, &sum, sizeof(double)), 0) << "column " << j;
      ++sumsChecked;
    }
  }
  EXPECT_EQ(sumsChecked, 2 * n);
}

// The diffusion stage's mass sums skip the zeros of a mostly dry mesh
// (stages/diffusion.cpp): a zero of either sign added to a CompensatedSum
// must change no bit, including after the sum cancelled to exactly zero.
TEST(CompensatedSum, ZerosOfEitherSignChangeNoBit) {
  std::mt19937_64 random(51);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-40, 40);
  const auto bits = [](double x) {
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
  };
  for (int trial = 0; trial < 200; ++trial) {
    CompensatedSum withZeros, without;
    std::vector<double> added;
    for (int k = 0; k < 400; ++k) {
      double x = std::ldexp(mantissa(random), exponent(random));
      // Now and then the negation of a term already added: exact
      // cancellations, so the running sum passes through exactly zero.
      if (k % 7 == 3 && !added.empty()) x = -added[static_cast<size_t>(k) % added.size()];
      added.push_back(x);
      withZeros.add(x);
      without.add(x);
      withZeros.add(k % 2 == 0 ? 0.0 : -0.0);
      ASSERT_EQ(bits(withZeros.value()), bits(without.value())) << "trial " << trial << ", term " << k;
    }
    // A sum of zeros only is +0, as the empty sum.
    CompensatedSum zeros;
    zeros.add(-0.0);
    zeros.add(0.0);
    zeros.add(-0.0);
    EXPECT_EQ(bits(zeros.value()), bits(CompensatedSum().value()));
  }
}

TEST(SuperTimeStepping, SecondOrderInTimeAgainstTheExactSemiDiscreteSolution) {
  // 14 x 14 grid, D_weft = 0.01 m²/s (λ_max(M⁻¹L) ≈ 10 /s, the slowest
  // modes decay at ~0.02–0.1 /s); T = 20 s is ~100 forward-Euler limits: the
  // coarsest run takes 2 steps of 14 stages, the finest 64 of 3.
  const LiquidMesh g = anisotropicGrid(14, 0.01);
  const ExactSemiDiscrete exact(g);
  const double T = 20.0;
  StainState initial = zeroState(g.vertexCount());
  initial.solvent = spot(g, Vector2(0.45, 0.5), 0.35, 1.0);
  initial.solute = spot(g, Vector2(0.55, 0.5), 0.3, 0.2);
  const Vector reference = exact.at(initial.solvent, T), referenceSolute = exact.at(initial.solute, T);
  std::printf("  lambda_max(M^-1 L) %.4g /s, Gershgorin bound %.4g /s\n", exact.largest(),
              spectralBound(g.intrinsic.densityStiffness, g.areas()));

  const auto error = [&](const StainState& state) {
    return std::max(massNorm(g.areas(), state.solvent - reference) / massNorm(g.areas(), reference),
                    massNorm(g.areas(), state.solute - referenceSolute) / massNorm(g.areas(), referenceSolute));
  };
  // (1) Through diffuse(), the stage count chosen per h, against backward Euler.
  std::vector<double> rklErrors, eulerErrors, tauLambda;
  for (int steps : {2, 4, 8, 16, 32, 64}) {
    const double h = T / steps;
    double errors[2];
    int stages = 0;
    for (DiffusionSolverChoice choice : {DiffusionSolverChoice::SuperTimeStepping, DiffusionSolverChoice::Direct}) {
      DiffusionSystems systems;
      systems.setSolverChoice(choice);
      ASSERT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
      DiffusionScratch scratch;
      scratch.resize(g.vertexCount());
      StainState state = initial;
      for (int k = 0; k < steps; ++k) {
        const DiffusionReport r = diffuse(context(h, false), g.intrinsic, systems, scratch, state);
        ASSERT_EQ(r.status, SolverStatus::Ok);
        if (choice == DiffusionSolverChoice::SuperTimeStepping) {
          ASSERT_EQ(r.densityMethod, DiffusionMethod::SuperTimeStepping);
          stages = r.densityStages;
        }
      }
      errors[choice == DiffusionSolverChoice::Direct] = error(state);
    }
    std::printf("  %2d steps (h lambda_max %5.1f): RKL2 (%2d stages) error %.3e, backward Euler %.3e\n", steps,
                h * exact.largest(), stages, errors[0], errors[1]);
    rklErrors.push_back(errors[0]);
    eulerErrors.push_back(errors[1]);
    tauLambda.push_back(h * exact.largest());
  }
  for (size_t k = 1; k < rklErrors.size(); ++k) {
    // Where h λ_max ≤ 20 (≤ 6 stages) the second-order scheme is the more
    // accurate; further into the super-time-stepping range its weakly damped
    // stiff modes (|R| up to ~1 − 2b_s ... 1, where backward Euler gives
    // 1/(1 + hλ)) make it the less accurate (asserted: docs/accuracy.md).
    if (tauLambda[k] <= 20) {
      EXPECT_LT(rklErrors[k], eulerErrors[k]) << "second order beats backward Euler at h lambda " << tauLambda[k];
    }
    if (tauLambda[k] >= 50) {
      EXPECT_GT(rklErrors[k], eulerErrors[k]) << "h lambda " << tauLambda[k];
    }
    EXPECT_GE(std::log2(eulerErrors[k - 1] / eulerErrors[k]), 0.9);
  }
  // (2) The order of one fixed scheme (s = 14 stages, stable for every h
  // here): second order in h.
  const int n = g.vertexCount();
  std::vector<int> list(static_cast<size_t>(n));
  std::vector<char> marks(static_cast<size_t>(n));
  std::vector<double> partials(static_cast<size_t>((n + kKrylovChunkRows - 1) / kKrylovChunkRows) *
                               kKrylovPartialsPerChunk);
  std::vector<double> fixedErrors;
  for (int steps : {4, 8, 16, 32, 64}) {
    const double h = T / steps;
    const int s = 14;
    ASSERT_LE(h * spectralBound(g.intrinsic.densityStiffness, g.areas()), 0.5 * (s * s + s - 2));
    Vector y = Vector::Zero(2 * n), w = Vector::Zero(2 * n), g0 = Vector::Zero(2 * n);
    StainState state = initial;
    for (int k = 0; k < steps; ++k) {
      ActiveSet active(list, marks);
      for (int i = 0; i < n; ++i) active.add(i);
      const double* x0[2] = {state.solvent.data(), state.solute.data()};
      double mass[2];
      ASSERT_TRUE(rkl2Step<false>(g.intrinsic.densityStiffness, g.areas().data(), x0, 1, s, h, y.data(), w.data(),
                                  g0.data(), active, false, mass, partials.data())
                      .finite);
      for (int i = 0; i < n; ++i) {
        state.solvent[i] = y[2 * i];
        state.solute[i] = y[2 * i + 1];
      }
      active.clearMarks();
    }
    fixedErrors.push_back(error(state));
  }
  for (size_t k = 1; k < fixedErrors.size(); ++k) {
    const double order = std::log2(fixedErrors[k - 1] / fixedErrors[k]);
    std::printf("  fixed s = 14, %d -> %d steps: error %.3e -> %.3e, order %.2f\n", 2 << k, 4 << k,
                fixedErrors[k - 1], fixedErrors[k], order);
    if (k >= 3) {  // before, the stiff modes' damping dominates (order 4–5)
      EXPECT_GE(order, 1.9) << "RKL2 must converge at second order in h";
      EXPECT_LE(order, 2.2);
    }
  }
}

TEST(SuperTimeStepping, StableAtTheChosenStageCountAndUnstableBeyond) {
  // The stiffest mode of M⁻¹L, stepped at exactly its stability limit with
  // s stages (τ λ_max = (s² + s − 2)/2), does not grow; with s − 1 stages
  // it grows geometrically.
  const LiquidMesh g = anisotropicGrid(12, 0.01);
  const ExactSemiDiscrete exact(g);
  Eigen::Index top;
  exact.values.maxCoeff(&top);
  const Vector mode = exact.vectors.col(top);
  const int n = g.vertexCount();
  std::vector<int> list(static_cast<size_t>(n));
  std::vector<char> marks(static_cast<size_t>(n));
  std::vector<double> partials(static_cast<size_t>((n + kKrylovChunkRows - 1) / kKrylovChunkRows) *
                               kKrylovPartialsPerChunk);
  for (int s : {3, 8, 20}) {
    const double tau = 0.5 * (s * s + s - 2) / exact.largest();
    for (int stages : {s, s - 1}) {
      Vector field = mode, zero = Vector::Zero(n);
      Vector y = Vector::Zero(2 * n), w = Vector::Zero(2 * n), g0 = Vector::Zero(2 * n);
      double growth = 1.0;
      for (int step = 0; step < 30; ++step) {
        ActiveSet active(list, marks);
        for (int i = 0; i < n; ++i) active.add(i);  // the whole mesh, a fixed domain
        const double* x0[2] = {field.data(), zero.data()};
        double mass[2];
        const RklOutcome outcome = rkl2Step<false>(g.intrinsic.densityStiffness, g.areas().data(), x0, 1, stages, tau,
                                                   y.data(), w.data(), g0.data(), active, false, mass, partials.data());
        ASSERT_TRUE(outcome.finite);
        const double before = massNorm(g.areas(), field);
        for (int i = 0; i < n; ++i) field[i] = y[2 * i];
        growth *= massNorm(g.areas(), field) / before;
        active.clearMarks();
      }
      std::printf("  s = %2d at tau lambda_max = %.0f, %2d stages: growth over 30 steps %.3e\n", s, tau * exact.largest(),
                  stages, growth);
      if (stages == s) {
        EXPECT_LE(growth, 1.0 + 1e-9);
      } else {
        EXPECT_GT(growth, 10.0) << "one stage fewer must be unstable";
      }
    }
  }
  // The Gershgorin bound is above λ_max, so the automatic count is stable.
  EXPECT_GE(spectralBound(g.intrinsic.densityStiffness, g.areas()), exact.largest() * (1 - 1e-12));
}

// One whole-mesh RKL2 step written the plain way (Eigen vectors), the reference
// for the band-restricted one.
Vector wholeMeshRkl2(const SparseMatrix& L, const Vector& areas, const Vector& u0, int s, double tau) {
  const auto F = [&](const Vector& v) -> Vector { return -tau * (L * v).cwiseQuotient(areas); };
  const Vector g0 = F(u0);
  Vector previous2 = u0, previous = u0 + rkl2Coefficients(s, 1).muTilde * g0;
  for (int j = 2; j <= s; ++j) {
    const Rkl2Stage c = rkl2Coefficients(s, j);
    const Vector next =
        c.mu * previous + c.nu * previous2 + (1 - c.mu - c.nu) * u0 + c.muTilde * F(previous) + c.gammaTilde * g0;
    previous2 = previous;
    previous = next;
  }
  return previous;
}

TEST(SuperTimeStepping, OnTheBandItIsTheWholeMeshStepConservesMassAndStaysPositive) {
  // 60 x 60 grid, a small top-hat stain (a sharp edge: the scheme undershoots
  // and the limiter must act), h = 1/60 s with D_weft = 0.05 m²/s (max
  // h L_ii / A_i ≈ 4, the CG threshold).
  const LiquidMesh g = anisotropicGrid(60, 0.05);
  const double h = 1.0 / 60;
  DiffusionSystems systems;
  systems.setSolverChoice(DiffusionSolverChoice::SuperTimeStepping);
  ASSERT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
  const int s = systems.scalarStages();
  ASSERT_GT(s, 2);
  DiffusionScratch scratch, scratchFree;
  scratch.resize(g.vertexCount());
  scratchFree.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount()), free = zeroState(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) {
    if ((g.position(i).head<2>() - Vector2(0.4, 0.55)).norm() < 0.08) state.solvent[i] = 1.0;
    if ((g.position(i).head<2>() - Vector2(0.42, 0.55)).norm() < 0.05) state.solute[i] = 0.1;
  }
  free = state;
  const double solvent0 = totalMass(g.areas(), state.solvent), solute0 = totalMass(g.areas(), state.solute);

  // One step without the limiter against the whole-mesh reference.
  const Vector reference = wholeMeshRkl2(g.intrinsic.densityStiffness, g.areas(), free.solvent, s, h);
  const DiffusionReport first = diffuse(context(h, false), g.intrinsic, systems, scratchFree, free);
  ASSERT_EQ(first.status, SolverStatus::Ok);
  ASSERT_EQ(first.densityMethod, DiffusionMethod::SuperTimeStepping);
  const double difference = (free.solvent - reference).cwiseAbs().maxCoeff() / reference.cwiseAbs().maxCoeff();
  std::printf("  %d stages on %d of %d rows; |band − whole mesh| / max = %.2e; min before limiter %.3e\n", s,
              first.densityActiveVertices, g.vertexCount(), difference, first.minDensityBeforeLimiter);
  EXPECT_LE(difference, 2e-9);  // the flush of values below 1e-9 × max, then the mass rescale
  EXPECT_LT(first.densityActiveVertices, g.vertexCount() / 4);
  EXPECT_EQ(free.solvent[0], 0.0) << "nothing was computed far from the liquid";
  EXPECT_LT(first.minDensityBeforeLimiter, 0.0) << "the sharp edge must undershoot (else the limiter is untested)";

  double worstMass = 0;
  int limited = 0;
  for (int step = 0; step < 100; ++step) {
    const DiffusionReport r = diffuse(context(h, true), g.intrinsic, systems, scratch, state);
    ASSERT_EQ(r.status, SolverStatus::Ok);
    limited += r.limiterCorrectedVertices;
    ASSERT_GE(state.solvent.minCoeff(), 0.0) << "step " << step;
    ASSERT_GE(state.solute.minCoeff(), 0.0) << "step " << step;
    worstMass = std::max({worstMass, std::abs(totalMass(g.areas(), state.solvent) - solvent0) / solvent0,
                          std::abs(totalMass(g.areas(), state.solute) - solute0) / solute0});
  }
  std::printf("  100 steps: worst relative mass error %.2e, limiter corrections %d\n", worstMass, limited);
  EXPECT_LE(worstMass, 1e-13);
  EXPECT_GT(limited, 0);
}

TEST(SuperTimeStepping, VelocityOnTheWetRegionKeepsTheBoundaryValues) {
  const LiquidMesh g = anisotropicGrid(40, 0.5);  // viscosity 0.05 m²/s
  const double h = 1.0 / 60;
  DiffusionSystems systems;
  systems.setSolverChoice(DiffusionSolverChoice::SuperTimeStepping);
  ASSERT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
  ASSERT_TRUE(systems.vectorIterative());
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  int wetCount = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Vector3 p = g.position(i);
    state.velocities[i] = Complex(std::sin(3 * p.x()) + 0.3 * std::cos(2 * p.y()), std::cos(2 * p.x() * p.y()));
    if (p.x() < 0.5) {
      wet[static_cast<size_t>(i)] = 1;
      ++wetCount;
    }
  }
  const ComplexVector before = state.velocities;
  PhysicsSwitches switches;
  switches.densityDiffusion = false;
  const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
  const DiffusionReport r = diffuse(ctx, g.intrinsic, systems, scratch, state, &wet);
  ASSERT_EQ(r.status, SolverStatus::Ok);
  EXPECT_EQ(r.velocityMethod, DiffusionMethod::SuperTimeStepping);
  EXPECT_EQ(r.velocityActiveVertices, wetCount);
  EXPECT_GT(r.velocityStages, 2);
  double energyBefore = 0, energyAfter = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    if (wet[static_cast<size_t>(i)]) {
      energyBefore += g.areas()[i] * std::norm(before[i]);
      energyAfter += g.areas()[i] * std::norm(state.velocities[i]);
    } else {
      ASSERT_EQ(state.velocities[i], before[i]) << "dry vertex " << i << " must keep its velocity";
    }
  }
  std::printf("  wet-region velocity energy after one RKL2 step (%d stages): %.4f of before\n", r.velocityStages,
              energyAfter / energyBefore);
  EXPECT_LT(energyAfter, energyBefore);
  // Against an independent whole-mesh RKL2 step whose rows outside the wet
  // region are reset to their initial values after every stage (Dirichlet
  // data; the velocity lives in per-vertex frames, so the rows are compared
  // as they are stored).
  const ComplexSparseMatrix& L = g.intrinsic.velocityStiffness;
  const int s = r.velocityStages;
  const auto F = [&](const ComplexVector& v) -> ComplexVector {
    ComplexVector out = L.adjoint() * v;  // row i: Σ conj(L_ji) v_j (L is Hermitian)
    for (int i = 0; i < g.vertexCount(); ++i) out[i] *= -h / g.areas()[i];
    return out;
  };
  const auto clamp = [&](ComplexVector& v) {
    for (int i = 0; i < g.vertexCount(); ++i)
      if (!wet[static_cast<size_t>(i)]) v[i] = before[i];
  };
  const ComplexVector g0 = F(before);
  ComplexVector previous2 = before, previous = before + rkl2Coefficients(s, 1).muTilde * g0;
  clamp(previous);
  for (int j = 2; j <= s; ++j) {
    const Rkl2Stage c = rkl2Coefficients(s, j);
    ComplexVector next =
        c.mu * previous + c.nu * previous2 + (1 - c.mu - c.nu) * before + c.muTilde * F(previous) + c.gammaTilde * g0;
    clamp(next);
    previous2 = previous;
    previous = next;
  }
  const double gap = (previous - state.velocities).cwiseAbs().maxCoeff() / before.cwiseAbs().maxCoeff();
  std::printf("  max |band RKL2 − whole-mesh RKL2 with Dirichlet rows| / max |u|: %.3e\n", gap);
  EXPECT_LT(gap, 1e-13);
}

StainState runThreaded(int threads, int steps) {
  omp_set_num_threads(threads);
  // 151 x 151 = 22,801 vertices, a stain over most of it: the active rows
  // pass kKrylovParallelRows, so the stages' row loops run threaded.
  const LiquidMesh g = anisotropicGrid(151, 2e-4);
  DiffusionSystems systems;
  systems.setSolverChoice(DiffusionSolverChoice::SuperTimeStepping);
  EXPECT_EQ(systems.assemble(g.intrinsic, 1.0 / 60), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent = spot(g, Vector2(0.5, 0.5), 0.5, 1.0);
  for (int i = 0; i < g.vertexCount(); ++i)
    if ((g.position(i).head<2>() - Vector2(0.5, 0.5)).norm() < 0.3) state.solute[i] = 0.2;
  for (int step = 0; step < steps; ++step) {
    const DiffusionReport r = diffuse(context(1.0 / 60, true), g.intrinsic, systems, scratch, state);
    EXPECT_EQ(r.status, SolverStatus::Ok);
    EXPECT_EQ(r.densityMethod, DiffusionMethod::SuperTimeStepping);
    EXPECT_GE(r.densityActiveVertices, kKrylovParallelRows);
  }
  return state;
}

TEST(SuperTimeStepping, BitIdenticalForOneAndTwoThreads) {
  const int previous = omp_get_max_threads();
  const StainState one = runThreaded(1, 3);
  const StainState two = runThreaded(2, 3);
  omp_set_num_threads(previous);
  EXPECT_TRUE((one.solvent.array() == two.solvent.array()).all());
  EXPECT_TRUE((one.solute.array() == two.solute.array()).all());
}

TEST(SuperTimeStepping, AStepAllocatesNothing) {
  if (!kCountsAllocations) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const LiquidMesh g = anisotropicGrid(40, 2e-3);
  const double h = 1.0 / 60;
  DiffusionSystems systems;  // Auto: RKL2 for both on this mild grid
  ASSERT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent = spot(g, Vector2(0.5, 0.5), 0.2, 1.0);
  for (int i = 0; i < g.vertexCount(); ++i)
    if (state.solvent[i] > 0) state.velocities[i] = Complex(0.1, -0.05 * state.solvent[i]);
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  for (int i = 0; i < g.vertexCount(); ++i) wet[static_cast<size_t>(i)] = state.solvent[i] > 0;
  PhysicsSwitches switches;
  const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
  DiffusionReport r = diffuse(ctx, g.intrinsic, systems, scratch, state, &wet);
  ASSERT_EQ(r.status, SolverStatus::Ok);
  ASSERT_EQ(r.densityMethod, DiffusionMethod::SuperTimeStepping);
  ASSERT_EQ(r.velocityMethod, DiffusionMethod::SuperTimeStepping);
  gAllocations = 0;
  gCountAllocations = true;
  for (int step = 0; step < 5; ++step) r = diffuse(ctx, g.intrinsic, systems, scratch, state, &wet);
  gCountAllocations = false;
  ASSERT_EQ(r.status, SolverStatus::Ok);
  EXPECT_EQ(gAllocations.load(), 0);
}

TEST(SuperTimeStepping, AutoChoosesByPredictedCost) {
  const LiquidMesh g = anisotropicGrid(60, 1e-3);
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  const auto run = [&](double h, double radius) {
    DiffusionSystems systems;  // Auto
    EXPECT_EQ(systems.assemble(g.intrinsic, h), SolverStatus::Ok);
    StainState state = zeroState(g.vertexCount());
    state.solvent = spot(g, Vector2(0.5, 0.5), radius, 1.0);
    const DiffusionReport r = diffuse(context(h, true), g.intrinsic, systems, scratch, state);
    EXPECT_EQ(r.status, SolverStatus::Ok);
    std::printf("  h = %g s, spot radius %.2f: stiffness ratio %.2f, %d stages, method %d, predicted cost %.3g\n", h,
                radius, systems.scalarStiffnessRatio(), systems.scalarStages(), static_cast<int>(r.densityMethod),
                r.densityPredictedCost);
    return r.densityMethod;
  };
  // A game step on a mild system: 2 stages beat ~20 predicted CG iterations.
  EXPECT_EQ(run(1.0 / 60, 0.15), DiffusionMethod::SuperTimeStepping);
  // Too stiff for CG's Jacobi preconditioner (ratio ≈ 6, the bunny's range,
  // where the stiffness rule took the whole-mesh factor), mild enough for RKL2.
  EXPECT_EQ(run(0.5, 0.15), DiffusionMethod::SuperTimeStepping);
  // h λ past kRklAutoStepStiffness (RKL2 less accurate than backward Euler)
  // and past CG's ratio: the factor.
  EXPECT_EQ(run(5.0, 0.15), DiffusionMethod::Direct);
  // The liquid covering the sheet, RKL2 still cheapest against the factor here.
  EXPECT_EQ(run(0.5, 2.0), DiffusionMethod::SuperTimeStepping);
}

}  // namespace
}  // namespace blot::stain
