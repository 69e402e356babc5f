// Sparse Cholesky on CHOLMOD, split into analysis / numeric factorization / solve.
//
// Design note: docs/design-notes.md, "stain/src/numerics/sparse_solver.cpp".
#include <blot/stain/numerics/sparse_solver.h>

#include <cholmod.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace blot::stain {

namespace cholmod_detail {

// From this many unknowns on, nested dissection is tried beside AMD.
constexpr int kNestedDissectionMinRows = 20000;

template <typename Scalar>
struct ScalarTraits;

template <>
struct ScalarTraits<double> {
  static constexpr int xtype = CHOLMOD_REAL;
  static bool isFinite(double value) { return std::isfinite(value); }
};

template <>
struct ScalarTraits<Complex> {
  // std::complex<double> is laid out as {re, im}: CHOLMOD_COMPLEX, interleaved.
  static constexpr int xtype = CHOLMOD_COMPLEX;
  static bool isFinite(const Complex& value) {
    return std::isfinite(value.real()) && std::isfinite(value.imag());
  }
};

// Everything that does not depend on the scalar type.
struct SolverCore {
  explicit SolverCore(FactorKind factorKind) : kind(factorKind) {
    cholmod_start(&common);
    common.print = 0;  // silent: every failure is returned as a SolverStatus.
    // Orderings tried by analyzeStoredPattern: method[0] = AMD (or the given
    // permutation), method[1] = NESDIS with CHOLMOD's default parameters.
    common.method[1].ordering = CHOLMOD_NESDIS;
    common.final_ll = 1;  // simplicial LLᵀ: detects non-positive pivots itself.
    common.quick_return_if_not_posdef = 1;
    switch (kind) {
      case FactorKind::Simplicial: common.supernodal = CHOLMOD_SIMPLICIAL; break;
      case FactorKind::Supernodal: common.supernodal = CHOLMOD_SUPERNODAL; break;
      case FactorKind::Auto: common.supernodal = CHOLMOD_AUTO; break;
    }
  }
  ~SolverCore() {
    freeNumeric();
    cholmod_free_factor(&symbolic, &common);
    cholmod_free_dense(&solution, &common);
    cholmod_free_dense(&workspaceY, &common);
    cholmod_free_dense(&workspaceE, &common);
    cholmod_finish(&common);
  }
  SolverCore(const SolverCore&) = delete;
  SolverCore& operator=(const SolverCore&) = delete;

  void freeNumeric() {
    cholmod_free_factor(&factor, &common);
    factorized = false;
  }
  void resetAnalysis() {
    freeNumeric();
    cholmod_free_factor(&symbolic, &common);
    n = 0;
    lowerColumnStarts.clear();
    lowerRowIndices.clear();
  }

  // Pattern-only, lower-triangle view of the stored analysed pattern.
  cholmod_sparse lowerPatternView() {
    cholmod_sparse view{};
    view.nrow = static_cast<size_t>(n);
    view.ncol = static_cast<size_t>(n);
    view.nzmax = lowerRowIndices.size();
    view.p = lowerColumnStarts.data();
    view.i = lowerRowIndices.data();
    view.stype = -1;
    view.itype = CHOLMOD_INT;
    view.xtype = CHOLMOD_PATTERN;
    view.dtype = CHOLMOD_DOUBLE;
    view.sorted = 1;
    view.packed = 1;
    return view;
  }

  // Symbolic analysis of the stored pattern; givenPermutation = nullptr lets AMD
  // (and NESDIS, for large n) order it, otherwise that ordering is used as is.
  SolverStatus analyzeStoredPattern(int* givenPermutation) {
    cholmod_sparse pattern = lowerPatternView();
    if (givenPermutation != nullptr) {
      common.nmethods = 1;
      common.method[0].ordering = CHOLMOD_GIVEN;
      common.postorder = 0;  // keep the given permutation exactly.
    } else {
      common.nmethods = n >= kNestedDissectionMinRows ? 2 : 1;
      common.method[0].ordering = CHOLMOD_AMD;
      common.postorder = 1;
    }
    symbolic = cholmod_analyze_p(&pattern, givenPermutation, nullptr, 0, &common);
    cholmod_free_work(&common);
    if (symbolic == nullptr || common.status < CHOLMOD_OK) {
      resetAnalysis();
      return SolverStatus::CholmodError;
    }
    ++analysisCount;
    return SolverStatus::Ok;
  }

  bool acceptsSymbolicKind(const cholmod_factor& other) const {
    switch (kind) {
      case FactorKind::Simplicial: return other.is_super == 0;
      case FactorKind::Supernodal: return other.is_super != 0;
      case FactorKind::Auto: return true;
    }
    return false;
  }

  SolverStatus shareFrom(const SolverCore& other) {
    if (&other == this) return symbolic != nullptr ? SolverStatus::Ok : SolverStatus::NotAnalyzed;
    resetAnalysis();
    if (other.symbolic == nullptr) return SolverStatus::NotAnalyzed;
    n = other.n;
    lowerColumnStarts = other.lowerColumnStarts;
    lowerRowIndices = other.lowerRowIndices;
    if (acceptsSymbolicKind(*other.symbolic)) {
      symbolic = cholmod_copy_factor(other.symbolic, &common);
      if (symbolic == nullptr) {
        resetAnalysis();
        return SolverStatus::CholmodError;
      }
      return SolverStatus::Ok;
    }
    return analyzeStoredPattern(static_cast<int*>(other.symbolic->Perm));
  }

  cholmod_common common{};
  FactorKind kind;
  cholmod_factor* symbolic = nullptr;  // pattern-only, from the analysis.
  cholmod_factor* factor = nullptr;    // numeric, refactored in place.
  cholmod_dense* solution = nullptr;   // solve workspace, reused.
  cholmod_dense* workspaceY = nullptr;
  cholmod_dense* workspaceE = nullptr;
  int n = 0;
  std::vector<int> lowerColumnStarts;  // n + 1
  std::vector<int> lowerRowIndices;    // nnz(tril(A))
  bool factorized = false;
  int analysisCount = 0;
  int factorizationCount = 0;
};

// Stored range [begin, end) of column j of an Eigen matrix, compressed or not.
template <typename Matrix>
inline int columnEnd(const Matrix& A, int j) {
  const int* outer = A.outerIndexPtr();
  return A.isCompressed() ? outer[j + 1] : outer[j] + A.innerNonZeroPtr()[j];
}

template <typename Matrix>
void storeLowerPattern(const Matrix& A, std::vector<int>& columnStarts,
                       std::vector<int>& rowIndices) {
  const int n = static_cast<int>(A.cols());
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  columnStarts.assign(static_cast<size_t>(n) + 1, 0);
  rowIndices.clear();
  rowIndices.reserve(static_cast<size_t>(A.nonZeros() / 2 + n));
  for (int j = 0; j < n; ++j) {
    for (int p = outer[j], end = columnEnd(A, j); p < end; ++p) {
      if (inner[p] >= j) rowIndices.push_back(inner[p]);
    }
    columnStarts[static_cast<size_t>(j) + 1] = static_cast<int>(rowIndices.size());
  }
}

template <typename Matrix>
bool lowerPatternMatches(const Matrix& A, const std::vector<int>& columnStarts,
                         const std::vector<int>& rowIndices) {
  const int n = static_cast<int>(columnStarts.size()) - 1;
  if (A.rows() != n || A.cols() != n) return false;
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  for (int j = 0; j < n; ++j) {
    int q = columnStarts[j];
    const int qEnd = columnStarts[j + 1];
    for (int p = outer[j], end = columnEnd(A, j); p < end; ++p) {
      if (inner[p] < j) continue;
      if (q == qEnd || rowIndices[q] != inner[p]) return false;
      ++q;
    }
    if (q != qEnd) return false;
  }
  return true;
}

template <typename Scalar, typename Matrix>
bool allValuesFinite(const Matrix& A) {
  const int n = static_cast<int>(A.cols());
  const Scalar* values = A.valuePtr();
  for (int j = 0; j < n; ++j) {
    for (int p = A.outerIndexPtr()[j], end = columnEnd(A, j); p < end; ++p) {
      if (!ScalarTraits<Scalar>::isFinite(values[p])) return false;
    }
  }
  return true;
}

// Header-only cholmod_sparse over Eigen's storage (no copy). CHOLMOD does not
// write through it.
template <typename Scalar, typename Matrix>
cholmod_sparse lowerView(const Matrix& A) {
  cholmod_sparse view{};
  view.nrow = static_cast<size_t>(A.rows());
  view.ncol = static_cast<size_t>(A.cols());
  view.nzmax = static_cast<size_t>(A.nonZeros());
  view.p = const_cast<int*>(A.outerIndexPtr());
  view.i = const_cast<int*>(A.innerIndexPtr());
  view.nz = A.isCompressed() ? nullptr : const_cast<int*>(A.innerNonZeroPtr());
  view.x = const_cast<Scalar*>(A.valuePtr());
  view.stype = -1;
  view.itype = CHOLMOD_INT;
  view.xtype = ScalarTraits<Scalar>::xtype;
  view.dtype = CHOLMOD_DOUBLE;
  view.sorted = 1;
  view.packed = A.isCompressed() ? 1 : 0;
  return view;
}

}  // namespace cholmod_detail

namespace cholmod_detail {

// The substitution's arithmetic, written out for complex values so that no
// libgcc call (__divdc3, __muldc3's NaN path) sits in the inner loops; the
// diagonal of an LLᴴ factor is real.
inline double minusProduct(double accumulator, double l, double z) { return accumulator - l * z; }
inline Complex minusProduct(const Complex& accumulator, const Complex& l, const Complex& z) {
  return {accumulator.real() - (l.real() * z.real() - l.imag() * z.imag()),
          accumulator.imag() - (l.real() * z.imag() + l.imag() * z.real())};
}
inline double minusConjugateProduct(double accumulator, double l, double z) { return accumulator - l * z; }
inline Complex minusConjugateProduct(const Complex& accumulator, const Complex& l, const Complex& z) {
  return {accumulator.real() - (l.real() * z.real() + l.imag() * z.imag()),
          accumulator.imag() - (l.real() * z.imag() - l.imag() * z.real())};
}
inline double divideByDiagonal(double value, double diagonal) { return value / diagonal; }
inline Complex divideByDiagonal(const Complex& value, const Complex& diagonal) {
  return {value.real() / diagonal.real(), value.imag() / diagonal.real()};
}

// x = A⁻¹ b = Pᵀ L⁻ᴴ L⁻¹ P b over a simplicial LLᴴ factor (CHOLMOD's layout:
// column j in i/x[p[j], p[j] + nz[j]), diagonal entry first, real for LLᴴ),
// for K right-hand sides b[c] into x[c] (x[c] may be b[c]: work holds P b
// first), through `work` (K n entries, the K interleaved). Column-oriented
// forward substitution (a scatter per column) and row-oriented back
// substitution (a gather), each one pass over L in a fixed order:
// deterministic and allocation-free. Each right-hand side gets the same
// operations in the same order whatever K is, so K = 2 gives bitwise two
// K = 1 solves, and reads L once. `rows` is L's row indices, CHOLMOD's own
// (int) or their 16-bit copy (shortRowIndices): the same values, so the same
// operations in the same order, and 2 bytes less read per entry of L.
template <int K, typename Scalar, typename RowIndex>
void simplicialSolve(const cholmod_factor& L, const RowIndex* rows, const Scalar* const b[K], Scalar* const x[K],
                     Scalar* work) {
  const int n = static_cast<int>(L.n);
  const int* perm = static_cast<const int*>(L.Perm);
  const int* columnStarts = static_cast<const int*>(L.p);
  const int* columnCounts = static_cast<const int*>(L.nz);
  const Scalar* values = static_cast<const Scalar*>(L.x);
  for (int k = 0; k < n; ++k)
    for (int c = 0; c < K; ++c) work[K * k + c] = b[c][perm[k]];
  for (int j = 0; j < n; ++j) {
    // A zero over the positive diagonal is that zero, sign and all, so a
    // column whose entries are all zero is left as it is without reading its
    // diagonal: on a right-hand side held by a few vertices, most columns are
    // such, and the diagonals of the rest of L are a cache miss each.
    bool zeroIn = true;
    for (int c = 0; c < K; ++c) zeroIn = zeroIn && work[K * j + c] == Scalar(0);
    if (zeroIn) continue;
    const int begin = columnStarts[j], end = begin + columnCounts[j];
    Scalar z[K];
    bool zero = true;
    for (int c = 0; c < K; ++c) {
      z[c] = divideByDiagonal(work[K * j + c], values[begin]);
      work[K * j + c] = z[c];
      zero = zero && z[c] == Scalar(0);
    }
    // A zero changes nothing below it (w − l·0 = w; only −0 − (−0) would
    // have turned a −0 into +0): a right-hand side held by a few vertices
    // costs the columns its entries reach in the elimination tree.
    if (zero) continue;
    for (int q = begin + 1; q < end; ++q) {
      Scalar* w = work + K * static_cast<size_t>(rows[q]);
      for (int c = 0; c < K; ++c) w[c] = minusProduct(w[c], values[q], z[c]);
    }
  }
  for (int j = n - 1; j >= 0; --j) {
    const int begin = columnStarts[j], end = begin + columnCounts[j];
    Scalar sum[K];
    for (int c = 0; c < K; ++c) sum[c] = work[K * j + c];
    for (int q = begin + 1; q < end; ++q) {
      const Scalar* w = work + K * static_cast<size_t>(rows[q]);
      for (int c = 0; c < K; ++c) sum[c] = minusConjugateProduct(sum[c], values[q], w[c]);
    }
    for (int c = 0; c < K; ++c) work[K * j + c] = divideByDiagonal(sum[c], values[begin]);
  }
  for (int k = 0; k < n; ++k)
    for (int c = 0; c < K; ++c) x[c][perm[k]] = work[K * k + c];
}

}  // namespace cholmod_detail

template <typename Scalar>
struct CholeskySolver<Scalar>::Impl : cholmod_detail::SolverCore {
  using SolverCore::SolverCore;
  std::vector<Scalar> solveWork;  // 2n: simplicialSolve for up to two right-hand sides (sized at factorize)
  // L's row indices as 16 bits (filled at factorize where every index fits;
  // empty otherwise). The back substitution reads every entry of L once a
  // solve and is bound by those reads: 10 bytes an entry instead of 12.
  std::vector<std::uint16_t> shortRows;
  bool shortRowsAllowed = true;  // setShortRowIndices

  // Our own substitution applies (the rest goes through cholmod_solve2).
  bool ownSolve() const {
    const cholmod_factor& L = *factor;
    return !L.is_super && L.is_ll && L.itype == CHOLMOD_INT &&
           L.xtype == cholmod_detail::ScalarTraits<Scalar>::xtype && L.Perm != nullptr && L.nz != nullptr;
  }
  // shortRows from the numeric factor: its row indices, when all are below
  // 2^16 (n ≤ 65,536) and the columns sit packed in index order without
  // slack (CHOLMOD's final_pack, its default), so entry q of column j is
  // entry q of the copy; otherwise none.
  void storeShortRows() {
    shortRows.clear();
    const cholmod_factor& L = *factor;
    if (!shortRowsAllowed || !ownSolve() || L.n > kShortRowLimit) return;
    const int* starts = static_cast<const int*>(L.p);
    const int* counts = static_cast<const int*>(L.nz);
    if (L.n > 0 && starts[0] != 0) return;
    for (size_t j = 0; j + 1 < L.n; ++j)
      if (counts[j] < 0 || starts[j] + counts[j] != starts[j + 1]) return;
    const size_t entries = L.n == 0 ? 0 : static_cast<size_t>(starts[L.n - 1]) + static_cast<size_t>(counts[L.n - 1]);
    const int* rows = static_cast<const int*>(L.i);
    shortRows.resize(entries);
    for (size_t q = 0; q < entries; ++q) shortRows[q] = static_cast<std::uint16_t>(rows[q]);
  }
  static constexpr size_t kShortRowLimit = size_t{1} << 16;

  // simplicialSolve over the factor, with the 16-bit row indices where stored.
  template <int K>
  void substitute(const Scalar* const (&in)[K], Scalar* const (&out)[K]) {
    const cholmod_factor& L = *factor;
    if (!shortRows.empty()) {
      cholmod_detail::simplicialSolve<K, Scalar>(L, shortRows.data(), in, out, solveWork.data());
    } else {
      cholmod_detail::simplicialSolve<K, Scalar>(L, static_cast<const int*>(L.i), in, out, solveWork.data());
    }
  }
};

template <typename Scalar>
CholeskySolver<Scalar>::CholeskySolver(FactorKind kind) : impl_(std::make_unique<Impl>(kind)) {}

template <typename Scalar>
CholeskySolver<Scalar>::~CholeskySolver() = default;

template <typename Scalar>
CholeskySolver<Scalar>::CholeskySolver(CholeskySolver&&) noexcept = default;

template <typename Scalar>
CholeskySolver<Scalar>& CholeskySolver<Scalar>::operator=(CholeskySolver&&) noexcept = default;

template <typename Scalar>
SolverStatus CholeskySolver<Scalar>::analyzePattern(const Matrix& A) {
  if (!impl_) impl_ = std::make_unique<Impl>(FactorKind::Simplicial);  // moved-from
  Impl& s = *impl_;
  s.resetAnalysis();
  if (A.rows() != A.cols() || A.rows() == 0) return SolverStatus::SizeMismatch;
  s.n = static_cast<int>(A.rows());
  cholmod_detail::storeLowerPattern(A, s.lowerColumnStarts, s.lowerRowIndices);
  return s.analyzeStoredPattern(nullptr);
}

template <typename Scalar>
template <typename OtherScalar>
SolverStatus CholeskySolver<Scalar>::shareAnalysisFrom(const CholeskySolver<OtherScalar>& other) {
  if (!impl_) impl_ = std::make_unique<Impl>(FactorKind::Simplicial);
  if (!other.impl_) {
    impl_->resetAnalysis();
    return SolverStatus::NotAnalyzed;
  }
  return impl_->shareFrom(*other.impl_);
}

template <typename Scalar>
SolverStatus CholeskySolver<Scalar>::factorize(const Matrix& A) {
  if (!impl_ || impl_->symbolic == nullptr) return SolverStatus::NotAnalyzed;
  Impl& s = *impl_;
  s.factorized = false;
  if (!cholmod_detail::lowerPatternMatches(A, s.lowerColumnStarts, s.lowerRowIndices)) {
    return SolverStatus::PatternMismatch;
  }
  if (!cholmod_detail::allValuesFinite<Scalar>(A)) return SolverStatus::NonFinite;

  s.freeNumeric();  // never two numeric factors at once (design note)
  s.factor = cholmod_copy_factor(s.symbolic, &s.common);
  if (s.factor == nullptr) return SolverStatus::CholmodError;
  cholmod_sparse view = cholmod_detail::lowerView<Scalar>(A);
  const int ok = cholmod_factorize(&view, s.factor, &s.common);
  cholmod_free_work(&s.common);
  ++s.factorizationCount;
  if (!ok || s.common.status < CHOLMOD_OK) {
    s.freeNumeric();
    return SolverStatus::CholmodError;
  }
  if (s.common.status == CHOLMOD_NOT_POSDEF || s.factor->minor < s.factor->n) {
    // Drop the partial factor: the next factorize starts from the symbolic one.
    s.freeNumeric();
    return SolverStatus::NotPositiveDefinite;
  }
  if (s.solveWork.size() != 2 * static_cast<size_t>(s.n)) s.solveWork.resize(2 * static_cast<size_t>(s.n));
  s.storeShortRows();
  s.factorized = true;
  return SolverStatus::Ok;
}

template <typename Scalar>
void CholeskySolver<Scalar>::releaseFactor() {
  if (!impl_) return;
  impl_->freeNumeric();
  std::vector<std::uint16_t>().swap(impl_->shortRows);  // released with the factor it copies
  cholmod_free_work(&impl_->common);
}

template <typename Scalar>
SolverStatus CholeskySolver<Scalar>::compute(const Matrix& A) {
  const SolverStatus status = analyzePattern(A);
  return status == SolverStatus::Ok ? factorize(A) : status;
}

template <typename Scalar>
SolverStatus CholeskySolver<Scalar>::solve(const VectorType& rhs, VectorType& x) const {
  if (!impl_ || impl_->symbolic == nullptr) return SolverStatus::NotAnalyzed;
  Impl& s = *impl_;
  if (!s.factorized) return SolverStatus::NotFactorized;
  if (rhs.size() != s.n) return SolverStatus::SizeMismatch;
  for (Eigen::Index i = 0; i < rhs.size(); ++i) {
    if (!cholmod_detail::ScalarTraits<Scalar>::isFinite(rhs[i])) return SolverStatus::NonFinite;
  }
  if (s.ownSolve()) {
    // Our own substitution: CHOLMOD's real simplicial solve allocates on every
    // call; this does not, and it writes x directly (work holds P b first, so
    // rhs and x may be the same vector).
    x.resize(s.n);
    const Scalar* in[1] = {rhs.data()};
    Scalar* const out[1] = {x.data()};
    s.template substitute<1>(in, out);
    return SolverStatus::Ok;
  }
  cholmod_dense b{};
  b.nrow = static_cast<size_t>(s.n);
  b.ncol = 1;
  b.nzmax = static_cast<size_t>(s.n);
  b.d = static_cast<size_t>(s.n);
  b.x = const_cast<Scalar*>(rhs.data());  // read only
  b.xtype = cholmod_detail::ScalarTraits<Scalar>::xtype;
  b.dtype = CHOLMOD_DOUBLE;
  const int ok = cholmod_solve2(CHOLMOD_A, s.factor, &b, nullptr, &s.solution, nullptr,
                                &s.workspaceY, &s.workspaceE, &s.common);
  if (!ok || s.solution == nullptr) return SolverStatus::CholmodError;
  // Copy out (O(n), small beside the O(nnz(L)) solve); reading rhs finished
  // above, so rhs and x may be the same vector.
  x.resize(s.n);
  std::memcpy(static_cast<void*>(x.data()), s.solution->x, sizeof(Scalar) * static_cast<size_t>(s.n));
  return SolverStatus::Ok;
}

template <typename Scalar>
SolverStatus CholeskySolver<Scalar>::solveInPlacePair(VectorType& a, VectorType& b) const {
  if (!impl_ || impl_->symbolic == nullptr) return SolverStatus::NotAnalyzed;
  Impl& s = *impl_;
  if (!s.factorized) return SolverStatus::NotFactorized;
  if (a.size() != s.n || b.size() != s.n) return SolverStatus::SizeMismatch;
  for (const VectorType* v : {&a, &b})
    for (Eigen::Index i = 0; i < v->size(); ++i)
      if (!cholmod_detail::ScalarTraits<Scalar>::isFinite((*v)[i])) return SolverStatus::NonFinite;
  if (s.ownSolve()) {
    const Scalar* in[2] = {a.data(), b.data()};
    Scalar* const out[2] = {a.data(), b.data()};
    s.template substitute<2>(in, out);
    return SolverStatus::Ok;
  }
  const SolverStatus status = solve(a, a);
  return status != SolverStatus::Ok ? status : solve(b, b);
}

template <typename Scalar>
bool CholeskySolver<Scalar>::isAnalyzed() const {
  return impl_ && impl_->symbolic != nullptr;
}

template <typename Scalar>
bool CholeskySolver<Scalar>::isFactorized() const {
  return impl_ && impl_->factorized;
}

template <typename Scalar>
int CholeskySolver<Scalar>::rows() const {
  return impl_ ? impl_->n : 0;
}

template <typename Scalar>
int CholeskySolver<Scalar>::analysisCount() const {
  return impl_ ? impl_->analysisCount : 0;
}

template <typename Scalar>
int CholeskySolver<Scalar>::factorizationCount() const {
  return impl_ ? impl_->factorizationCount : 0;
}

template <typename Scalar>
void CholeskySolver<Scalar>::setShortRowIndices(bool on) {
  if (!impl_) impl_ = std::make_unique<Impl>(FactorKind::Simplicial);  // moved-from
  impl_->shortRowsAllowed = on;
}

template <typename Scalar>
bool CholeskySolver<Scalar>::usesShortRowIndices() const {
  return impl_ && impl_->factorized && !impl_->shortRows.empty();
}

template <typename Scalar>
long CholeskySolver<Scalar>::factorNonZeros() const {
  if (!impl_ || impl_->symbolic == nullptr) return 0;
  // Exact nnz(L) of the simplicial factor (diagonal included) from the
  // symbolic column counts; the same for simplicial and supernodal, which also
  // stores the zeros of relaxed amalgamation.
  const cholmod_factor& L = *impl_->symbolic;
  const int* columnCounts = static_cast<const int*>(L.ColCount);
  long total = 0;
  for (size_t j = 0; j < L.n; ++j) total += columnCounts[j];
  return total;
}

const char* toString(SolverStatus status) {
  switch (status) {
    case SolverStatus::Ok: return "Ok";
    case SolverStatus::NotAnalyzed: return "NotAnalyzed";
    case SolverStatus::PatternMismatch: return "PatternMismatch";
    case SolverStatus::NotPositiveDefinite: return "NotPositiveDefinite";
    case SolverStatus::NotFactorized: return "NotFactorized";
    case SolverStatus::SizeMismatch: return "SizeMismatch";
    case SolverStatus::NonFinite: return "NonFinite";
    case SolverStatus::CholmodError: return "CholmodError";
  }
  return "Unknown";
}

template class CholeskySolver<double>;
template class CholeskySolver<Complex>;
template SolverStatus CholeskySolver<double>::shareAnalysisFrom<double>(
    const CholeskySolver<double>&);
template SolverStatus CholeskySolver<double>::shareAnalysisFrom<Complex>(
    const CholeskySolver<Complex>&);
template SolverStatus CholeskySolver<Complex>::shareAnalysisFrom<double>(
    const CholeskySolver<double>&);
template SolverStatus CholeskySolver<Complex>::shareAnalysisFrom<Complex>(
    const CholeskySolver<Complex>&);

}  // namespace blot::stain
