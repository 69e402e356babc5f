#include "spectral_checks.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <random>
#include <stdexcept>

#include "geometry_test_support.h"

namespace blot::stain::testing {
namespace {

template <typename Scalar>
Vector smallestEigenvaluesOf(const Eigen::SparseMatrix<Scalar>& L, const SparseMatrix& M, int count) {
  using Dense = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  using ScalarVector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  const Eigen::Index n = L.rows();
  const Vector diagonal = M.diagonal();
  const ScalarVector d = diagonal.cast<Scalar>();
  const ScalarVector invSqrt = diagonal.cwiseSqrt().cwiseInverse().cast<Scalar>();
  if (n <= 200) {
    Dense A = invSqrt.asDiagonal() * Dense(L) * invSqrt.asDiagonal();
    A = (0.5 * (A + A.adjoint())).eval();
    Eigen::SelfAdjointEigenSolver<Dense> solver(A, Eigen::EigenvaluesOnly);
    return solver.eigenvalues().head(count);
  }
  const int block = count + 10;
  const double shift = 1.0;  // any positive shift makes L + shift M SPD
  Eigen::SparseMatrix<Scalar> shifted = L + shift * M.cast<Scalar>();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<Scalar>> factor(shifted);
  if (factor.info() != Eigen::Success) throw std::runtime_error("smallestEigenvalues: factor failed");
  std::mt19937 rng(7);
  Dense X(n, block);
  for (Eigen::Index j = 0; j < block; ++j)
    for (Eigen::Index i = 0; i < n; ++i) X(i, j) = Scalar(uniform(rng, -1.0, 1.0));
  Vector previous = Vector::Constant(count, -1.0);
  Vector values(count);
  for (int iteration = 0; iteration < 200; ++iteration) {
    Dense Y = factor.solve(d.asDiagonal() * X);
    // M-orthonormalise, then Rayleigh–Ritz on the subspace.
    Dense gram = Y.adjoint() * d.asDiagonal() * Y;
    Eigen::LLT<Dense> llt(0.5 * (gram + gram.adjoint()));
    Dense Q = llt.matrixU().template solve<Eigen::OnTheRight>(Y);
    Dense small = Q.adjoint() * (L * Q);
    Eigen::SelfAdjointEigenSolver<Dense> solver(0.5 * (small + small.adjoint()));
    X = Q * solver.eigenvectors();
    values = solver.eigenvalues().head(count);
    // Ritz values converge monotonically from above; 1e-13 is far below any
    // discretization error measured with this helper and above rounding noise.
    if ((values - previous).cwiseAbs().maxCoeff() <= 1e-13 * std::max(1.0, values.cwiseAbs().maxCoeff()))
      break;
    previous = values;
    if (iteration == 199) throw std::runtime_error("smallestEigenvalues: no convergence");
  }
  return values;
}

template <typename Scalar>
bool choleskySucceedsFor(const Eigen::SparseMatrix<Scalar>& L, const SparseMatrix& M, double delta) {
  const Eigen::SparseMatrix<Scalar> shifted = L + delta * M.cast<Scalar>();
  Eigen::SimplicialLLT<Eigen::SparseMatrix<Scalar>> llt(shifted);
  return llt.info() == Eigen::Success;
}

}  // namespace

Vector smallestEigenvalues(const SparseMatrix& L, const SparseMatrix& M, int count) {
  return smallestEigenvaluesOf(L, M, count);
}
Vector smallestEigenvalues(const ComplexSparseMatrix& L, const SparseMatrix& M, int count) {
  return smallestEigenvaluesOf(L, M, count);
}
bool choleskySucceeds(const SparseMatrix& L, const SparseMatrix& M, double delta) {
  return choleskySucceedsFor(L, M, delta);
}
bool choleskySucceeds(const ComplexSparseMatrix& L, const SparseMatrix& M, double delta) {
  return choleskySucceedsFor(L, M, delta);
}

struct ShiftedInertia::Factor {
  Eigen::SimplicialLDLT<ComplexSparseMatrix> ldlt;
};

ShiftedInertia::ShiftedInertia(const ComplexSparseMatrix& E, const SparseMatrix& M)
    : E_(E), M_(M.cast<Complex>()), factor_(std::make_unique<Factor>()) {
  factor_->ldlt.analyzePattern(E);
}

ShiftedInertia::~ShiftedInertia() = default;

void ShiftedInertia::factorAt(double sigma) { factor_->ldlt.factorize(ComplexSparseMatrix(E_ - sigma * M_)); }

int ShiftedInertia::eigenvaluesBelow(double sigma) {
  factorAt(sigma);
  return static_cast<int>((factor_->ldlt.vectorD().real().array() < 0.0).count());
}

ComplexVector ShiftedInertia::inverseIteration(double sigma, int iterations) {
  factorAt(sigma);
  ComplexVector x = ComplexVector::Ones(E_.rows());
  for (int iteration = 0; iteration < iterations; ++iteration) {
    x = factor_->ldlt.solve(ComplexVector(M_ * x));
    x /= x.norm();
  }
  return x;
}

}  // namespace blot::stain::testing
