// Explicit super-time-stepping of the diffusion, u' = −M⁻¹L u, by the
// second-order Runge–Kutta–Legendre scheme RKL2 (Meyer, Balsara & Aslam,
// J. Comput. Phys. 257 (2014) 594–626), on the liquid's rows only
// (design note: stages/diffusion.cpp; docs/accuracy.md, "Explicit diffusion
// by super-time-stepping").
#pragma once

#include <blot/stain/stages/diffusion.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "numerics/compensated_sum.h"
#include "numerics/krylov_solver.h"
#include "numerics/threads.h"

namespace blot::stain::diffusion_internal {

// Gershgorin bound of the spectrum of M⁻¹L: max_i Σ_j |L_ij| / A_i (1/s).
// M⁻¹L is similar to the symmetric (Hermitian) M^{-1/2} L M^{-1/2}, so its
// eigenvalues are real, and each lies in a Gershgorin disc of its rows: the
// bound holds for the connection Laplacian too (|L_ij| is the modulus).
// Column sums are taken (the matrices store both triangles; |L_ij| = |L_ji|).
// |value| for the bound: √(re² + im²) for a complex entry rather than
// std::abs's hypot, whose over- and underflow guards these entries (|L_ij|
// of a cloth's metric, far from 1e±150) do not need: about a fifth of the
// assembly of M + hL (geometry_refresh_bench part 11, tablecloth 120 -> 94
// us). Within an ulp of hypot; kRklStabilityMargin covers the bound's rounding.
inline double boundModulus(double value) { return std::abs(value); }
inline double boundModulus(const std::complex<double>& value) {
  return std::sqrt(value.real() * value.real() + value.imag() * value.imag());
}

// Σ boundModulus over values[begin, end), added in index order.
inline double columnModulusSum(const double* values, int begin, int end) {
  double sum = 0.0;
  for (int p = begin; p < end; ++p) sum += boundModulus(values[p]);
  return sum;
}
inline double columnModulusSum(const std::complex<double>* values, int begin, int end) {
  double sum = 0.0;
  int p = begin;
#ifdef __SSE2__
  // Two entries' moduli in one vector square root (correctly rounded per
  // lane, as the scalar one), then added one by one in index order: the same
  // bits as the scalar loop below, at about half the cost of its square
  // roots (the bound's share of a metric rebuild).
  const double* raw = reinterpret_cast<const double*>(values);
  for (; p + 1 < end; p += 2) {
    const __m128d a = _mm_loadu_pd(raw + 2 * p), b = _mm_loadu_pd(raw + 2 * p + 2);
    const __m128d squaresA = _mm_mul_pd(a, a), squaresB = _mm_mul_pd(b, b);
    const __m128d moduli =
        _mm_sqrt_pd(_mm_add_pd(_mm_unpacklo_pd(squaresA, squaresB), _mm_unpackhi_pd(squaresA, squaresB)));
    sum += _mm_cvtsd_f64(moduli);
    sum += _mm_cvtsd_f64(_mm_unpackhi_pd(moduli, moduli));
  }
#endif
  for (; p < end; ++p) sum += boundModulus(values[p]);
  return sum;
}

// Column j's term of spectralBound: Σ_i |L_ij| / A_j, and 0 where A_j is not
// positive (which the bound, taken from 0, then skips).
template <typename Scalar>
double spectralBoundTerm(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& areas, int j) {
  const int* outer = stiffness.outerIndexPtr();
  const int end = stiffness.isCompressed() ? outer[j + 1] : outer[j] + stiffness.innerNonZeroPtr()[j];
  const double sum = columnModulusSum(stiffness.valuePtr(), outer[j], end);
  return areas[j] > 0.0 ? sum / areas[j] : 0.0;
}

template <typename Scalar>
double spectralBound(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& areas) {
  const int n = static_cast<int>(stiffness.cols());
  double bound = 0.0;
  for (int j = 0; j < n; ++j) bound = std::max(bound, spectralBoundTerm(stiffness, areas, j));
  return bound;
}

// Stages RKL2 needs for one step τ: the smallest s ≥ 2 with
// τ λ ≤ (s² + s − 2) / 2 (its stability interval, τ_expl (s² + s − 2)/4 with
// τ_expl = 2/λ), λ a bound on λ_max(M⁻¹L). kRklStabilityMargin keeps a
// relative margin for the rounding in the bound; 0 when s would exceed
// kMaxRklStages.
inline int rkl2Stages(double tauLambda) {
  if (!(tauLambda >= 0.0) || !std::isfinite(tauLambda)) return 0;
  const double needed = 2.0 * tauLambda * (1.0 + kRklStabilityMargin);  // s² + s − 2 ≥ needed
  int s = static_cast<int>(std::ceil(0.5 * (-1.0 + std::sqrt(9.0 + 4.0 * needed))));
  s = std::max(s, 2);
  while (s * s + s - 2 < needed) ++s;  // the square root's rounding
  return s <= kMaxRklStages ? s : 0;
}

// The RKL2 coefficients of stage j (2 ≤ j ≤ s) and of stage 1 (μ̃_1 in muTilde[1]).
struct Rkl2Stage {
  double mu = 0, nu = 0, muTilde = 0, gammaTilde = 0;
};
inline Rkl2Stage rkl2Coefficients(int s, int j) {
  const auto b = [](int k) { return k <= 2 ? 1.0 / 3.0 : (k * k + k - 2.0) / (2.0 * k * (k + 1.0)); };
  const double w1 = 4.0 / (s * s + s - 2.0);
  Rkl2Stage c;
  if (j == 1) {
    c.muTilde = b(1) * w1;
    return c;
  }
  c.mu = (2.0 * j - 1.0) / j * b(j) / b(j - 1);
  c.nu = -(j - 1.0) / j * b(j) / b(j - 2);
  c.muTilde = c.mu * w1;
  c.gammaTilde = -(1.0 - b(j - 1)) * c.muTilde;
  return c;
}

struct RklOutcome {
  int stages = 0;
  bool finite = true;  ///< false: a non-finite value in x0 or in a stage (the caller reports NonFinite)
};

// One RKL2 step of u' = −M⁻¹L u over τ with s stages, on pairs (two numbers
// per vertex, as the CG's: kComplex = false, two independent real fields
// sharing each pass over L; kComplex = true, one field on (Re, Im) with the
// Hermitian L stored by columns, row i of L y = Σ conj(L_ji) y_j over column i).
// `stiffness` is L itself (compressed or not), not M + hL.
//
// Rows: the active set. With `grow`, the caller seeds it with x0's support
// and its first ring (the support of L x0, as for the CG), and each later
// stage first adds the next ring (the support of L Y_{j−1}), so stage j works
// on the support and its j-ring halo and the result is the whole-mesh RKL2
// step to the bit (everything further out is exactly zero). Without it the active rows are a fixed domain whose
// unmarked neighbours keep their x0 values through every stage (Dirichlet
// data, the CG's treatment of the velocity band).
//
// x0: component c of vertex j at x0[c][j * x0Stride]. y (the result), w and
// g0 (τ F(Y_0)) are work pairs that must be zero outside the active set on
// entry; y is written on the active rows; w and g0 are left non-zero there
// (the caller zeroes them with releaseActive). mass[c] = compensated
// Σ_{initial rows} A_i x0_c,i. Row loops run in fixed chunks (the CG's
// chunking and threshold), and no stage sums across rows, so the result is
// the same to the bit for any thread count. No allocation.
template <bool kComplex, typename Scalar>
RklOutcome rkl2Step(const Eigen::SparseMatrix<Scalar>& stiffness, const double* area, const double* const x0[2],
                    int x0Stride, int stages, double tau, double* __restrict y, double* __restrict w,
                    double* __restrict g0, ActiveSet& active, bool grow, double mass[2], double* partials) {
  RklOutcome outcome;
  outcome.stages = stages;
  const int* outer = stiffness.outerIndexPtr();
  const int* inner = stiffness.innerIndexPtr();
  const int* nonZeros = stiffness.isCompressed() ? nullptr : stiffness.innerNonZeroPtr();
  const double* values = reinterpret_cast<const double*>(stiffness.valuePtr());
  const auto x0At = [&](int c, int j) { return x0[c][static_cast<size_t>(j) * static_cast<size_t>(x0Stride)]; };

  // Masses and finiteness of x0 over the initial rows (chunked, compensated).
  {
    const int* list = active.list();
    const int count = active.size();
    double totals[3];
    chunkedSums<3>(count, partials, totals, [&](int begin, int end, double* out) {
      CompensatedSum m0, m1;
      double magnitude = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        m0.add(area[i] * x0At(0, i));
        m1.add(area[i] * x0At(1, i));
        magnitude += std::abs(x0At(0, i)) + std::abs(x0At(1, i));
      }
      out[0] = m0.value();
      out[1] = m1.value();
      out[2] = magnitude;
    });
    const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
    CompensatedSum m0, m1;
    for (int c = 0; c < chunks; ++c) {
      m0.add(partials[3 * c]);
      m1.add(partials[3 * c + 1]);
    }
    mass[0] = m0.value();
    mass[1] = m1.value();
    if (!std::isfinite(totals[2])) {
      outcome.finite = false;
      return outcome;
    }
  }

  // τ (M⁻¹ L v)_i with v read from `current` on active rows and from x0
  // outside (zero there when growing).
  const char* marks = active.marks();
  const auto applyRow = [&](const double* current, int i, double& f0, double& f1) {
    const int begin = outer[i], end = nonZeros ? outer[i] + nonZeros[i] : outer[i + 1];
    double s0 = 0.0, s1 = 0.0;
    for (int e = begin; e < end; ++e) {
      const int j = inner[e];
      const double v0 = current ? (marks[j] ? current[2 * j] : x0At(0, j)) : x0At(0, j);
      const double v1 = current ? (marks[j] ? current[2 * j + 1] : x0At(1, j)) : x0At(1, j);
      if (kComplex) {
        const double re = values[2 * e], im = values[2 * e + 1];
        s0 += re * v0 + im * v1;
        s1 += re * v1 - im * v0;
      } else {
        s0 += values[e] * v0;
        s1 += values[e] * v1;
      }
    }
    const double scale = -tau / area[i];  // F = −M⁻¹ L
    f0 = scale * s0;
    f1 = scale * s1;
  };
  const auto forRows = [&](const auto& body) {
    const int* list = active.list();
    const int count = active.size();
    const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
    threads::runLoop(count >= kKrylovParallelRows, [&] {
#pragma omp for schedule(static)
      for (int c = 0; c < chunks; ++c) {
        const int end = std::min(count, (c + 1) * kKrylovChunkRows);
        for (int k = c * kKrylovChunkRows; k < end; ++k) body(list[k]);
      }
    });
  };

  // Y_j lives in `odd` for odd j and in `even` for even j (Y_j overwrites
  // Y_{j−2} row by row: each row reads only its own Y_{j−2}); Y_s ends in y.
  double* odd = stages % 2 == 1 ? y : w;
  double* even = stages % 2 == 1 ? w : y;

  // Stage 1: g0 = τ F(Y_0), Y_1 = Y_0 + μ̃_1 g0 (on the seeded rows).
  const double muTilde1 = rkl2Coefficients(stages, 1).muTilde;
  forRows([&](int i) {
    double f0, f1;
    applyRow(nullptr, i, f0, f1);
    g0[2 * i] = f0;
    g0[2 * i + 1] = f1;
    odd[2 * i] = x0At(0, i) + muTilde1 * f0;
    odd[2 * i + 1] = x0At(1, i) + muTilde1 * f1;
  });
  for (int j = 2; j <= stages; ++j) {
    if (grow) active.grow(outer, inner);
    const Rkl2Stage c = rkl2Coefficients(stages, j);
    const double keep = 1.0 - c.mu - c.nu;
    const double* previous = j % 2 == 1 ? even : odd;  // Y_{j−1}
    double* next = j % 2 == 1 ? odd : even;            // Y_{j−2} in, Y_j out
    const bool secondStage = j == 2;                   // Y_0 = x0 is not in a buffer
    forRows([&](int i) {
      double f0, f1;
      applyRow(previous, i, f0, f1);
      const double y00 = x0At(0, i), y01 = x0At(1, i);
      const double before0 = secondStage ? y00 : next[2 * i];
      const double before1 = secondStage ? y01 : next[2 * i + 1];
      next[2 * i] = c.mu * previous[2 * i] + c.nu * before0 + keep * y00 + c.muTilde * f0 + c.gammaTilde * g0[2 * i];
      next[2 * i + 1] =
          c.mu * previous[2 * i + 1] + c.nu * before1 + keep * y01 + c.muTilde * f1 + c.gammaTilde * g0[2 * i + 1];
    });
  }
  // A non-finite stage (an unstable s would overflow; a NaN in L) shows in the result.
  {
    const int* list = active.list();
    double total[1];
    chunkedSums<1>(active.size(), partials, total, [&](int begin, int end, double* out) {
      double sum = 0.0;
      for (int k = begin; k < end; ++k) sum += std::abs(y[2 * list[k]]) + std::abs(y[2 * list[k] + 1]);
      out[0] = sum;
    });
    outcome.finite = std::isfinite(total[0]);
  }
  return outcome;
}

// The per-solve cost model (design note; docs/performance.md, "The cheapest
// solver"): predicted work in matrix entries visited, each method's row
// overhead (vector loads and stores, reductions) counted as that many entries.
// It reads only the solve's inputs (the system's bounds, the support), never
// the history of earlier solves, so a restored run chooses as the original
// did. `rows`: the liquid's rows plus the first ring (both restricted methods
// start there), `ring`: that first ring's size, the growth per further ring
// assumed (0 on a fixed domain).
inline constexpr double kRklRowOverhead = 6.0;   // Y_{j−1}, Y_{j−2}, Y_0, g0 loads, one store, one division
inline constexpr double kCgRowOverhead = 14.0;   // two updates, the direction, three reductions
// The factorization, once computed, is assumed to serve this many solves
// (a metric refresh every few steps on deforming cloth; never on rigid
// motion, where it would serve all of them): its cost is divided by it.
inline constexpr double kAssumedFactorReuse = 10.0;

inline double rklCost(int stages, int rows, int ring, double entriesPerRow) {
  return stages * (rows + 0.5 * (stages - 1) * ring) * (entriesPerRow + kRklRowOverhead);
}

// Jacobi-PCG iterations to kIterativeTolerance from the condition-number
// bound κ ≤ 2(1 + max h L_ii / A_i) of the Jacobi-scaled system: the
// classical bound ½ √κ ln(2/ε), halved to match the counts measured on the
// warm-started solves (7–10 at ratios 0.05–0.75 in stain_step_bench, 8.8 at
// 0.59 in krylov_diffusion_test, against 19 from the bound), capped at
// kMaxIterations.
inline int predictedCgIterations(double stiffnessRatio) {
  const double kappa = 2.0 * (1.0 + std::max(0.0, stiffnessRatio));
  const double k = std::ceil(0.25 * std::sqrt(kappa) * std::log(2.0 / kIterativeTolerance));
  return static_cast<int>(std::min<double>(k, kMaxIterations));
}

// The band's symmetric Gauss–Seidel PCG (bandConjugateGradients): half
// Jacobi's iterations (measured 87 → 34 at max h L_ii / A_i = 107 in
// krylov_diffusion_test, 34 → 16–17 on Table 1's bunny at 60, 6 → 3 at 0.4),
// each about one Jacobi iteration's entries (two half sweeps in place of
// one product).
inline int predictedBandCgIterations(double stiffnessRatio) {
  return (predictedCgIterations(stiffnessRatio) + 1) / 2;
}

inline double cgCost(int iterations, int rows, int ring, double entriesPerRow) {
  return iterations * (rows + 0.5 * (iterations - 1) * ring) * (entriesPerRow + kCgRowOverhead);
}

// Whole-mesh direct solve of `fields` right-hand sides: forward and back
// substitution (two passes over the factor's entries) per field, the mass
// product and copies over #V, and the numeric factorization amortized.
// The factor's entries are estimated (nested dissection on a 2-D mesh,
// 4 n log₂ n), not read from a factor that may or may not exist yet (the
// choice must not depend on history); the factorization's work is taken as
// entries²/n (Σ of squared column counts for equal columns).
inline double directCost(int vertices, int fields) {
  const double n = std::max(1, vertices);
  const double entries = 4.0 * n * std::log2(std::max(2.0, n));
  return fields * (2.0 * entries + 4.0 * n) + entries * entries / n / kAssumedFactorReuse;
}

}  // namespace blot::stain::diffusion_internal
