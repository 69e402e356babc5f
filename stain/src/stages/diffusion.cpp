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

namespace blot::stain {
namespace {

// See pairConjugateGradients: the Krylov support stops growing while the
// outermost ring's next correction is below this fraction of the flush level.
constexpr double kGrowthFraction = 0.1;

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

// `candidates` (optional, `candidateCount` vertices): the only vertices that
// can be negative (a CG solve's active set), visited in that order instead of
// scanning all of them in index order.
template <typename Rings>
std::pair<int, double> limit(const Rings& rings, const Vector& dualAreas, Vector& densities,
                             const int* candidates = nullptr, int candidateCount = 0) {
  const int n = static_cast<int>(densities.size());
  double* sigma = densities.data();
  const double* area = dualAreas.data();
  const int visits = candidates != nullptr ? candidateCount : n;
  int corrected = 0;
  for (int v = 0; v < visits; ++v) corrected += sigma[candidates != nullptr ? candidates[v] : v] < 0.0 ? 1 : 0;
  if (corrected == 0) return {0, 0.0};

  double moved = 0.0;
  bool remaining = false;
  int visited[kLimiterSearchBudget];  // the search region, ring by ring (no allocation)
  SearchSet seen;
  for (int v = 0; v < visits; ++v) {
    const int i = candidates != nullptr ? candidates[v] : v;
    if (!(sigma[i] < 0.0)) continue;       // the common case: one comparison
    double deficit = -area[i] * sigma[i];  // kg
    sigma[i] = 0.0;
    {
      // Fast path, bit for bit the first ring of the search below: the ring's
      // entries other than i are distinct (a matrix column), so no visited set
      // is needed when the first ring covers the deficit, as it does for
      // almost every fix (7K per step on the 35K grid of stain_step_bench).
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


// The vertices a restricted Krylov solve works on: a breadth-first list
// (capacity #V, no allocation) with a membership mark per vertex, grown one
// ring at a time along the matrix pattern (= the one-ring for P1 operators).
class ActiveSet {
 public:
  ActiveSet(std::vector<int>& list, std::vector<char>& marks) : list_(list.data()), marks_(marks.data()) {}
  void add(int v) {
    if (!marks_[v]) {
      marks_[v] = 1;
      list_[size_++] = v;
    }
  }
  /// Adds every unmarked neighbour of the outermost layer (the whole set the
  /// first time); returns how many were added.
  int grow(const int* outer, const int* inner) {
    const int begin = layerBegin_, end = size_;
    layerBegin_ = end;
    for (int k = begin; k < end; ++k) {
      const int i = list_[k];
      for (int p = outer[i]; p < outer[i + 1]; ++p) add(inner[p]);
    }
    return size_ - end;
  }
  /// Removes the marks (the list's contents stay readable until the next add).
  void clearMarks() {
    for (int k = 0; k < size_; ++k) marks_[list_[k]] = 0;
  }
  int size() const { return size_; }
  const int* list() const { return list_; }
  /// Start of the outermost layer (the last ring grow() added) in list().
  int layerBegin() const { return layerBegin_; }

 private:
  int* list_;
  char* marks_;
  int size_ = 0, layerBegin_ = 0;
};

struct KrylovOutcome {
  int iterations = 0;
  bool converged = false;
  bool finite = true;  ///< false: a non-finite right-hand side (the caller reports NonFinite)
};

// Jacobi-PCG on pairs: every vector holds two numbers per vertex (v[2i],
// v[2i + 1]). kComplex = false: two independent real systems A x_c = M x0_c
// (solvent and solute) sharing each pass over A, each with its own α, β and
// stopping test. kComplex = true: one Hermitian system on (Re, Im); column i
// holds A(j, i) = conj(A(i, j)), so row i of A p is Σ conj(a) p_j over column
// i, and α, β use the sums over both components (Re pᴴq = p·q on pairs).
// Runs on the active set `active` (seeded by the caller with every row whose
// residual can be non-zero); with `grow`, each iteration first adds the next
// ring (the support of A p), otherwise the active rows are a fixed domain.
// x0 (component c of vertex j at x0[c][j * x0Stride]) is read at every
// neighbour of the active rows: zeros or fixed (Dirichlet) values outside.
// x, r, p must be zero outside `active` on entry; x is written on the active
// rows only. mass[c] = compensated Σ_{active} A_i x0_c,i.
// Runs body(begin, end, sums) over the active rows [0, count) in fixed chunks
// of kKrylovChunkRows, on OpenMP threads from kKrylovParallelRows rows on;
// each chunk's kSums partial sums go to partials[chunk * kSums + s] and are
// added in chunk order into total. The chunking depends on count only, so
// the sums (and the whole solve) are the same to the bit for any thread
// count, threaded or not; with one chunk it is the plain serial sum.
template <int kSums, typename Body>
void chunkedSums(int count, double* partials, double total[kSums], const Body& body) {
  const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
#pragma omp parallel for schedule(static) if (count >= kKrylovParallelRows)
  for (int c = 0; c < chunks; ++c) {
    double sums[kSums] = {};
    body(c * kKrylovChunkRows, std::min(count, (c + 1) * kKrylovChunkRows), sums);
    for (int k = 0; k < kSums; ++k) partials[c * kSums + k] = sums[k];
  }
  for (int k = 0; k < kSums; ++k) total[k] = 0.0;
  for (int c = 0; c < chunks; ++c) {
    for (int k = 0; k < kSums; ++k) total[k] += partials[c * kSums + k];
  }
}

// Jacobi-PCG on pairs: every vector holds two numbers per vertex (v[2i],
// v[2i + 1]). kComplex = false: two independent real systems A x_c = M x0_c
// (solvent and solute) sharing each pass over A, each with its own α, β and
// stopping test. kComplex = true: one Hermitian system on (Re, Im); column i
// holds A(j, i) = conj(A(i, j)), so row i of A p is Σ conj(a) p_j over column
// i, and α, β use the sums over both components (Re pᴴq = p·q on pairs).
// Runs on the active set `active` (seeded by the caller with every row whose
// residual can be non-zero); with `grow`, each iteration first adds the next
// ring (the support of A p), otherwise the active rows are a fixed domain.
// x0 (component c of vertex j at x0[c][j * x0Stride]) is read at every
// neighbour of the active rows: zeros or fixed (Dirichlet) values outside.
// x, r, p must be zero outside `active` on entry; x is written on the active
// rows only. mass[c] = compensated Σ_{active} A_i x0_c,i. `partials`: room
// for kKrylovPartialsPerChunk numbers per chunk of the largest active set
// (chunkedSums). Every row loop writes only its own rows, and reads of p at
// neighbours happen in the product loop, which writes q only.
template <bool kComplex>
KrylovOutcome pairConjugateGradients(const int* outer, const int* inner, const double* values,
                                     const double* inverseDiagonal, const double* area, const double* const x0[2],
                                     int x0Stride, double* __restrict x, double* __restrict r,
                                     double* __restrict p, double* __restrict q, ActiveSet& active, bool grow,
                                     double mass[2], double* partials) {
  KrylovOutcome outcome;
  double rz[2] = {0, 0}, rr[2] = {0, 0}, bb[2] = {0, 0}, largest[2] = {0, 0};
  {
    const int* list = active.list();
    const int count = active.size();
    // Per chunk: rz, rr, bb (two each), the two compensated masses as (sum,
    // compensation) and the two largest |x0| (max: order-free).
    double sums[kKrylovPartialsPerChunk];
    chunkedSums<kKrylovPartialsPerChunk>(count, partials, sums, [&](int begin, int end, double* out) {
      CompensatedSum massSum[2];
      double top0 = 0.0, top1 = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        double a0 = 0.0, a1 = 0.0;  // (A x0)_i
        for (int e = outer[i]; e < outer[i + 1]; ++e) {
          const size_t j = static_cast<size_t>(inner[e]) * static_cast<size_t>(x0Stride);
          if (kComplex) {
            const double re = values[2 * e], im = values[2 * e + 1];
            a0 += re * x0[0][j] + im * x0[1][j];
            a1 += re * x0[1][j] - im * x0[0][j];
          } else {
            a0 += values[e] * x0[0][j];
            a1 += values[e] * x0[1][j];
          }
        }
        const size_t ii = static_cast<size_t>(i) * static_cast<size_t>(x0Stride);
        const double invD = inverseDiagonal[i];
        const double v0 = x0[0][ii], v1 = x0[1][ii];
        const double b0 = area[i] * v0, b1 = area[i] * v1;
        const double r0 = b0 - a0, r1 = b1 - a1;
        x[2 * i] = v0;
        x[2 * i + 1] = v1;
        r[2 * i] = r0;
        r[2 * i + 1] = r1;
        p[2 * i] = invD * r0;
        p[2 * i + 1] = invD * r1;
        out[0] += invD * r0 * r0;
        out[1] += invD * r1 * r1;
        out[2] += r0 * r0;
        out[3] += r1 * r1;
        out[4] += b0 * b0;
        out[5] += b1 * b1;
        massSum[0].add(b0);
        massSum[1].add(b1);
        top0 = std::max(top0, std::abs(v0));
        top1 = std::max(top1, std::abs(v1));
      }
      out[6] = massSum[0].value();
      out[7] = massSum[1].value();
      out[8] = top0;
      out[9] = top1;
    });
    rz[0] = sums[0], rz[1] = sums[1], rr[0] = sums[2], rr[1] = sums[3], bb[0] = sums[4], bb[1] = sums[5];
    // The masses and maxima are combined from the chunks' own values, not
    // the plain sums chunkedSums made of them.
    const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
    CompensatedSum massSum[2];
    for (int c = 0; c < chunks; ++c) {
      const double* chunk = partials + c * kKrylovPartialsPerChunk;
      massSum[0].add(chunk[6]);
      massSum[1].add(chunk[7]);
      largest[0] = std::max(largest[0], chunk[8]);
      largest[1] = std::max(largest[1], chunk[9]);
    }
    mass[0] = massSum[0].value();
    mass[1] = massSum[1].value();
  }
  if (kComplex) largest[0] = largest[1] = std::max(largest[0], largest[1]);
  // Growth stops while the next correction on the outermost ring, D⁻¹r, is
  // below kGrowthFraction × kIterativeTolerance × max |x0|: what it would add
  // further out is smaller still and would be flushed anyway (design note).
  const double growthFloor[2] = {kGrowthFraction * kIterativeTolerance * largest[0],
                                 kGrowthFraction * kIterativeTolerance * largest[1]};
  if (!std::isfinite(bb[0] + bb[1] + rr[0] + rr[1])) {
    outcome.finite = false;
    return outcome;
  }
  if (kComplex) {  // one system: combined sums in slot 0
    rz[0] += rz[1];
    rr[0] += rr[1];
    bb[0] += bb[1];
  }
  const int systems = kComplex ? 1 : 2;
  const double tolerance2 = kIterativeTolerance * kIterativeTolerance;
  bool done[2] = {rr[0] <= tolerance2 * bb[0], kComplex || rr[1] <= tolerance2 * bb[1]};
  for (int iteration = 1; iteration <= kMaxIterations; ++iteration) {
    if (done[0] && done[1]) {
      outcome.converged = true;
      return outcome;
    }
    if (grow) {
      bool reaches = false;
      for (int k = active.layerBegin(); k < active.size() && !reaches; ++k) {
        const int i = active.list()[k];
        reaches = std::abs(inverseDiagonal[i] * r[2 * i]) >= growthFloor[0] ||
                  std::abs(inverseDiagonal[i] * r[2 * i + 1]) >= growthFloor[1];
      }
      if (reaches) active.grow(outer, inner);
    }
    const int* list = active.list();
    const int count = active.size();
    // q = A p on the active rows, and pᵀq per component.
    double pq[2];
    chunkedSums<2>(count, partials, pq, [&](int begin, int end, double* out) {
      double pq0 = 0.0, pq1 = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        // Two partial sums per component (even and odd entries): halves the
        // chain of dependent additions that bounds this loop.
        double s0 = 0.0, s1 = 0.0, t0 = 0.0, t1 = 0.0;
        const int rowBegin = outer[i], rowEnd = outer[i + 1];
        int e = rowBegin;
        for (; e + 1 < rowEnd; e += 2) {
          const int j = inner[e], l = inner[e + 1];
          if (kComplex) {
            const double re = values[2 * e], im = values[2 * e + 1];
            const double re2 = values[2 * e + 2], im2 = values[2 * e + 3];
            s0 += re * p[2 * j] + im * p[2 * j + 1];
            s1 += re * p[2 * j + 1] - im * p[2 * j];
            t0 += re2 * p[2 * l] + im2 * p[2 * l + 1];
            t1 += re2 * p[2 * l + 1] - im2 * p[2 * l];
          } else {
            s0 += values[e] * p[2 * j];
            s1 += values[e] * p[2 * j + 1];
            t0 += values[e + 1] * p[2 * l];
            t1 += values[e + 1] * p[2 * l + 1];
          }
        }
        if (e < rowEnd) {
          const int j = inner[e];
          if (kComplex) {
            const double re = values[2 * e], im = values[2 * e + 1];
            s0 += re * p[2 * j] + im * p[2 * j + 1];
            s1 += re * p[2 * j + 1] - im * p[2 * j];
          } else {
            s0 += values[e] * p[2 * j];
            s1 += values[e] * p[2 * j + 1];
          }
        }
        s0 += t0;
        s1 += t1;
        q[2 * i] = s0;
        q[2 * i + 1] = s1;
        pq0 += p[2 * i] * s0;
        pq1 += p[2 * i + 1] * s1;
      }
      out[0] = pq0;
      out[1] = pq1;
    });
    if (kComplex) pq[0] += pq[1];
    double alpha[2] = {0.0, 0.0};
    for (int c = 0; c < systems; ++c) {
      if (done[c]) continue;
      alpha[c] = rz[c] / pq[c];
      if (!(pq[c] > 0.0) || !std::isfinite(alpha[c])) return outcome;  // breakdown: not converged
    }
    if (kComplex) alpha[1] = alpha[0];
    // x += α p, r −= α q, and the new rᵀD⁻¹r, rᵀr per component.
    double next[4];
    chunkedSums<4>(count, partials, next, [&](int begin, int end, double* out) {
      double z0 = 0.0, z1 = 0.0, s0 = 0.0, s1 = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        x[2 * i] += alpha[0] * p[2 * i];
        x[2 * i + 1] += alpha[1] * p[2 * i + 1];
        const double r0 = r[2 * i] - alpha[0] * q[2 * i];
        const double r1 = r[2 * i + 1] - alpha[1] * q[2 * i + 1];
        r[2 * i] = r0;
        r[2 * i + 1] = r1;
        z0 += inverseDiagonal[i] * r0 * r0;
        z1 += inverseDiagonal[i] * r1 * r1;
        s0 += r0 * r0;
        s1 += r1 * r1;
      }
      out[0] = z0;
      out[1] = z1;
      out[2] = s0;
      out[3] = s1;
    });
    double nextRz[2] = {next[0], next[1]}, nextRr[2] = {next[2], next[3]};
    if (kComplex) {
      nextRz[0] += nextRz[1];
      nextRr[0] += nextRr[1];
    }
    double beta[2] = {0.0, 0.0};
    for (int c = 0; c < systems; ++c) {
      if (!done[c] && rz[c] != 0.0) beta[c] = nextRz[c] / rz[c];
      if (!done[c]) {
        rz[c] = nextRz[c];
        rr[c] = nextRr[c];
      }
    }
    if (kComplex) beta[1] = beta[0];
    // p = D⁻¹ r + β p (no sums).
    const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
#pragma omp parallel for schedule(static) if (count >= kKrylovParallelRows)
    for (int c = 0; c < chunks; ++c) {
      const int end = std::min(count, (c + 1) * kKrylovChunkRows);
      for (int k = c * kKrylovChunkRows; k < end; ++k) {
        const int i = list[k];
        const double invD = inverseDiagonal[i];
        p[2 * i] = invD * r[2 * i] + beta[0] * p[2 * i];
        p[2 * i + 1] = invD * r[2 * i + 1] + beta[1] * p[2 * i + 1];
      }
    }
    outcome.iterations = iteration;
    for (int c = 0; c < systems; ++c) {
      if (!std::isfinite(rr[c])) return outcome;
      done[c] = done[c] || rr[c] <= tolerance2 * bb[c];
    }
  }
  outcome.converged = done[0] && done[1];
  return outcome;
}

// Zeroes pair vectors (two numbers per vertex) on the active rows, their
// invariant between calls, and removes the marks.
void releaseActive(ActiveSet& active, std::initializer_list<double*> vectors) {
  const int* list = active.list();
  for (double* v : vectors) {
    for (int k = 0; k < active.size(); ++k) {
      v[2 * list[k]] = 0.0;
      v[2 * list[k] + 1] = 0.0;
    }
  }
  active.clearMarks();
}

inline double realPart(double v) { return v; }
inline double realPart(const Complex& v) { return v.real(); }

// 1 / diagonal of a compressed system, and max_i (A_ii / A_i − 1) = h L_ii / A_i.
template <typename Scalar>
double inverseDiagonal(const Eigen::SparseMatrix<Scalar>& system, const Vector& areas, Vector& inverse) {
  const int n = static_cast<int>(system.cols());
  inverse.resize(n);
  double ratio = 0.0;
  for (int j = 0; j < n; ++j) {
    double diagonal = 0.0;
    for (int p = system.outerIndexPtr()[j]; p < system.outerIndexPtr()[j + 1]; ++p) {
      if (system.innerIndexPtr()[p] == j) diagonal = realPart(system.valuePtr()[p]);
    }
    inverse[j] = diagonal > 0.0 ? 1.0 / diagonal : 0.0;
    ratio = std::max(ratio, diagonal / areas[j] - 1.0);
  }
  return ratio;
}

}  // namespace

DiffusionSystems::DiffusionSystems() = default;

void DiffusionSystems::releaseFactors() {
  scalar_.releaseFactor();
  vector_.releaseFactor();
  h_ = 0;  // diffuse() refuses to run until the systems are factorized again
}

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
  // Method per system from its conditioning (see the design note).
  const auto iterative = [&](double ratio) {
    return choice_ == DiffusionSolverChoice::Iterative ||
           (choice_ == DiffusionSolverChoice::Auto && ratio <= kIterativeStiffnessRatio);
  };
  scalarRatio_ = inverseDiagonal(scalarSystem_, areas, scalarInverseDiagonal_);
  scalarIterative_ = iterative(scalarRatio_);
  if (vectorStiffness.rows() != 0) {
    vectorRatio_ = inverseDiagonal(vectorSystem_, areas, vectorInverseDiagonal_);
    vectorIterative_ = iterative(vectorRatio_);
  } else {
    vectorIterative_ = false;
  }
  return scalarStatus != SolverStatus::Ok ? scalarStatus : vectorStatus;
}

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

std::pair<int, double> limitPositivity(const SurfaceTopology& topology, const Vector& dualAreas,
                                       Vector& densities) {
  return limit(TopologyRings{topology}, dualAreas, densities);
}

}  // namespace blot::stain
