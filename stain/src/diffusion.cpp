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
#include <blot/stain/diffusion.h>

#include <algorithm>
#include <cmath>

namespace blot::stain {
namespace {

// Most vertices the limiter's ring-by-ring search around one negative vertex
// may visit (about 8 rings on a regular mesh) before the global fallback.
constexpr int kLimiterSearchBudget = 256;

// Refills `system` = M + h L in place. `system`'s pattern must contain L's
// and the diagonal; entries of `system` that L lacks get only the mass.
// Returns false if L has an entry `system` lacks (its pattern changed).
template <typename Scalar>
bool fillSystem(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& dualAreas, double h,
                Eigen::SparseMatrix<Scalar>& system) {
  if (system.rows() != stiffness.rows() || system.cols() != stiffness.cols() || !system.isCompressed()) {
    return false;
  }
  const int n = static_cast<int>(system.cols());
  const int* sOuter = system.outerIndexPtr();
  const int* sInner = system.innerIndexPtr();
  Scalar* sValues = system.valuePtr();
  const int* lOuter = stiffness.outerIndexPtr();
  const int* lInner = stiffness.innerIndexPtr();
  const int* lNonZeros = stiffness.isCompressed() ? nullptr : stiffness.innerNonZeroPtr();
  const Scalar* lValues = stiffness.valuePtr();
  for (int j = 0; j < n; ++j) {
    int q = lOuter[j];
    const int qEnd = lNonZeros ? lOuter[j] + lNonZeros[j] : lOuter[j + 1];
    bool hasDiagonal = false;
    for (int p = sOuter[j]; p < sOuter[j + 1]; ++p) {
      const int row = sInner[p];
      Scalar value(0);
      if (q < qEnd && lInner[q] == row) {
        value = h * lValues[q];
        ++q;
      } else if (q < qEnd && lInner[q] < row) {
        return false;  // L has an entry the system lacks.
      }
      if (row == j) {
        value += Scalar(dualAreas[j]);
        hasDiagonal = true;
      }
      sValues[p] = value;
    }
    if (q != qEnd || !hasDiagonal) return false;
  }
  return true;
}

// Builds the pattern of M + h L (L's pattern plus the diagonal) and fills it.
template <typename Scalar>
void buildSystem(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& dualAreas, double h,
                 Eigen::SparseMatrix<Scalar>& system) {
  Eigen::SparseMatrix<Scalar> diagonal(stiffness.rows(), stiffness.cols());
  diagonal.setIdentity();
  system = stiffness + diagonal;  // union pattern, explicit zeros kept
  system.makeCompressed();
  fillSystem(stiffness, dualAreas, h, system);
}

template <typename A, typename B>
bool samePattern(const Eigen::SparseMatrix<A>& a, const Eigen::SparseMatrix<B>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros()) return false;
  if (!a.isCompressed() || !b.isCompressed()) return false;
  return std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.cols() + 1, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
}

template <typename Scalar>
bool allZero(const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v) {
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    if (v[i] != Scalar(0)) return false;
  }
  return true;
}

// rhs_i = A_i x_i. Serial on purpose: one multiply per vertex is memory-bound
// and costs ~1 % of the solve it feeds; an OpenMP region costs more than it
// saves below ~10^5 vertices (and libgomp allocates on every region it starts).
template <typename Scalar>
void massTimes(const Vector& dualAreas, const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& x,
               Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& rhs) {
  rhs = dualAreas.cast<Scalar>().cwiseProduct(x);
}

// Σ x_i in index order with Neumaier's compensation: the sum's own rounding
// stays at ~1 ulp whatever #V, so the mass fix below does not drift by
// ~sqrt(#V) ε per step.
class CompensatedSum {
 public:
  void add(double x) {
    const double t = sum_ + x;
    compensation_ += std::abs(sum_) >= std::abs(x) ? (sum_ - t) + x : (x - t) + sum_;
    sum_ = t;
  }
  double value() const { return sum_ + compensation_; }

 private:
  double sum_ = 0.0, compensation_ = 0.0;
};

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

// Neighbours of vertex i as a half-open range of vertex indices (may contain i
// itself, which the limiter skips).
struct NeighborRange {
  const int* begin;
  const int* end;
};

// One-ring from the topology's CSR rings.
struct TopologyRings {
  const SurfaceTopology& topology;
  NeighborRange operator()(int i) const {
    const int* data = topology.ringNeighbors().data();
    return {data + topology.ringOffsets()[static_cast<size_t>(i)],
            data + topology.ringOffsets()[static_cast<size_t>(i) + 1]};
  }
};

// Operator neighbours: the column pattern of the (symmetric) stiffness matrix.
struct MatrixRings {
  const SparseMatrix& matrix;
  NeighborRange operator()(int i) const {
    const int* inner = matrix.innerIndexPtr();
    const int begin = matrix.outerIndexPtr()[i];
    const int end =
        matrix.isCompressed() ? matrix.outerIndexPtr()[i + 1] : begin + matrix.innerNonZeroPtr()[i];
    return {inner + begin, inner + end};
  }
};

// The set of vertices one limiter search has visited: open addressing on the
// stack, with a stamp per search so it is never cleared (no allocation, O(1)
// membership, which a linear scan of the visited list is not once the search
// passes the first ring).
class SearchSet {
 public:
  SearchSet() {
    for (Slot& slot : slots_) slot = {-1, -1};
  }
  void restart() { ++stamp_; }
  /// Inserts v; false if it was already in this search.
  bool insert(int v) {
    unsigned h = (static_cast<unsigned>(v) * 2654435761u) >> (32 - kBits);
    while (slots_[h].stamp == stamp_) {
      if (slots_[h].vertex == v) return false;
      h = (h + 1) & (kCapacity - 1);
    }
    slots_[h] = {v, stamp_};
    return true;
  }

 private:
  static constexpr int kBits = 9;
  static constexpr int kCapacity = 1 << kBits;  // 2 × kLimiterSearchBudget: load ≤ ½
  static_assert(kCapacity >= 2 * kLimiterSearchBudget, "search set too small");
  struct Slot {
    int vertex, stamp;
  };
  Slot slots_[kCapacity];
  int stamp_ = 0;
};

template <typename Rings>
std::pair<int, double> limit(const Rings& rings, const Vector& dualAreas, Vector& densities) {
  const int n = static_cast<int>(densities.size());
  double* sigma = densities.data();
  const double* area = dualAreas.data();
  int corrected = 0;
  for (int i = 0; i < n; ++i) corrected += sigma[i] < 0.0 ? 1 : 0;
  if (corrected == 0) return {0, 0.0};

  double moved = 0.0;
  bool remaining = false;
  int visited[kLimiterSearchBudget];  // the search region, ring by ring (no allocation)
  SearchSet seen;
  for (int i = 0; i < n; ++i) {
    if (!(sigma[i] < 0.0)) continue;       // the common case: one comparison
    double deficit = -area[i] * sigma[i];  // kg
    sigma[i] = 0.0;
    {
      // Fast path, bit for bit the first ring of the search below: the ring's
      // entries other than i are distinct (a matrix column), so no visited set
      // is needed when the first ring covers the deficit, as it does for
      // almost every fix (7K per step on the 35K grid of issue 4's bench).
      const NeighborRange ring = rings(i);
      double available = 0.0;
      for (const int* j = ring.begin; j != ring.end; ++j) {
        if (*j != i && sigma[*j] > 0.0) available += area[*j] * sigma[*j];
      }
      if (ring.end - ring.begin < kLimiterSearchBudget && available > 0.0 && available >= deficit) {
        const double keep = 1.0 - deficit / available;
        for (const int* j = ring.begin; j != ring.end; ++j) {
          if (*j != i && sigma[*j] > 0.0) sigma[*j] *= keep;
        }
        moved += deficit;
        continue;
      }
    }
    seen.restart();
    seen.insert(i);
    visited[0] = i;
    int size = 1, levelBegin = 0;
    bool full = false;
    while (deficit > 0.0 && !full) {
      // The next ring: unvisited neighbours of the current one.
      const int levelEnd = size;
      for (int k = levelBegin; k < levelEnd && !full; ++k) {
        const NeighborRange ring = rings(visited[k]);
        for (const int* j = ring.begin; j != ring.end; ++j) {
          if (size == kLimiterSearchBudget) {
            full = true;
            break;
          }
          if (seen.insert(*j)) visited[size++] = *j;
        }
      }
      if (size == levelEnd) break;  // nothing further: the component is exhausted
      double available = 0.0;       // kg held by positive vertices of this ring
      for (int k = levelEnd; k < size; ++k) {
        if (sigma[visited[k]] > 0.0) available += area[visited[k]] * sigma[visited[k]];
      }
      if (available > 0.0) {
        const double taken = std::min(deficit, available);
        const double keep = 1.0 - taken / available;  // exactly 0 when all of it is taken
        for (int k = levelEnd; k < size; ++k) {
          if (sigma[visited[k]] > 0.0) sigma[visited[k]] *= keep;
        }
        deficit -= taken;
        moved += taken;
      }
      levelBegin = levelEnd;
    }
    if (deficit > 0.0) {
      sigma[i] = -deficit / area[i];
      remaining = true;
    }
  }
  if (!remaining) return {corrected, moved};

  // Global fallback, proportional to the mass each positive vertex holds.
  double deficit = 0.0, available = 0.0;
  for (int i = 0; i < n; ++i) {
    if (sigma[i] < 0.0) deficit -= area[i] * sigma[i];
    if (sigma[i] > 0.0) available += area[i] * sigma[i];
  }
  if (deficit == 0.0) return {corrected, moved};
  if (available >= deficit) {
    const double keep = 1.0 - deficit / available;
    for (int i = 0; i < n; ++i) sigma[i] = sigma[i] < 0.0 ? 0.0 : sigma[i] * keep;
    moved += deficit;
  } else {
    // The field's total is negative: no positive solution has this mass.
    // Conserve it anyway (spread the net negative mass over the negatives).
    const double keep = 1.0 - available / deficit;
    for (int i = 0; i < n; ++i) sigma[i] = sigma[i] > 0.0 ? 0.0 : sigma[i] * keep;
    moved += available;
  }
  return {corrected, moved};
}

}  // namespace

DiffusionSystems::DiffusionSystems() = default;

SolverStatus DiffusionSystems::factorize(const IntrinsicGeometry& geometry, double h) {
  const Vector& areas = geometry.vertexDualAreas;
  const SparseMatrix& scalarStiffness = geometry.densityStiffness;
  const ComplexSparseMatrix& vectorStiffness = geometry.velocityStiffness;
  if (scalarStiffness.rows() != areas.size() || scalarStiffness.cols() != areas.size()) {
    return SolverStatus::SizeMismatch;
  }
  h_ = h;
  ++factorizations_;

  bool scalarPatternChanged = false;
  if (!fillSystem(scalarStiffness, areas, h, scalarSystem_)) {
    buildSystem(scalarStiffness, areas, h, scalarSystem_);
    scalarPatternChanged = true;
  }
  if (scalarPatternChanged || !scalar_.isAnalyzed()) {
    const SolverStatus status = scalar_.analyzePattern(scalarSystem_);
    if (status != SolverStatus::Ok) return status;
  }
  const SolverStatus scalarStatus = scalar_.factorize(scalarSystem_);

  // The connection system: absent (0 x 0) when the geometry has no velocity
  // operator; then velocity diffusion reports NotAnalyzed.
  SolverStatus vectorStatus = SolverStatus::Ok;
  if (vectorStiffness.rows() != 0) {
    if (vectorStiffness.rows() != areas.size() || vectorStiffness.cols() != areas.size()) {
      return SolverStatus::SizeMismatch;
    }
    bool vectorPatternChanged = false;
    if (!fillSystem(vectorStiffness, areas, h, vectorSystem_)) {
      buildSystem(vectorStiffness, areas, h, vectorSystem_);
      vectorPatternChanged = true;
    }
    if (vectorPatternChanged || scalarPatternChanged || !vector_.isAnalyzed()) {
      // Same pattern as the scalar system (both are P1 one-ring operators):
      // copy its ordering and symbolic factor instead of analysing again.
      const SolverStatus status = samePattern(vectorSystem_, scalarSystem_)
                                      ? vector_.shareAnalysisFrom(scalar_)
                                      : vector_.analyzePattern(vectorSystem_);
      if (status != SolverStatus::Ok) return status;
    }
    vectorStatus = vector_.factorize(vectorSystem_);
  }
  return scalarStatus != SolverStatus::Ok ? scalarStatus : vectorStatus;
}

void DiffusionScratch::resize(int vertexCount) {
  rhs.setZero(vertexCount);
  solution.setZero(vertexCount);
  complexRhs.setZero(vertexCount);
  complexSolution.setZero(vertexCount);
}

DiffusionReport diffuse(const StepContext& ctx, const IntrinsicGeometry& geometry,
                        const DiffusionSystems& systems, DiffusionScratch& scratch, StainState& state) {
  DiffusionReport report;
  const PhysicsSwitches& switches = ctx.switches;
  if (!switches.densityDiffusion && !switches.velocityDiffusion) return report;

  const Eigen::Index n = state.solvent.size();
  const Vector& areas = geometry.vertexDualAreas;
  if (areas.size() != n || state.solute.size() != n || state.velocities.size() != n ||
      scratch.rhs.size() != n || scratch.solution.size() != n || scratch.complexRhs.size() != n ||
      scratch.complexSolution.size() != n) {
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

  // Solve into scratch: σ_f -> solution, σ_s -> rhs (in place), u -> complexSolution.
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
  if (velocity) {
    massTimes(areas, state.velocities, scratch.complexRhs);
    report.status = systems.vectorSolver().solve(scratch.complexRhs, scratch.complexSolution);
    if (report.status != SolverStatus::Ok) return report;
  }

  // Commit (copies, not swaps: the state's arrays keep their addresses).
  if (solvent) state.solvent = scratch.solution;
  if (solute) state.solute = scratch.rhs;
  if (velocity) state.velocities = scratch.complexSolution;
  if (!solvent && !solute) return report;

  double minimum = 0.0;
  if (solvent) minimum = std::min(minimum, state.solvent.minCoeff());
  if (solute) minimum = std::min(minimum, state.solute.minCoeff());
  report.minDensityBeforeLimiter = minimum;
  if (!switches.positivityLimiter || minimum >= 0.0) return report;

  const MatrixRings rings{geometry.densityStiffness};
  for (Vector* field : {solvent ? &state.solvent : nullptr, solute ? &state.solute : nullptr}) {
    if (field == nullptr) continue;
    const auto [count, mass] = limit(rings, areas, *field);
    report.limiterCorrectedVertices += count;
    report.limiterMovedMass += mass;
  }
  return report;
}

std::pair<int, double> limitPositivity(const SurfaceTopology& topology, const Vector& dualAreas,
                                       Vector& densities) {
  return limit(TopologyRings{topology}, dualAreas, densities);
}

}  // namespace blot::stain
