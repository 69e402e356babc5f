#pragma once
// Spectral checks of the operator tests (operators_test): eigenvalues of
// L x = λ M x, positive definiteness and the inertia of shifted matrices.
// Each factorizes a sparse matrix in the test's own code, so they live in
// their own source, compiled at -O1 even where the test files are compiled at
// -O0 (scripts/sanitize: the bisection on the camel and the icosphere spectra
// took 100 of operators_test's 116 s there; tests/CMakeLists.txt).
#include <blot/stain/types.h>

#include <memory>

namespace blot::stain::testing {

/// The `count` smallest eigenvalues of L x = λ M x (L Hermitian PSD, M
/// diagonal positive), ascending. Dense (M^{-1/2} L M^{-1/2}) for small
/// problems, shift-invert subspace iteration with Rayleigh–Ritz otherwise
/// (converged to 1e-13; throws if it does not converge).
Vector smallestEigenvalues(const SparseMatrix& L, const SparseMatrix& M, int count);
Vector smallestEigenvalues(const ComplexSparseMatrix& L, const SparseMatrix& M, int count);

/// Whether L + δM has a Cholesky factor, i.e. is positive definite: for M
/// positive diagonal, λ_min(M⁻¹L) > −δ.
bool choleskySucceeds(const SparseMatrix& L, const SparseMatrix& M, double delta);
bool choleskySucceeds(const ComplexSparseMatrix& L, const SparseMatrix& M, double delta);

/// E − σM = L D Lᴴ for one Hermitian E and diagonal M, the pattern analysed
/// once: the number of negative pivots is the number of eigenvalues of M⁻¹E
/// below σ (Sylvester's law of inertia). E is referenced, not copied: it must
/// outlive this object.
class ShiftedInertia {
 public:
  ShiftedInertia(const ComplexSparseMatrix& E, const SparseMatrix& M);
  ~ShiftedInertia();
  /// Eigenvalues of M⁻¹E below σ.
  int eigenvaluesBelow(double sigma);
  /// `iterations` steps of inverse iteration x ← (E − σM)⁻¹ M x, x / |x|,
  /// from the vector of ones.
  ComplexVector inverseIteration(double sigma, int iterations);

 private:
  struct Factor;
  void factorAt(double sigma);  ///< factorizes E − σM
  const ComplexSparseMatrix& E_;
  ComplexSparseMatrix M_;
  std::unique_ptr<Factor> factor_;
};

}  // namespace blot::stain::testing
