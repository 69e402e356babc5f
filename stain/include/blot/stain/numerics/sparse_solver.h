#pragma once
/// Sparse symmetric (Hermitian) positive-definite solver on CHOLMOD.
///
/// Three separate steps, so the expensive ones are done only when needed:
///  - analyzePattern(A): fill-reducing ordering and symbolic factorization,
///    once per sparsity pattern (i.e. per mesh connectivity);
///  - factorize(A): numeric Cholesky of new values on the same pattern
///    (e.g. after the metric changed, or a new h);
///  - solve(rhs, x): forward/back substitution into a caller-owned vector.
/// A symbolic analysis can be shared between the real scalar system and the
/// complex connection system, which have the same pattern (shareAnalysisFrom).
/// Non-positive-definite input returns SolverStatus::NotPositiveDefinite and
/// keeps the previous factor unusable rather than returning garbage.
/// cholmod.h stays out of this header (pimpl).
#include <blot/stain/types.h>

#include <memory>
#include <string>

namespace blot::stain {

enum class SolverStatus {
  Ok,
  NotAnalyzed,          ///< factorize/solve before analyzePattern.
  PatternMismatch,      ///< factorize with a matrix whose pattern differs from the analysed one.
  NotPositiveDefinite,  ///< Cholesky broke down (leading minor not positive).
  NotFactorized,        ///< solve before a successful factorize.
  SizeMismatch,         ///< rhs / x of the wrong size.
  NonFinite,            ///< NaN/Inf in the matrix or right-hand side.
  CholmodError          ///< any other CHOLMOD failure (out of memory, ...).
};

const char* toString(SolverStatus status);

/// Which CHOLMOD factorization kind to use. Simplicial is the default: with
/// Debian's reference BLAS it beats supernodal on our meshes (docs/performance.md).
enum class FactorKind { Simplicial, Supernodal, Auto };

template <typename Scalar>
class CholeskySolver {
 public:
  using Matrix = Eigen::SparseMatrix<Scalar>;
  using VectorType = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;

  explicit CholeskySolver(FactorKind kind = FactorKind::Simplicial);
  ~CholeskySolver();
  CholeskySolver(CholeskySolver&&) noexcept;
  CholeskySolver& operator=(CholeskySolver&&) noexcept;
  CholeskySolver(const CholeskySolver&) = delete;
  CholeskySolver& operator=(const CholeskySolver&) = delete;

  /// Symbolic analysis of A's pattern (A square, both triangles stored; only the
  /// lower triangle is read).
  SolverStatus analyzePattern(const Matrix& A);
  /// Reuses the ordering and symbolic factor of another solver with the same
  /// pattern (e.g. the scalar solver's for the complex connection system).
  template <typename OtherScalar>
  SolverStatus shareAnalysisFrom(const CholeskySolver<OtherScalar>& other);
  /// Numeric factorization on the analysed pattern. The previous numeric
  /// factor is freed first and the new one starts from the symbolic analysis,
  /// so at most one numeric factor is alive and the result depends on A only.
  SolverStatus factorize(const Matrix& A);
  /// Frees the numeric factor (and CHOLMOD's workspace), keeping the symbolic
  /// analysis: for a caller about to build new values (an intrinsic rebuild),
  /// so the old factor is not held while they are assembled. The solver is
  /// then "not factorized" until the next factorize.
  void releaseFactor();
  /// analyzePattern + factorize.
  SolverStatus compute(const Matrix& A);
  /// x = A⁻¹ rhs. x is resized only if its size differs.
  SolverStatus solve(const VectorType& rhs, VectorType& x) const;
  /// a = A⁻¹ a and b = A⁻¹ b (in place, both of A's size), bitwise what two
  /// solve calls give: one pass over the factor serves both (a simplicial
  /// solve is bound by reading L, so two right-hand sides cost little more
  /// than one). Other factor kinds run two solves.
  SolverStatus solveInPlacePair(VectorType& a, VectorType& b) const;

  bool isAnalyzed() const;
  bool isFactorized() const;
  int rows() const;
  /// Counters for profiles and tests.
  int analysisCount() const;
  int factorizationCount() const;
  /// Non-zeros in the factor L (memory report).
  long factorNonZeros() const;
  /// Whether the simplicial solves read L's row indices as 16 bits (the
  /// default, where n ≤ 65,536: 2 bytes less read per entry, the same bits;
  /// the back substitution is bound by those reads). Off: CHOLMOD's own 32-bit indices, for
  /// the benchmark and the test that compare the two. Takes effect at the next
  /// factorize.
  void setShortRowIndices(bool on);
  /// True when the current factor's solves read the 16-bit row indices.
  bool usesShortRowIndices() const;

  struct Impl;

 private:
  template <typename>
  friend class CholeskySolver;
  std::unique_ptr<Impl> impl_;
};

using RealCholeskySolver = CholeskySolver<double>;
using ComplexCholeskySolver = CholeskySolver<Complex>;

}  // namespace blot::stain
