// Stage "diffuse": implicit diffusion of densities and velocity, and the
// mass-conserving positivity limiter (paper sec. 3.2).
//
// Design note.
//  - Equations: ∂σ/∂t = ∇·(S_f ∇σ) for σ_f and σ_s, ∂u/∂t = ∇·(S_v ∇u) for the
//    tangent velocity (Bochner Laplacian). P1 elements, lumped mass M = diag(A_i),
//    backward Euler: (M + h L_Sf) σ^{t+h} = M σ^t and (M + h L_Sv) u^{t+h} = M u^t,
//    L PSD (operators.h sign convention). Rows of L_Sf sum to zero, so the
//    exact discrete solution conserves Σ_i A_i σ_i; the direct solve does only to
//    its backward error (~ε h‖L‖/‖M‖, up to 4e-13 relative measured), so each
//    density solution is rescaled by the ratio of masses before/after (a change of
//    that size). The boundary condition is the natural one (no flux, free slip).
//  - Systems: M + hL is assembled once into a matrix that owns its pattern and
//    is refilled in place (no allocation) when h or the intrinsic tier changes;
//    the scalar system is analysed once (AMD + symbolic), the complex connection
//    system copies that analysis (same pattern), and each refresh is a numeric
//    refactorization only. Both density fields are solved against the same
//    factor; a field that is identically zero is skipped (no solute, dry mesh).
//  - All-or-nothing: the three solutions go to scratch first (the solute one
//    in place of its own right-hand side) and are committed only when every solve
//    succeeded, so a failing step leaves the state as it was.
//  - Positivity: with strong anisotropy (eigenvalue ratio up to 1e6, weft not
//    aligned with the mesh) the P1 stiffness gets positive off-diagonal entries
//    (it is no longer an M-matrix) and the solve undershoots below zero near the
//    front of a spot (measured in tests/stain/diffusion_test.cpp). The limiter
//    fixes each negative vertex by pulling its deficit from the nearest vertices
//    that hold positive mass, ring by ring in the operator's graph: first its
//    one-ring, then, only if that ring holds too little, the next ring, up to
//    kLimiterSearchBudget vertices (the undershoot forms lobes a few vertices
//    wide beside the spot: at a ratio of 1e6, 30° and h D/dx² = 10 on a 40x40
//    grid, roughly half of the fixes go past the first ring; none needed the
//    fallback when the limiter runs after every solve). Visited vertices are
//    kept in a small stack hash set, so a search costs O(vertices visited)
//    and allocates nothing. Within a ring the donors give in proportion
//    to their mass (σ_j ← σ_j (1 − taken / available)), so they stay ≥ 0 and
//    the correction stays where the error was made. Vertices are visited once,
//    in index order (deterministic). Whatever no nearby ring can cover is taken
//    from all positive vertices in proportion to their mass (global fallback).
//    Σ A_i σ_i changes only by rounding. Rejected: a silent clamp σ ← max(σ, 0),
//    which creates mass (as much as the undershoot: measured 1e-4 to 8e-3 of
//    the total per step at ratios 1e2–1e6, h D/dx² = 0.1–100);
//    flux-corrected transport (a low-order monotone solve plus limited
//    antidiffusive fluxes), which needs a second solve per field and
//    per-edge flux limiting every step for an error that is already confined
//    to a few front vertices; a global proportional rescale alone, which moves
//    mass across the whole stain.
//  - Zero and positive vertices cost one comparison in the limiter; a field with
//    no negative value costs one scan.
//  - Solver per system (DiffusionSystems::factorize): with r = max_i h L_ii / A_i
//    the Jacobi-scaled system D^-1/2 (M + hL) D^-1/2 has its spectrum in
//    [~1/(1 + r), ~2], so for r <= kIterativeStiffnessRatio (4) Jacobi-PCG
//    reaches a relative residual of kIterativeTolerance (1e-9) in ~5-15
//    iterations (measured: 7 / 10 / 9 for the densities and 4-6 for the
//    velocity on the 2.5K / 10K / 35K grids of stain_step_bench, r = 0.05-0.75), while the
//    direct solve reads the whole factor (nnz(L) ~ 25 #V) per field whatever
//    the stain's size. CG is warm-started at σ^t (whose support is the
//    liquid), and the iterate's support grows by exactly one ring per
//    iteration (one product with the one-ring operator), so iteration k runs
//    only over the liquid and its k-ring halo: an active list grown
//    breadth-first (deterministic); it is the whole-mesh CG iterate, nothing
//    truncated. Vectors hold two numbers per vertex, so solvent and solute
//    (or Re and Im of u) share every pass over the matrix. Above the ratio,
//    or when CG has not converged in kMaxIterations, the factor solves it
//    (it is kept up to date either way, so the fallback is always there).
//    Threads: the row loops (A p with pᵀq, the x/r update with rᵀD⁻¹r and
//    rᵀr, the p update, the start's residual) work on fixed chunks of
//    kKrylovChunkRows active rows, each chunk's partial sums stored and added
//    in chunk order, so the sums depend on the active count only, never on
//    the thread count or on whether threads ran (bit-identical for 1 and N
//    threads; with one chunk it is the old plain serial sum). The chunks run
//    on OpenMP threads from kKrylovParallelRows active rows: below that a
//    fork/join (three per iteration) costs more than the loop on two cores.
//    Rejected: OpenMP's reduction(+), whose combination order is the
//    runtime's and changes with the thread count.
//    Rejected: running CG on the whole mesh (4-8x the rows of a
//    10 % drop), and a stronger preconditioner (IC(0), SSOR: fewer iterations
//    but the triangular sweeps fill the whole active region at once, and the
//    solution must reach the same rings anyway).
//  - Tail flush: the CG solution decays geometrically away from the liquid
//    (so does the exact one: backward Euler has unbounded propagation speed);
//    values below kIterativeTolerance × max |σ|, inside the iterate's own
//    error, are set to zero before the mass fix, or the support (and the
//    next step's work) would creep outwards every step. Tiny negative
//    ripples of the tail go with them instead of costing limiter searches.
//  - Mass with CG: 1ᵀ(M + hL)x = 1ᵀM x, so the mass error is 1ᵀr plus the
//    flushed mass, ~1e-9 relative at most; the rescale above removes it (a
//    relative change of that size; the CG-vs-direct difference measured in
//    tests/stain/krylov_diffusion_test.cpp is 9e-9 after 20 steps, far below
//    any discretization error). Rejected: iterating to 1e-13 (~2x the
//    iterations and more rings for a change nobody can measure).
//  - Velocity: u matters only where there is liquid. Given a mask (the
//    solver passes the liquid band less its outermost ring), the connection
//    system is solved on the masked vertices only, the u of their unmasked
//    neighbours entering as fixed (Dirichlet) values and left as they are.
//    The solver extends the liquid's velocity onto the band first, so that
//    boundary data is the liquid's own velocity, not a dry vertex's zero
//    (which pinned the wet front to rest and acted as friction, issue 14): a
//    uniformly moving film is in the null space and keeps its velocity.
//    Without a mask (tests), like the densities, on the Krylov support.
//  - After a CG solve the limiter visits only the active list (the only
//    vertices that can be negative), in its order.
#include <blot/stain/stages/diffusion.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <vector>

#include "numerics/compensated_sum.h"
#include "numerics/diffusion_system.h"
#include "numerics/krylov_solver.h"
#include "numerics/positivity_limiter.h"

namespace blot::stain {
using namespace diffusion_internal;
namespace {

template <typename Scalar>
bool allZero(const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v) {
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    if (v[i] != Scalar(0)) return false;
  }
  return true;
}

double massOf(const Vector& rhs) {
  CompensatedSum sum;
  for (Eigen::Index i = 0; i < rhs.size(); ++i) sum.add(rhs[i]);
  return sum.value();
}

// The exact discrete solution conserves Σ A_i σ_i (rows of L sum to zero), but
// the direct solve's backward error, of relative size ε h‖L‖/‖M‖, does not:
// measured up to 3.6e-13 of the total at h D/dx² = 100. Rescaling by the ratio
// of the masses restores conservation to rounding (a relative change of that
// same 1e-13 size, far below the discretization error; zeros stay zero and
// signs are kept).
void restoreMass(const Vector& dualAreas, double mass, Vector& solution) {
  CompensatedSum solved;
  for (Eigen::Index i = 0; i < solution.size(); ++i) solved.add(dualAreas[i] * solution[i]);
  if (!(mass > 0.0) || !(solved.value() > 0.0)) return;
  solution *= mass / solved.value();
}

}  // namespace

void DiffusionScratch::resize(int vertexCount) {
  rhs.setZero(vertexCount);
  solution.setZero(vertexCount);
  complexRhs.setZero(vertexCount);
  complexSolution.setZero(vertexCount);
  for (Vector* v : {&densityX, &densityR, &densityP, &densityQ, &velocityX, &velocityR, &velocityP, &velocityQ})
    v->setZero(2 * static_cast<Eigen::Index>(vertexCount));
  densityActive.assign(static_cast<size_t>(vertexCount), 0);
  velocityActive.assign(static_cast<size_t>(vertexCount), 0);
  densityMarks.assign(static_cast<size_t>(vertexCount), 0);
  velocityMarks.assign(static_cast<size_t>(vertexCount), 0);
  densityActiveCount = velocityActiveCount = 0;
  const int chunks = (vertexCount + kKrylovChunkRows - 1) / kKrylovChunkRows;
  krylovPartials.assign(static_cast<size_t>(chunks) * kKrylovPartialsPerChunk, 0.0);
}

DiffusionReport diffuse(const StepContext& ctx, const IntrinsicGeometry& geometry,
                        const DiffusionSystems& systems, DiffusionScratch& scratch, StainState& state,
                        const std::vector<char>* wet) {
  DiffusionReport report;
  const PhysicsSwitches& switches = ctx.switches;
  if (!switches.densityDiffusion && !switches.velocityDiffusion) return report;

  const Eigen::Index n = state.solvent.size();
  const Vector& areas = geometry.vertexDualAreas;
  if (areas.size() != n || state.solute.size() != n || state.velocities.size() != n ||
      scratch.rhs.size() != n || scratch.solution.size() != n || scratch.complexRhs.size() != n ||
      scratch.complexSolution.size() != n || scratch.densityX.size() != 2 * n || scratch.velocityX.size() != 2 * n ||
      static_cast<Eigen::Index>(scratch.densityMarks.size()) != n ||
      static_cast<Eigen::Index>(scratch.krylovPartials.size()) <
          (n + kKrylovChunkRows - 1) / kKrylovChunkRows * kKrylovPartialsPerChunk ||
      (wet != nullptr && static_cast<Eigen::Index>(wet->size()) != n)) {
    report.status = SolverStatus::SizeMismatch;
    return report;
  }
  // The factor belongs to one step size; a different h would silently solve
  // another equation.
  if (systems.factorizedStep() != ctx.h) {
    report.status = SolverStatus::NotFactorized;
    return report;
  }

  const bool solvent = switches.densityDiffusion && !allZero(state.solvent);
  const bool solute = switches.densityDiffusion && !allZero(state.solute);
  const bool velocity = switches.velocityDiffusion && !allZero(state.velocities);

  // Densities by CG (both fields in one pass) into densityX, on densityActive.
  const SparseMatrix& scalarSystem = systems.scalarSystem();
  ActiveSet densityActive(scratch.densityActive, scratch.densityMarks);
  bool densityByCg = false;
  double* dx = scratch.densityX.data();
  if ((solvent || solute) && systems.scalarIterative()) {
    const int vertices = static_cast<int>(n);
    const double* s0 = state.solvent.data();
    const double* s1 = state.solute.data();
    for (int i = 0; i < vertices; ++i) {
      if (s0[i] != 0.0 || s1[i] != 0.0) densityActive.add(i);
    }
    // r0 = −h L σ reaches one ring further.
    densityActive.grow(scalarSystem.outerIndexPtr(), scalarSystem.innerIndexPtr());
    const double* x0[2] = {s0, s1};
    double mass[2];
    const KrylovOutcome outcome = pairConjugateGradients<false>(
        scalarSystem.outerIndexPtr(), scalarSystem.innerIndexPtr(), scalarSystem.valuePtr(),
        systems.scalarInverseDiagonal().data(), areas.data(), x0, 1, dx, scratch.densityR.data(),
        scratch.densityP.data(), scratch.densityQ.data(), densityActive, true, mass, scratch.krylovPartials.data());
    report.densityIterations = outcome.iterations;
    report.densityActiveVertices = densityActive.size();
    if (!outcome.finite) {
      releaseActive(densityActive, {dx, scratch.densityR.data(), scratch.densityP.data()});
      report.status = SolverStatus::NonFinite;
      return report;
    }
    if (outcome.converged) {
      densityByCg = true;
      report.densityMethod = DiffusionMethod::ConjugateGradient;
      // Flush the far tail and restore the exact mass (design note), over
      // the active rows only.
      // Chunked like the CG's sums (the same bits for any thread count).
      const int* list = densityActive.list();
      const int count = densityActive.size();
      const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
      double* partials = scratch.krylovPartials.data();
      const bool threaded = count >= kKrylovParallelRows;
      for (int c = 0; c < 2; ++c) {
        double largest = 0.0;  // a max: the same in any order
#pragma omp parallel for schedule(static) reduction(max : largest) if (threaded)
        for (int k = 0; k < count; ++k) largest = std::max(largest, std::abs(dx[2 * list[k] + c]));
        const double floor = kIterativeTolerance * largest;
#pragma omp parallel for schedule(static) if (threaded)
        for (int chunk = 0; chunk < chunks; ++chunk) {
          CompensatedSum solved;
          const int end = std::min(count, (chunk + 1) * kKrylovChunkRows);
          for (int k = chunk * kKrylovChunkRows; k < end; ++k) {
            double& v = dx[2 * list[k] + c];
            if (std::abs(v) < floor) v = 0.0;
            solved.add(areas[list[k]] * v);
          }
          partials[chunk] = solved.value();
        }
        CompensatedSum solved;
        for (int chunk = 0; chunk < chunks; ++chunk) solved.add(partials[chunk]);
        if (mass[c] > 0.0 && solved.value() > 0.0) {
          const double scale = mass[c] / solved.value();
#pragma omp parallel for schedule(static) if (threaded)
          for (int k = 0; k < count; ++k) dx[2 * list[k] + c] *= scale;
        }
      }
    } else {
      releaseActive(densityActive, {dx, scratch.densityR.data(), scratch.densityP.data()});
      densityActive = ActiveSet(scratch.densityActive, scratch.densityMarks);
      ++report.fallbacks;
    }
  }
  // Direct solves into scratch: σ_f -> solution, σ_s -> rhs (in place).
  if (!densityByCg && (solvent || solute)) {
    report.densityMethod = DiffusionMethod::Direct;
    if (solvent) {
      massTimes(areas, state.solvent, scratch.rhs);
      const double mass = massOf(scratch.rhs);
      report.status = systems.scalarSolver().solve(scratch.rhs, scratch.solution);
      if (report.status != SolverStatus::Ok) return report;
      restoreMass(areas, mass, scratch.solution);
    }
    if (solute) {
      massTimes(areas, state.solute, scratch.rhs);
      const double mass = massOf(scratch.rhs);
      report.status = systems.scalarSolver().solve(scratch.rhs, scratch.rhs);
      if (report.status != SolverStatus::Ok) return report;
      restoreMass(areas, mass, scratch.rhs);
    }
  }
  // A failed velocity solve must leave the densities as they were: undo the
  // CG bookkeeping before returning.
  const auto abandonDensities = [&] {
    if (densityByCg) releaseActive(densityActive, {dx, scratch.densityR.data(), scratch.densityP.data()});
  };

  // Velocity: CG on the wet region (or the Krylov support) into velocityX.
  const ComplexSparseMatrix& vectorSystem = systems.vectorSystem();
  ActiveSet velocityActive(scratch.velocityActive, scratch.velocityMarks);
  bool velocityByCg = false;
  double* ux = scratch.velocityX.data();
  if (velocity && systems.vectorIterative()) {
    const int vertices = static_cast<int>(n);
    const Complex* u0 = state.velocities.data();
    if (wet != nullptr) {
      for (int i = 0; i < vertices; ++i) {
        if ((*wet)[static_cast<size_t>(i)]) velocityActive.add(i);
      }
    } else {
      for (int i = 0; i < vertices; ++i) {
        if (u0[i] != Complex(0.0)) velocityActive.add(i);
      }
      velocityActive.grow(vectorSystem.outerIndexPtr(), vectorSystem.innerIndexPtr());
    }
    // std::complex<double> is two doubles (re, im) by the standard's array rule.
    const double* u0Pairs = reinterpret_cast<const double*>(u0);
    const double* x0[2] = {u0Pairs, u0Pairs + 1};
    double mass[2];
    const KrylovOutcome outcome = pairConjugateGradients<true>(
        vectorSystem.outerIndexPtr(), vectorSystem.innerIndexPtr(),
        reinterpret_cast<const double*>(vectorSystem.valuePtr()), systems.vectorInverseDiagonal().data(),
        areas.data(), x0, 2, ux, scratch.velocityR.data(), scratch.velocityP.data(), scratch.velocityQ.data(),
        velocityActive, wet == nullptr, mass, scratch.krylovPartials.data());
    report.velocityIterations = outcome.iterations;
    report.velocityActiveVertices = velocityActive.size();
    if (!outcome.finite) {
      releaseActive(velocityActive, {ux, scratch.velocityR.data(), scratch.velocityP.data()});
      abandonDensities();
      report.status = SolverStatus::NonFinite;
      return report;
    }
    if (outcome.converged) {
      velocityByCg = true;
      report.velocityMethod = DiffusionMethod::ConjugateGradient;
    } else {
      releaseActive(velocityActive, {ux, scratch.velocityR.data(), scratch.velocityP.data()});
      ++report.fallbacks;
    }
  }
  if (velocity && !velocityByCg) {
    report.velocityMethod = DiffusionMethod::Direct;
    massTimes(areas, state.velocities, scratch.complexRhs);
    report.status = systems.vectorSolver().solve(scratch.complexRhs, scratch.complexSolution);
    if (report.status != SolverStatus::Ok) {
      abandonDensities();
      return report;
    }
  }

  // Commit (copies, not swaps: the state's arrays keep their addresses).
  double minimum = 0.0;
  if (densityByCg) {
    const int* list = densityActive.list();
    for (int k = 0; k < densityActive.size(); ++k) {
      const int i = list[k];
      state.solvent[i] = dx[2 * i];
      state.solute[i] = dx[2 * i + 1];
      minimum = std::min(minimum, std::min(dx[2 * i], dx[2 * i + 1]));
    }
    abandonDensities();  // the CG vectors' invariant: zero outside the active set
  } else {
    if (solvent) state.solvent = scratch.solution;
    if (solute) state.solute = scratch.rhs;
    if (solvent) minimum = std::min(minimum, state.solvent.minCoeff());
    if (solute) minimum = std::min(minimum, state.solute.minCoeff());
  }
  if (velocityByCg) {
    const int* list = velocityActive.list();
    for (int k = 0; k < velocityActive.size(); ++k) {
      const int i = list[k];
      state.velocities[i] = Complex(ux[2 * i], ux[2 * i + 1]);
    }
    releaseActive(velocityActive, {ux, scratch.velocityR.data(), scratch.velocityP.data()});
  } else if (velocity) {
    state.velocities = scratch.complexSolution;
  }
  if (!solvent && !solute) return report;

  report.minDensityBeforeLimiter = minimum;
  if (!switches.positivityLimiter || minimum >= 0.0) return report;

  const MatrixRings rings{geometry.densityStiffness};
  for (Vector* field : {solvent ? &state.solvent : nullptr, solute ? &state.solute : nullptr}) {
    if (field == nullptr) continue;
    const auto [count, mass] = densityByCg ? limit(rings, areas, *field, densityActive.list(), densityActive.size())
                                           : limit(rings, areas, *field);
    report.limiterCorrectedVertices += count;
    report.limiterMovedMass += mass;
  }
  return report;
}

}  // namespace blot::stain
