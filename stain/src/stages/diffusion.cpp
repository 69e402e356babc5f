// Stage "diffuse": implicit diffusion of densities and velocity, and the
// mass-conserving positivity limiter (paper sec. 3.2).
//
// Design note: docs/design-notes.md, "stain/src/stages/diffusion.cpp".
#include <blot/stain/stages/diffusion.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <vector>

#include "numerics/compensated_sum.h"
#include "numerics/diffusion_system.h"
#include "numerics/krylov_solver.h"
#include "numerics/positivity_limiter.h"
#include "numerics/super_time_stepping.h"
#include "numerics/threads.h"

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

// A cost no method reaches (the method may not run).
constexpr double kNever = 1e300;

// rhs_i = A_i x_i (massTimes's product) and the mass Σ_i rhs_i, compensated
// in index order, in one pass. Adding a zero (of either sign) leaves a
// CompensatedSum's bits as they are, so the zeros, most of the mesh, are
// not added: the sum's dependency chain runs over the liquid only.
double massTimesSummed(const Vector& dualAreas, const Vector& x, Vector& rhs) {
  CompensatedSum sum;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    rhs[i] = dualAreas[i] * x[i];
    if (rhs[i] != 0.0) sum.add(rhs[i]);
  }
  return sum.value();
}

// The exact discrete solution conserves Σ A_i σ_i (rows of L sum to zero), but
// the direct solve's backward error, of relative size ε h‖L‖/‖M‖, does not:
// measured up to 3.6e-13 of the total at h D/dx² = 100. Rescaling by the ratio
// of the masses restores conservation to rounding (a relative change of that
// same 1e-13 size, far below the discretization error; zeros stay zero and
// signs are kept).
// Values below kIterativeTolerance × max |σ| are set to zero, as after CG:
// backward Euler's exponential tail, below what either solve resolves. Left
// in place, a factor's solution holds a trace on every vertex, and every
// later step's support, damp set and limiter would cover the mesh.
// flushTail zeros that tail and measures the mass left (Σ A_i σ_i,
// compensated, in index order) in the same pass; the factor to scale by is
// applied when the solution is committed (commitRestored), so that a failed
// velocity solve after it leaves the densities as they were.
struct MassRestore {
  bool scales = false;  // the solution's mass and the target are positive
  double factor = 1.0;  // target mass / the solution's
};
MassRestore flushTail(const Vector& dualAreas, double mass, Vector& solution) {
  const double floor = kIterativeTolerance * solution.cwiseAbs().maxCoeff();
  CompensatedSum solved;
  for (Eigen::Index i = 0; i < solution.size(); ++i) {
    if (std::abs(solution[i]) < floor) solution[i] = 0.0;
    const double held = dualAreas[i] * solution[i];
    if (held != 0.0) solved.add(held);  // a zero adds nothing (massTimesSummed)
  }
  MassRestore restore;
  if (!(mass > 0.0) || !(solved.value() > 0.0)) return restore;
  restore.scales = true;
  restore.factor = mass / solved.value();
  return restore;
}

// density = the solution, times the restoring factor where there is one;
// returns min(0, its least value), what minCoeff would give in that min.
// Lists (once, with `marks`) each vertex whose value changed, to the bit, or
// is nonzero: all this write and the limiter after it can change.
double commitRestored(const Vector& solution, const MassRestore& restore, Vector& density,
                      std::vector<char>& marks, int* listed, int& count) {
  double least = 0.0;
  const double factor = restore.factor;
  for (Eigen::Index i = 0; i < solution.size(); ++i) {
    const double value = restore.scales ? solution[i] * factor : solution[i];
    std::uint64_t now, before;
    std::memcpy(&now, &value, sizeof now);
    std::memcpy(&before, &density[i], sizeof before);
    // Changed bits, or nonzero (the sign bit shifted out).
    const bool written = now != before || (now << 1) != 0;
    if (written && marks[static_cast<size_t>(i)] == 0) {
      marks[static_cast<size_t>(i)] = 1;
      listed[count++] = static_cast<int>(i);
    }
    density[i] = value;
    least = std::min(least, value);
  }
  return least;
}

}  // namespace

void DomainRows::resize(int vertexCount, int nonZeros) {
  position.assign(static_cast<size_t>(vertexCount), -1);
  starts.assign(static_cast<size_t>(vertexCount) + 1, 0);
  splits.assign(static_cast<size_t>(vertexCount), 0);
  columns.resize(static_cast<size_t>(std::max(nonZeros, 0)));
  values.resize(2 * static_cast<size_t>(std::max(nonZeros, 0)));
}

void DiffusionScratch::resize(int vertexCount, int edgeCount) {
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
  directSupport.assign(static_cast<size_t>(vertexCount), 0);
  directMarks.assign(static_cast<size_t>(vertexCount), 0);
  densityActiveCount = velocityActiveCount = 0;
  const int chunks = (vertexCount + kKrylovChunkRows - 1) / kKrylovChunkRows;
  krylovPartials.assign(static_cast<size_t>(chunks) * kKrylovPartialsPerChunk, 0.0);
  velocityRows.resize(vertexCount, vertexCount + 2 * edgeCount);
  velocityT.setZero(2 * static_cast<Eigen::Index>(vertexCount));
}

namespace {

// The velocity's restricted methods on `rows` rows growing by `ring` per
// stage or iteration, predicted (kNever where not allowed).
struct RestrictedCosts {
  double rkl, cg;
};
// On the band (a fixed domain) CG runs with the symmetric Gauss–Seidel
// preconditioner, on a growing support with Jacobi's.
RestrictedCosts velocityCosts(const DiffusionSystems& systems, int rows, int ring, bool cgAllowed,
                              double entriesPerRow, bool onBand) {
  const int stages = systems.vectorStages();
  const double ratio = systems.vectorStiffnessRatio();
  const int iterations = onBand ? predictedBandCgIterations(ratio) : predictedCgIterations(ratio);
  return {stages > 0 ? rklCost(stages, rows, ring, entriesPerRow) : kNever,
          cgAllowed ? cgCost(iterations, rows, ring, entriesPerRow) : kNever};
}

// Whether every array diffuse() reads or writes is sized for the state's #V
// vertices (the CG's pair vectors 2 #V, the chunk partials for #V rows).
bool sizesMatch(const Vector& areas, const DiffusionScratch& scratch, const StainState& state,
                const std::vector<char>* wet) {
  const Eigen::Index n = state.solvent.size();
  return !(areas.size() != n || state.solute.size() != n || state.velocities.size() != n ||
           scratch.rhs.size() != n || scratch.solution.size() != n || scratch.complexRhs.size() != n ||
           scratch.complexSolution.size() != n || scratch.densityX.size() != 2 * n ||
           scratch.velocityX.size() != 2 * n || static_cast<Eigen::Index>(scratch.densityMarks.size()) != n ||
           static_cast<Eigen::Index>(scratch.krylovPartials.size()) <
               (n + kKrylovChunkRows - 1) / kKrylovChunkRows * kKrylovPartialsPerChunk ||
           (wet != nullptr && static_cast<Eigen::Index>(wet->size()) != n));
}

// Flushes the far tail and restores the exact mass (design note) of the
// two fields in dx (pairs), over the active rows only: values below
// kIterativeTolerance × max |x_c| become zero, then x_c is scaled by
// mass[c] / Σ A_i x_c,i where both are positive. Chunked like the CG's sums
// (the same bits for any thread count).
void flushAndRestoreOnSupport(const Vector& areas, const double mass[2], const ActiveSet& densityActive,
                              double* partials, double* dx) {
  const int* list = densityActive.list();
  const int count = densityActive.size();
  const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
  const bool threaded = count >= kKrylovParallelRows;
  for (int c = 0; c < 2; ++c) {
    double largest = 0.0;  // a max: the same in any order
    threads::runLoop(threaded, [&] {
      decltype(largest) largestHere = threads::lowest<decltype(largest)>();
#pragma omp for schedule(static) nowait
      for (int k = 0; k < count; ++k) largestHere = std::max(largestHere, std::abs(dx[2 * list[k] + c]));
#pragma omp critical(blot_threads_combine)
      {
        largest = std::max(largest, largestHere);
      }
    });
    const double floor = kIterativeTolerance * largest;
    threads::runLoop(threaded, [&] {
#pragma omp for schedule(static)
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
    });
    CompensatedSum solved;
    for (int chunk = 0; chunk < chunks; ++chunk) solved.add(partials[chunk]);
    if (mass[c] > 0.0 && solved.value() > 0.0) {
      const double scale = mass[c] / solved.value();
      threads::runLoop(threaded, [&] {
#pragma omp for schedule(static)
        for (int k = 0; k < count; ++k) dx[2 * list[k] + c] *= scale;
      });
    }
  }
}

// One field's restricted solve as the cost model predicts it on the
// liquid's rows: RKL2, CG and the whole-mesh factor (kNever where a method
// may not run); `considered` is false where no restricted solve is tried
// (the factor solves).
struct LadderCosts {
  double rkl = kNever, cg = kNever, direct = kNever;
  bool considered = false;
};

// The report's counts for one field (the densities' or the velocity's).
struct FieldReport {
  DiffusionMethod& method;
  int& iterations;
  int& stages;
  double& predictedCost;
  int& activeVertices;
};

// A field's pair vectors (2 #V each, zero outside the active set between
// calls) that a restricted solve leaves non-zero on the active rows: the
// iterate (the solution), the residual and the search direction.
struct PairWork {
  double* x;
  double* r;
  double* p;
};

struct LadderResult {
  SolverStatus status = SolverStatus::Ok;
  bool onSupport = false;  // the solution is in PairWork::x on the active rows
};

// The solver ladder, the same for the densities and the velocity: the cost
// model's cheapest method runs (RKL2 on a tie, then CG; a kNever cost never),
// and a CG that stalls falls back to the factor (counted in `fallbacks`).
// runRkl / runCg / runFactor are the field's RKL2 step, CG solve and direct
// solve. On the support the active set is kept for the caller to commit and
// release; otherwise it is released (marks removed, `work` zero again) and,
// unless the restricted solve met a non-finite value (NonFinite), the factor
// has run and its status is returned.
template <typename RunRkl, typename RunCg, typename RunFactor>
LadderResult climbLadder(const LadderCosts& costs, ActiveSet& active, const PairWork& work, const RunRkl& runRkl,
                         const RunCg& runCg, const RunFactor& runFactor, FieldReport field, int& fallbacks) {
  LadderResult result;
  if (costs.considered) {
    const double cheapest = std::min({costs.rkl, costs.cg, costs.direct});
    field.predictedCost = cheapest < kNever ? cheapest : 0;
    if (costs.rkl <= costs.cg && costs.rkl <= costs.direct && costs.rkl < kNever) {
      const RklOutcome outcome = runRkl();
      field.stages = outcome.stages;
      field.activeVertices = active.size();
      if (!outcome.finite) {
        releaseActive(active, {work.x, work.r, work.p});
        result.status = SolverStatus::NonFinite;
        return result;
      }
      field.method = DiffusionMethod::SuperTimeStepping;
      result.onSupport = true;
      return result;
    }
    if (costs.cg <= costs.direct && costs.cg < kNever) {
      const KrylovOutcome outcome = runCg();
      field.iterations = outcome.iterations;
      field.activeVertices = active.size();
      if (!outcome.finite) {
        releaseActive(active, {work.x, work.r, work.p});
        result.status = SolverStatus::NonFinite;
        return result;
      }
      if (outcome.converged) {
        field.method = DiffusionMethod::ConjugateGradient;
        result.onSupport = true;
        return result;
      }
      releaseActive(active, {work.x, work.r, work.p});
      ++fallbacks;
    } else {
      active.clearMarks();  // the factor predicted cheaper, or the only method left; `work` untouched
    }
  }
  field.method = DiffusionMethod::Direct;
  result.status = runFactor();
  return result;
}

// What diffuse() hands each field's ladder.
struct DiffusionInputs {
  const StepContext& ctx;
  const IntrinsicGeometry& geometry;
  DiffusionSystems& systems;
  DiffusionScratch& scratch;
  const StainState& state;
  double entriesPerRow;       // of the scalar system (the cost model's row cost)
  int factorizationsBefore;   // systems.factorizationCount() when diffuse() began
};

// The densities' ladder, solvent and solute as one pair field (densityX). On
// their support (when scalarIterative()), which r0 = −h L σ (and L σ for
// RKL2's first stage) reaches one ring further: RKL2 or CG, then the far
// tail's flush and the mass restore. By the factor, in place: σ_f into
// scratch.solution, σ_s into scratch.rhs, both in one pass over the factor
// when both are held (the same bits as two solves); their tails flushed and
// the restoring factors into `restores` (solvent, solute), applied at commit.
LadderResult diffuseDensities(const DiffusionInputs& in, bool solvent, bool solute, ActiveSet& active,
                              MassRestore restores[2], DiffusionReport& report) {
  DiffusionSystems& systems = in.systems;
  DiffusionScratch& scratch = in.scratch;
  const Vector& areas = in.geometry.vertexDualAreas;
  const SparseMatrix& system = systems.scalarSystem();
  const int vertices = static_cast<int>(areas.size());
  const double* x0[2] = {in.state.solvent.data(), in.state.solute.data()};
  double mass[2] = {0.0, 0.0};  // written by the restricted solve
  const PairWork work{scratch.densityX.data(), scratch.densityR.data(), scratch.densityP.data()};
  LadderCosts costs;
  if (systems.scalarIterative()) {
    for (int i = 0; i < vertices; ++i) {
      if (x0[0][i] != 0.0 || x0[1][i] != 0.0) active.add(i);
    }
    const int ring = active.grow(system.outerIndexPtr(), system.innerIndexPtr());
    const int stages = systems.scalarStages();
    const int rows = active.size();
    const int iterations = predictedCgIterations(systems.scalarStiffnessRatio());
    costs.rkl = stages > 0 ? rklCost(stages, rows, ring, in.entriesPerRow) : kNever;
    costs.cg = systems.scalarCgAllowed() ? cgCost(iterations, rows, ring, in.entriesPerRow) : kNever;
    costs.direct = systems.solverChoice() == DiffusionSolverChoice::Auto
                       ? directCost(vertices, int(solvent) + int(solute))
                       : kNever;
    costs.considered = true;
  }
  const auto rkl = [&] {
    return rkl2Step<false>(in.geometry.densityStiffness, areas.data(), x0, 1, systems.scalarStages(), in.ctx.h,
                           work.x, work.r, work.p, active, true, mass, scratch.krylovPartials.data());
  };
  const auto cg = [&] {
    return pairConjugateGradients<false>(system.outerIndexPtr(), system.innerIndexPtr(), system.valuePtr(),
                                         systems.scalarInverseDiagonal().data(), areas.data(), x0, 1, work.x,
                                         work.r, work.p, scratch.densityQ.data(), active, mass,
                                         scratch.krylovPartials.data());
  };
  const auto factor = [&] {
    const double solventMass = solvent ? massTimesSummed(areas, in.state.solvent, scratch.solution) : 0.0;
    const double soluteMass = solute ? massTimesSummed(areas, in.state.solute, scratch.rhs) : 0.0;
    const SolverStatus status = systems.solveScalarInPlace(solvent ? scratch.solution : scratch.rhs,
                                                           solvent && solute ? &scratch.rhs : nullptr);
    report.factorizations = systems.factorizationCount() - in.factorizationsBefore;
    if (status != SolverStatus::Ok) return status;
    if (solvent) restores[0] = flushTail(areas, solventMass, scratch.solution);
    if (solute) restores[1] = flushTail(areas, soluteMass, scratch.rhs);
    return status;
  };
  const FieldReport field{report.densityMethod, report.densityIterations, report.densityStages,
                          report.densityPredictedCost, report.densityActiveVertices};
  const LadderResult result = climbLadder(costs, active, work, rkl, cg, factor, field, report.fallbacks);
  if (result.onSupport) flushAndRestoreOnSupport(areas, mass, active, scratch.krylovPartials.data(), work.x);
  return result;
}

// The velocity's ladder, Re and Im as one pair field (velocityX). On the wet
// region (`wet`, a fixed domain whose unmarked neighbours keep their values)
// or, without it, on the velocity's support growing with the solve, when
// vectorIterative() and the caller did not choose the factor: RKL2 or CG
// (on the band with the symmetric Gauss–Seidel preconditioner, on a growing
// support with Jacobi's, which reaches one ring per iteration). By the
// factor: the whole mesh into scratch.complexSolution.
LadderResult diffuseVelocity(const DiffusionInputs& in, const std::vector<char>* wet, bool velocityByFactor,
                             ActiveSet& active, DiffusionReport& report) {
  DiffusionSystems& systems = in.systems;
  DiffusionScratch& scratch = in.scratch;
  const Vector& areas = in.geometry.vertexDualAreas;
  const ComplexSparseMatrix& system = systems.vectorSystem();
  const int vertices = static_cast<int>(areas.size());
  const Complex* u0 = in.state.velocities.data();
  // std::complex<double> is two doubles (re, im) by the standard's array rule.
  const double* u0Pairs = reinterpret_cast<const double*>(u0);
  const double* x0[2] = {u0Pairs, u0Pairs + 1};
  double mass[2] = {0.0, 0.0};  // written by the restricted solve
  const PairWork work{scratch.velocityX.data(), scratch.velocityR.data(), scratch.velocityP.data()};
  LadderCosts costs;
  if (systems.vectorIterative() && !velocityByFactor) {
    int ring = 0;
    if (wet != nullptr) {
      for (int i = 0; i < vertices; ++i) {
        if ((*wet)[static_cast<size_t>(i)]) active.add(i);
      }
    } else {
      for (int i = 0; i < vertices; ++i) {
        if (u0[i] != Complex(0.0)) active.add(i);
      }
      ring = active.grow(system.outerIndexPtr(), system.innerIndexPtr());
    }
    // The band was sized for a restricted solve (StainSolver chose it): the
    // factor is not a candidate here. Without a band the support grows with
    // the solve like the densities', and Auto allows CG only up to their
    // ratio (kIterativeStiffnessRatio); past it the factor solves.
    const bool cgHere = systems.vectorCgAllowed() &&
                        (wet != nullptr || systems.solverChoice() != DiffusionSolverChoice::Auto ||
                         systems.vectorStiffnessRatio() <= kIterativeStiffnessRatio);
    const RestrictedCosts restricted =
        velocityCosts(systems, active.size(), ring, cgHere, in.entriesPerRow, wet != nullptr);
    costs.rkl = restricted.rkl;
    costs.cg = restricted.cg;
    costs.considered = true;
  }
  const auto rkl = [&] {
    return rkl2Step<true>(in.geometry.velocityStiffness, areas.data(), x0, 2, systems.vectorStages(), in.ctx.h,
                          work.x, work.r, work.p, active, wet == nullptr, mass, scratch.krylovPartials.data());
  };
  const auto cg = [&] {
    const int* vo = system.outerIndexPtr();
    const int* vi = system.innerIndexPtr();
    const double* values = reinterpret_cast<const double*>(system.valuePtr());
    const double* inverseDiagonal = systems.vectorInverseDiagonal().data();
    return wet != nullptr
               ? bandConjugateGradients(vo, vi, values, inverseDiagonal, areas.data(), u0Pairs, active, work.x,
                                        work.r, work.p, scratch.velocityT.data(), scratch.velocityQ.data(),
                                        scratch.velocityRows)
               : pairConjugateGradients<true>(vo, vi, values, inverseDiagonal, areas.data(), x0, 2, work.x, work.r,
                                              work.p, scratch.velocityQ.data(), active, mass,
                                              scratch.krylovPartials.data());
  };
  const auto factor = [&] {
    massTimes(areas, in.state.velocities, scratch.complexRhs);
    const SolverStatus status = systems.solveVector(scratch.complexRhs, scratch.complexSolution);
    report.factorizations = systems.factorizationCount() - in.factorizationsBefore;
    return status;
  };
  const FieldReport field{report.velocityMethod, report.velocityIterations, report.velocityStages,
                          report.velocityPredictedCost, report.velocityActiveVertices};
  return climbLadder(costs, active, work, rkl, cg, factor, field, report.fallbacks);
}

// Writes the densities' solution into the state: from densityX on the
// support's rows (the set then released), or else the direct solve's with its
// mass restored, listing the vertices written in DiffusionScratch::directSupport
// (report.directSupportVertices of them: 0 when no density was solved).
// Returns min(0, the least density written), what the limiter tests.
double commitDensities(bool densityOnSupport, bool solvent, bool solute, const MassRestore restores[2],
                       ActiveSet& densityActive, DiffusionScratch& scratch, StainState& state,
                       DiffusionReport& report) {
  double* dx = scratch.densityX.data();
  double minimum = 0.0;
  if (densityOnSupport) {
    const int* list = densityActive.list();
    for (int k = 0; k < densityActive.size(); ++k) {
      const int i = list[k];
      // The pair solve carries σ_s along; it is kept only when asked for
      // (soluteWithSolvent leaves σ_s to carrySoluteWithSolvent).
      state.solvent[i] = dx[2 * i];
      minimum = std::min(minimum, dx[2 * i]);
      if (solute) {
        state.solute[i] = dx[2 * i + 1];
        minimum = std::min(minimum, dx[2 * i + 1]);
      }
    }
    // The CG vectors' invariant: zero outside the active set.
    releaseActive(densityActive, {dx, scratch.densityR.data(), scratch.densityP.data()});
  } else {
    int* listed = scratch.directSupport.data();
    int count = 0;
    if (solvent)
      minimum = std::min(minimum, commitRestored(scratch.solution, restores[0], state.solvent, scratch.directMarks,
                                                 listed, count));
    if (solute)
      minimum = std::min(minimum, commitRestored(scratch.rhs, restores[1], state.solute, scratch.directMarks,
                                                 listed, count));
    for (int k = 0; k < count; ++k) scratch.directMarks[static_cast<size_t>(listed[k])] = 0;
    report.directSupportVertices = count;
  }
  return minimum;
}

}  // namespace

double velocityCostOnBand(const DiffusionSystems& systems, int rows) {
  const SparseMatrix& scalarSystem = systems.scalarSystem();
  const Eigen::Index n = scalarSystem.rows();
  const double entriesPerRow = n > 0 ? static_cast<double>(scalarSystem.nonZeros()) / static_cast<double>(n) : 0.0;
  const RestrictedCosts costs = velocityCosts(systems, rows, 0, systems.vectorCgAllowed(), entriesPerRow, true);
  return std::min(costs.rkl, costs.cg);
}

double velocityCostByFactor(const DiffusionSystems& systems, int addedBandVertices) {
  return directCost(static_cast<int>(systems.scalarSystem().rows()), 2) + kBandVertexCost * addedBandVertices;
}

DiffusionReport diffuse(const StepContext& ctx, const IntrinsicGeometry& geometry,
                        DiffusionSystems& systems, DiffusionScratch& scratch, StainState& state,
                        const std::vector<char>* wet, bool velocityByFactor) {
  DiffusionReport report;
  const PhysicsSwitches& switches = ctx.switches;
  if (!switches.densityDiffusion && !switches.velocityDiffusion) return report;

  const Eigen::Index n = state.solvent.size();
  const Vector& areas = geometry.vertexDualAreas;
  if (!sizesMatch(areas, scratch, state, wet)) {
    report.status = SolverStatus::SizeMismatch;
    return report;
  }
  // The systems belong to one step size; a different h would silently solve
  // another equation.
  if (systems.assembledStep() != ctx.h) {
    report.status = SolverStatus::NotFactorized;
    return report;
  }

  const bool solvent = switches.densityDiffusion && !allZero(state.solvent);
  // With soluteWithSolvent the solvent slot holds the whole free liquid and
  // the solute is carried afterwards (carrySoluteWithSolvent).
  const bool solute = switches.densityDiffusion && !switches.soluteWithSolvent && !allZero(state.solute);
  // With massWeightedViscosity u is diffused afterwards (diffuseFilmVelocity).
  const bool velocity = switches.velocityDiffusion && !switches.massWeightedViscosity && !allZero(state.velocities);
  const SparseMatrix& scalarSystem = systems.scalarSystem();
  const double entriesPerRow = n > 0 ? static_cast<double>(scalarSystem.nonZeros()) / static_cast<double>(n) : 0.0;
  const DiffusionInputs inputs{ctx, geometry, systems, scratch, state, entriesPerRow, systems.factorizationCount()};

  ActiveSet densityActive(scratch.densityActive, scratch.densityMarks);
  MassRestore restores[2];  // solvent, solute (after a direct solve)
  bool densityOnSupport = false;
  if (solvent || solute) {
    const LadderResult densities = diffuseDensities(inputs, solvent, solute, densityActive, restores, report);
    if (densities.status != SolverStatus::Ok) {
      report.status = densities.status;
      return report;
    }
    densityOnSupport = densities.onSupport;
  }
  // A failed velocity solve must leave the densities as they were: undo the
  // CG bookkeeping before returning.
  double* dx = scratch.densityX.data();
  const auto abandonDensities = [&] {
    if (densityOnSupport) releaseActive(densityActive, {dx, scratch.densityR.data(), scratch.densityP.data()});
  };

  ActiveSet velocityActive(scratch.velocityActive, scratch.velocityMarks);
  bool velocityOnBand = false;
  double* ux = scratch.velocityX.data();
  if (velocity) {
    const LadderResult velocities = diffuseVelocity(inputs, wet, velocityByFactor, velocityActive, report);
    if (velocities.status != SolverStatus::Ok) {
      abandonDensities();
      report.status = velocities.status;
      return report;
    }
    velocityOnBand = velocities.onSupport;
  }

  // Commit (copies, not swaps: the state's arrays keep their addresses).
  const double minimum =
      commitDensities(densityOnSupport, solvent, solute, restores, densityActive, scratch, state, report);
  if (velocityOnBand) {
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
    const auto [count, mass] = densityOnSupport ? limit(rings, areas, *field, densityActive.list(), densityActive.size())
                                           : limit(rings, areas, *field);
    report.limiterCorrectedVertices += count;
    report.limiterMovedMass += mass;
  }
  return report;
}

}  // namespace blot::stain
