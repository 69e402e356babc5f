// CholeskySolver: residuals on real SPD and complex Hermitian PD matrices, the
// analysis/factorization/solve split, every error status, sharing the analysis
// between the scalar and the complex system, and move semantics.
#include <blot/stain/numerics/sparse_solver.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace blot::stain {
namespace {

constexpr FactorKind kAllKinds[] = {FactorKind::Simplicial, FactorKind::Supernodal,
                                    FactorKind::Auto};

// 5-point Laplacian of an m x m grid plus shift * I (SPD for shift > 0;
// eigenvalues in (shift, shift + 8), so the residual tolerance is meaningful).
SparseMatrix gridLaplacianPlusShift(int m, double shift) {
  std::vector<Eigen::Triplet<double>> entries;
  const auto index = [m](int i, int j) { return j * m + i; };
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < m; ++i) {
      const int a = index(i, j);
      entries.emplace_back(a, a, shift);
      const int neighbours[2][2] = {{i + 1, j}, {i, j + 1}};
      for (const auto& nb : neighbours) {
        if (nb[0] >= m || nb[1] >= m) continue;
        const int b = index(nb[0], nb[1]);
        entries.emplace_back(a, a, 1.0);
        entries.emplace_back(b, b, 1.0);
        entries.emplace_back(a, b, -1.0);
        entries.emplace_back(b, a, -1.0);
      }
    }
  }
  SparseMatrix A(m * m, m * m);
  A.setFromTriplets(entries.begin(), entries.end());
  return A;
}

// Random Hermitian, strictly diagonally dominant with a positive diagonal
// (hence positive definite): `perColumn` random off-diagonal entries per
// column, mirrored as conjugates.
ComplexSparseMatrix randomHermitianPositiveDefinite(int n, int perColumn, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> row(0, n - 1);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<Eigen::Triplet<Complex>> entries;
  Vector rowSums = Vector::Zero(n);
  for (int j = 0; j < n; ++j) {
    for (int k = 0; k < perColumn; ++k) {
      const int i = row(rng);
      if (i == j) continue;
      const Complex a(value(rng), value(rng));
      entries.emplace_back(i, j, a);
      entries.emplace_back(j, i, std::conj(a));
      rowSums[i] += std::abs(a);
      rowSums[j] += std::abs(a);
    }
  }
  for (int i = 0; i < n; ++i) entries.emplace_back(i, i, Complex(rowSums[i] + 0.5, 0.0));
  ComplexSparseMatrix A(n, n);
  A.setFromTriplets(entries.begin(), entries.end());
  return A;
}

// Same pattern as gridLaplacianPlusShift, complex: each edge carries a unit
// rotation (a flat "connection"), so it is Hermitian PD for shift > 0.
ComplexSparseMatrix gridConnectionPlusShift(int m, double shift, unsigned seed) {
  const SparseMatrix real = gridLaplacianPlusShift(m, shift);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> angle(-3.14159, 3.14159);
  ComplexSparseMatrix A = real.cast<Complex>();
  for (int j = 0; j < A.outerSize(); ++j) {
    for (ComplexSparseMatrix::InnerIterator it(A, j); it; ++it) {
      if (it.row() > it.col()) {
        const Complex rotation = std::polar(1.0, angle(rng));
        it.valueRef() *= rotation;
        A.coeffRef(it.col(), it.row()) *= std::conj(rotation);
      }
    }
  }
  return A;
}

template <typename Scalar>
Eigen::Matrix<Scalar, Eigen::Dynamic, 1> randomVector(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  Eigen::Matrix<Scalar, Eigen::Dynamic, 1> v(n);
  for (int i = 0; i < n; ++i) {
    if constexpr (std::is_same_v<Scalar, double>) {
      v[i] = value(rng);
    } else {
      v[i] = Scalar(value(rng), value(rng));
    }
  }
  return v;
}

template <typename Matrix, typename VectorType>
double relativeResidual(const Matrix& A, const VectorType& x, const VectorType& b) {
  return (A * x - b).norm() / b.norm();
}

TEST(SparseSolver, RealSpdResidualEveryKind) {
  const SparseMatrix A = gridLaplacianPlusShift(40, 0.5);
  const Vector b = randomVector<double>(static_cast<int>(A.rows()), 1);
  for (FactorKind kind : kAllKinds) {
    RealCholeskySolver solver(kind);
    ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
    Vector x;
    ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
    EXPECT_LT(relativeResidual(A, x, b), 1e-12) << "kind " << static_cast<int>(kind);
    EXPECT_TRUE(solver.isAnalyzed());
    EXPECT_TRUE(solver.isFactorized());
    EXPECT_EQ(solver.rows(), 1600);
    // nnz(L) lies between nnz(tril(A)) (no fill) and a dense triangle.
    const long lowerNonZeros = (A.nonZeros() + A.rows()) / 2;
    EXPECT_GE(solver.factorNonZeros(), lowerNonZeros);
    EXPECT_LT(solver.factorNonZeros(), 1600L * 1601L / 2);
  }
}

TEST(SparseSolver, ComplexHermitianResidualEveryKind) {
  const ComplexSparseMatrix A = randomHermitianPositiveDefinite(800, 4, 7);
  const ComplexVector b = randomVector<Complex>(800, 2);
  for (FactorKind kind : kAllKinds) {
    ComplexCholeskySolver solver(kind);
    ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
    ComplexVector x;
    ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
    EXPECT_LT(relativeResidual(A, x, b), 1e-12) << "kind " << static_cast<int>(kind);
  }
}

// Two right-hand sides in one pass over the factor give each the bits of its
// own solve (the direct density diffusion solves solvent and solute so).
template <typename Scalar, typename Matrix>
void expectPairEqualsTwoSolves(const Matrix& A, FactorKind kind) {
  const int n = static_cast<int>(A.rows());
  using VectorType = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  CholeskySolver<Scalar> solver(kind);
  ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
  VectorType a = randomVector<Scalar>(n, 3), b = randomVector<Scalar>(n, 4);
  VectorType xa, xb;
  ASSERT_EQ(solver.solve(a, xa), SolverStatus::Ok);
  ASSERT_EQ(solver.solve(b, xb), SolverStatus::Ok);
  ASSERT_EQ(solver.solveInPlacePair(a, b), SolverStatus::Ok);
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(a[i], xa[i]) << "kind " << static_cast<int>(kind) << ", row " << i;
    ASSERT_EQ(b[i], xb[i]) << "kind " << static_cast<int>(kind) << ", row " << i;
  }
  EXPECT_LT(relativeResidual(A, a, randomVector<Scalar>(n, 3)), 1e-12);
}

TEST(SparseSolver, PairOfRightHandSidesGivesTheBitsOfTwoSolves) {
  for (FactorKind kind : kAllKinds) {
    expectPairEqualsTwoSolves<double>(gridLaplacianPlusShift(40, 0.5), kind);
    expectPairEqualsTwoSolves<Complex>(randomHermitianPositiveDefinite(800, 4, 7), kind);
  }
  // Refused like solve: wrong size, a non-finite entry (nothing written), no factor.
  RealCholeskySolver solver;
  const SparseMatrix A = gridLaplacianPlusShift(10, 0.5);
  Vector a = Vector::Ones(100), b = Vector::Ones(99);
  EXPECT_EQ(solver.solveInPlacePair(a, a), SolverStatus::NotAnalyzed);
  ASSERT_EQ(solver.analyzePattern(A), SolverStatus::Ok);
  EXPECT_EQ(solver.solveInPlacePair(a, a), SolverStatus::NotFactorized);
  ASSERT_EQ(solver.factorize(A), SolverStatus::Ok);
  EXPECT_EQ(solver.solveInPlacePair(a, b), SolverStatus::SizeMismatch);
  b = Vector::Ones(100);
  b[50] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(solver.solveInPlacePair(a, b), SolverStatus::NonFinite);
  EXPECT_TRUE((a.array() == 1.0).all());
}

// A right-hand side held by a few vertices (a drop's diffusion): the
// simplicial substitution skips the factor columns its entries never reach,
// and must still give the full solution (CHOLMOD's own supernodal solve as
// the reference), a zero right-hand side exactly zero, and in a pair the bits
// of two solves.
template <typename Scalar, typename Matrix>
void expectLocalRightHandSideSolved(const Matrix& A) {
  using VectorType = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  const int n = static_cast<int>(A.rows());
  VectorType local = VectorType::Zero(n);
  const VectorType values = randomVector<Scalar>(3, 11);
  local[7] = values[0];
  local[8] = values[1];
  local[n / 2] = values[2];
  const VectorType zero = VectorType::Zero(n);
  CholeskySolver<Scalar> simplicial(FactorKind::Simplicial), supernodal(FactorKind::Supernodal);
  ASSERT_EQ(simplicial.compute(A), SolverStatus::Ok);
  ASSERT_EQ(supernodal.compute(A), SolverStatus::Ok);
  VectorType x, reference, x0;
  ASSERT_EQ(simplicial.solve(local, x), SolverStatus::Ok);
  ASSERT_EQ(supernodal.solve(local, reference), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A, x, local), 1e-13);
  EXPECT_LT((x - reference).norm(), 1e-13 * reference.norm());
  // Backward Euler's solution reaches every vertex of the connected mesh.
  for (int i = 0; i < n; ++i) ASSERT_NE(x[i], Scalar(0)) << "row " << i;
  ASSERT_EQ(simplicial.solve(zero, x0), SolverStatus::Ok);
  for (int i = 0; i < n; ++i) ASSERT_EQ(x0[i], Scalar(0)) << "row " << i;
  VectorType a = local, b = zero;
  ASSERT_EQ(simplicial.solveInPlacePair(a, b), SolverStatus::Ok);
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(a[i], x[i]) << "row " << i;
    ASSERT_EQ(b[i], Scalar(0)) << "row " << i;
  }
}

TEST(SparseSolver, RightHandSideOnAFewVerticesIsSolvedInFull) {
  expectLocalRightHandSideSolved<double>(gridLaplacianPlusShift(60, 0.05));
  expectLocalRightHandSideSolved<Complex>(gridConnectionPlusShift(60, 0.05, 5));
}

TEST(SparseSolver, RefactorizationReusesTheAnalysis) {
  RealCholeskySolver solver;
  const SparseMatrix A1 = gridLaplacianPlusShift(30, 0.5);
  const SparseMatrix A2 = gridLaplacianPlusShift(30, 3.0);  // same pattern, new values
  const Vector b = randomVector<double>(900, 3);
  Vector x;
  ASSERT_EQ(solver.analyzePattern(A1), SolverStatus::Ok);
  ASSERT_EQ(solver.factorize(A1), SolverStatus::Ok);
  ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A1, x, b), 1e-12);
  ASSERT_EQ(solver.factorize(A2), SolverStatus::Ok);
  ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A2, x, b), 1e-12);
  EXPECT_GT(relativeResidual(A1, x, b), 1e-3);  // really solved the new matrix
  EXPECT_EQ(solver.analysisCount(), 1);
  EXPECT_EQ(solver.factorizationCount(), 2);
}

TEST(SparseSolver, UncompressedInputAndAliasedRhs) {
  SparseMatrix A = gridLaplacianPlusShift(12, 1.0);
  const Vector b = randomVector<double>(144, 4);
  RealCholeskySolver reference;
  ASSERT_EQ(reference.compute(A), SolverStatus::Ok);
  Vector expected;
  ASSERT_EQ(reference.solve(b, expected), SolverStatus::Ok);

  A.uncompress();  // Eigen storage with per-column counts and slack
  A.reserve(Eigen::VectorXi::Constant(144, 2));
  ASSERT_FALSE(A.isCompressed());
  RealCholeskySolver solver;
  ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
  Vector x = b;
  ASSERT_EQ(solver.solve(x, x), SolverStatus::Ok);  // rhs and x are one vector
  EXPECT_LT((x - expected).norm(), 1e-14 * expected.norm());
}

TEST(SparseSolver, PatternMismatchIsDetected) {
  RealCholeskySolver solver;
  const SparseMatrix A = gridLaplacianPlusShift(10, 1.0);
  ASSERT_EQ(solver.compute(A), SolverStatus::Ok);

  SparseMatrix extra = A;  // one more symmetric pair of entries in the lower triangle
  extra.coeffRef(50, 0) = -1e-3;
  extra.coeffRef(0, 50) = -1e-3;
  EXPECT_EQ(solver.factorize(extra), SolverStatus::PatternMismatch);
  EXPECT_FALSE(solver.isFactorized());
  Vector x;
  EXPECT_EQ(solver.solve(Vector::Ones(100), x), SolverStatus::NotFactorized);

  EXPECT_EQ(solver.factorize(gridLaplacianPlusShift(11, 1.0)), SolverStatus::PatternMismatch);

  // Same pattern again: works, on the first analysis.
  EXPECT_EQ(solver.factorize(A), SolverStatus::Ok);
  EXPECT_EQ(solver.analysisCount(), 1);
}

TEST(SparseSolver, UpperTriangleIsNotRead) {
  // Only tril(A) is read, so a different upper pattern is not a mismatch and
  // a matrix stored as its lower triangle alone solves the same system.
  const SparseMatrix A = gridLaplacianPlusShift(10, 1.0);
  const SparseMatrix lower = A.triangularView<Eigen::Lower>();
  const Vector b = randomVector<double>(100, 5);
  RealCholeskySolver solver;
  ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
  ASSERT_EQ(solver.factorize(lower), SolverStatus::Ok);
  Vector x;
  ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A, x, b), 1e-12);
}

TEST(SparseSolver, IndefiniteMatrixIsRejectedEveryKind) {
  // Grid Laplacian eigenvalues lie in [0, 8): shifting by -2.5 puts several
  // below zero, and no pivot is exactly zero (CHOLMOD's simplicial LDLᵀ alone
  // would accept it).
  const SparseMatrix indefinite = gridLaplacianPlusShift(20, -2.5);
  const SparseMatrix definite = gridLaplacianPlusShift(20, 0.5);
  const Vector b = randomVector<double>(400, 6);
  for (FactorKind kind : kAllKinds) {
    RealCholeskySolver solver(kind);
    ASSERT_EQ(solver.compute(definite), SolverStatus::Ok);
    EXPECT_EQ(solver.factorize(indefinite), SolverStatus::NotPositiveDefinite);
    EXPECT_FALSE(solver.isFactorized());
    Vector x;
    EXPECT_EQ(solver.solve(b, x), SolverStatus::NotFactorized);
    // Recovers on the next positive-definite matrix.
    ASSERT_EQ(solver.factorize(definite), SolverStatus::Ok);
    ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
    EXPECT_LT(relativeResidual(definite, x, b), 1e-12);
  }
}

TEST(SparseSolver, NegativeFirstPivotIsRejected) {
  SparseMatrix A = gridLaplacianPlusShift(5, 1.0);
  A.coeffRef(0, 0) = -1.0;
  RealCholeskySolver solver;
  EXPECT_EQ(solver.compute(A), SolverStatus::NotPositiveDefinite);
}

TEST(SparseSolver, ComplexIndefiniteIsRejected) {
  // Mean eigenvalue = trace / n = 3.73 - 3.9 < 0: some eigenvalue is negative.
  const ComplexSparseMatrix A = gridConnectionPlusShift(15, -3.9, 8);
  for (FactorKind kind : kAllKinds) {
    ComplexCholeskySolver solver(kind);
    EXPECT_EQ(solver.compute(A), SolverStatus::NotPositiveDefinite);
  }
}

TEST(SparseSolver, NonFiniteValuesAreRejected) {
  const SparseMatrix A = gridLaplacianPlusShift(8, 1.0);
  RealCholeskySolver solver;
  ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
  SparseMatrix withNan = A;
  withNan.coeffRef(9, 9) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(solver.factorize(withNan), SolverStatus::NonFinite);
  EXPECT_FALSE(solver.isFactorized());
  SparseMatrix withInf = A;
  withInf.coeffRef(10, 9) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(solver.factorize(withInf), SolverStatus::NonFinite);

  ASSERT_EQ(solver.factorize(A), SolverStatus::Ok);
  Vector b = Vector::Ones(64);
  b[3] = std::numeric_limits<double>::quiet_NaN();
  Vector x;
  EXPECT_EQ(solver.solve(b, x), SolverStatus::NonFinite);

  ComplexSparseMatrix complexNan = A.cast<Complex>();
  complexNan.coeffRef(2, 1) = Complex(0.0, std::numeric_limits<double>::quiet_NaN());
  ComplexCholeskySolver complexSolver;
  EXPECT_EQ(complexSolver.compute(complexNan), SolverStatus::NonFinite);
}

TEST(SparseSolver, SizeMismatchAndCallOrder) {
  RealCholeskySolver solver;
  const SparseMatrix A = gridLaplacianPlusShift(6, 1.0);
  Vector x;
  EXPECT_EQ(solver.factorize(A), SolverStatus::NotAnalyzed);
  EXPECT_EQ(solver.solve(Vector::Ones(36), x), SolverStatus::NotAnalyzed);
  EXPECT_FALSE(solver.isAnalyzed());
  EXPECT_EQ(solver.factorNonZeros(), 0);

  ASSERT_EQ(solver.analyzePattern(A), SolverStatus::Ok);
  EXPECT_EQ(solver.solve(Vector::Ones(36), x), SolverStatus::NotFactorized);
  ASSERT_EQ(solver.factorize(A), SolverStatus::Ok);
  EXPECT_EQ(solver.solve(Vector::Ones(35), x), SolverStatus::SizeMismatch);
  EXPECT_EQ(solver.solve(Vector::Ones(37), x), SolverStatus::SizeMismatch);

  x = Vector::Constant(3, 7.0);  // wrong size on input: resized
  ASSERT_EQ(solver.solve(Vector::Ones(36), x), SolverStatus::Ok);
  EXPECT_EQ(x.size(), 36);

  EXPECT_EQ(solver.analyzePattern(SparseMatrix(4, 5)), SolverStatus::SizeMismatch);
  EXPECT_FALSE(solver.isAnalyzed());  // a failed analysis drops the old one
  EXPECT_EQ(solver.analyzePattern(SparseMatrix(0, 0)), SolverStatus::SizeMismatch);
}

TEST(SparseSolver, ShareAnalysisRealToComplex) {
  const int m = 25;
  const SparseMatrix scalar = gridLaplacianPlusShift(m, 0.5);
  const ComplexSparseMatrix connection = gridConnectionPlusShift(m, 0.5, 9);
  const ComplexVector b = randomVector<Complex>(m * m, 10);

  RealCholeskySolver scalarSolver;
  ASSERT_EQ(scalarSolver.compute(scalar), SolverStatus::Ok);  // numeric state: shared anyway

  ComplexCholeskySolver copied;  // same kind: the symbolic factor is copied
  ASSERT_EQ(copied.shareAnalysisFrom(scalarSolver), SolverStatus::Ok);
  EXPECT_TRUE(copied.isAnalyzed());
  EXPECT_EQ(copied.analysisCount(), 0);
  EXPECT_EQ(copied.factorNonZeros(), scalarSolver.factorNonZeros());
  ASSERT_EQ(copied.factorize(connection), SolverStatus::Ok);
  ComplexVector x;
  ASSERT_EQ(copied.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(connection, x, b), 1e-12);

  ComplexCholeskySolver reanalysed(FactorKind::Supernodal);  // other kind: given ordering
  ASSERT_EQ(reanalysed.shareAnalysisFrom(scalarSolver), SolverStatus::Ok);
  EXPECT_EQ(reanalysed.analysisCount(), 1);
  EXPECT_EQ(reanalysed.factorNonZeros(), scalarSolver.factorNonZeros());
  ASSERT_EQ(reanalysed.factorize(connection), SolverStatus::Ok);
  ComplexVector y;
  ASSERT_EQ(reanalysed.solve(b, y), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(connection, y, b), 1e-12);

  // A pattern other than the shared one is still refused.
  EXPECT_EQ(copied.factorize(gridConnectionPlusShift(m + 1, 0.5, 9)),
            SolverStatus::PatternMismatch);

  RealCholeskySolver unanalysed;
  EXPECT_EQ(copied.shareAnalysisFrom(unanalysed), SolverStatus::NotAnalyzed);
  EXPECT_FALSE(copied.isAnalyzed());
}

TEST(SparseSolver, ShareAnalysisComplexToReal) {
  const SparseMatrix scalar = gridLaplacianPlusShift(15, 0.5);
  const ComplexSparseMatrix connection = gridConnectionPlusShift(15, 0.5, 11);
  ComplexCholeskySolver complexSolver(FactorKind::Supernodal);
  ASSERT_EQ(complexSolver.analyzePattern(connection), SolverStatus::Ok);
  RealCholeskySolver realSolver(FactorKind::Supernodal);
  ASSERT_EQ(realSolver.shareAnalysisFrom(complexSolver), SolverStatus::Ok);
  ASSERT_EQ(realSolver.factorize(scalar), SolverStatus::Ok);
  const Vector b = randomVector<double>(225, 12);
  Vector x;
  ASSERT_EQ(realSolver.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(scalar, x, b), 1e-12);
}

TEST(SparseSolver, MoveKeepsTheFactorization) {
  const SparseMatrix A = gridLaplacianPlusShift(10, 1.0);
  const Vector b = randomVector<double>(100, 13);
  RealCholeskySolver original;
  ASSERT_EQ(original.compute(A), SolverStatus::Ok);

  RealCholeskySolver moved(std::move(original));
  Vector x;
  ASSERT_EQ(moved.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A, x, b), 1e-12);
  EXPECT_EQ(moved.analysisCount(), 1);

  RealCholeskySolver assigned(FactorKind::Supernodal);
  assigned = std::move(moved);
  ASSERT_EQ(assigned.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A, x, b), 1e-12);

  // Moved-from solvers are empty but usable.
  EXPECT_FALSE(original.isAnalyzed());  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(original.solve(b, x), SolverStatus::NotAnalyzed);
  EXPECT_EQ(original.rows(), 0);
  ASSERT_EQ(original.compute(A), SolverStatus::Ok);
  ASSERT_EQ(original.solve(b, x), SolverStatus::Ok);
  EXPECT_LT(relativeResidual(A, x, b), 1e-12);
}

TEST(SparseSolver, RepeatedRunsAreBitwiseIdentical) {
  const ComplexSparseMatrix A = randomHermitianPositiveDefinite(500, 5, 14);
  const ComplexVector b = randomVector<Complex>(500, 15);
  ComplexVector first;
  for (int run = 0; run < 2; ++run) {
    ComplexCholeskySolver solver;
    ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
    ComplexVector x;
    ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
    if (run == 0) {
      first = x;
    } else {
      EXPECT_EQ(x, first);
    }
  }
}

// The simplicial solves read L's row indices as 16 bits where every index
// fits (n ≤ 65,536): the same operations in the same order as with CHOLMOD's
// 32-bit indices, so the same bits, for one right-hand side and a pair, a
// dense and a local one, real and complex. Above 65,536 rows the 32-bit
// indices are read.
template <typename Scalar, typename Matrix>
void expectShortRowsBitwise(const Matrix& A) {
  using VectorType = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  const int n = static_cast<int>(A.rows());
  CholeskySolver<Scalar> wide(FactorKind::Simplicial), narrow(FactorKind::Simplicial);
  wide.setShortRowIndices(false);
  ASSERT_EQ(wide.compute(A), SolverStatus::Ok);
  ASSERT_EQ(narrow.compute(A), SolverStatus::Ok);
  ASSERT_FALSE(wide.usesShortRowIndices());
  ASSERT_TRUE(narrow.usesShortRowIndices());
  VectorType dense = randomVector<Scalar>(n, 21), local = VectorType::Zero(n);
  local[n / 3] = dense[0];
  local[n / 3 + 1] = dense[1];
  for (const VectorType* b : {&dense, &local}) {
    VectorType x, y;
    ASSERT_EQ(wide.solve(*b, x), SolverStatus::Ok);
    ASSERT_EQ(narrow.solve(*b, y), SolverStatus::Ok);
    for (int i = 0; i < n; ++i) ASSERT_EQ(x[i], y[i]) << "row " << i;
    EXPECT_LT(relativeResidual(A, y, *b), 1e-12);
    VectorType wa = *b, wb = dense, na = *b, nb = dense;
    ASSERT_EQ(wide.solveInPlacePair(wa, wb), SolverStatus::Ok);
    ASSERT_EQ(narrow.solveInPlacePair(na, nb), SolverStatus::Ok);
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(wa[i], na[i]) << "row " << i;
      ASSERT_EQ(wb[i], nb[i]) << "row " << i;
    }
  }
  // Switched off, the next factorization reads the 32-bit indices again.
  narrow.setShortRowIndices(false);
  ASSERT_EQ(narrow.factorize(A), SolverStatus::Ok);
  EXPECT_FALSE(narrow.usesShortRowIndices());
  narrow.releaseFactor();
  EXPECT_FALSE(narrow.usesShortRowIndices());
}

TEST(SparseSolver, ShortRowIndicesGiveTheBitsOfCholmodsOwn) {
  expectShortRowsBitwise<double>(gridLaplacianPlusShift(150, 0.05));
  expectShortRowsBitwise<Complex>(gridConnectionPlusShift(90, 0.05, 9));
  // 256² = 65,536 rows: the largest index, 65,535, still fits; 257² does not.
  for (const int m : {256, 257}) {
    const SparseMatrix A = gridLaplacianPlusShift(m, 0.5);
    RealCholeskySolver solver;
    ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
    EXPECT_EQ(solver.usesShortRowIndices(), m == 256) << m << " x " << m;
    const Vector b = randomVector<double>(m * m, 23);
    Vector x;
    ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
    EXPECT_LT(relativeResidual(A, x, b), 1e-12) << m << " x " << m;
  }
  // Supernodal factors go through CHOLMOD's solve.
  RealCholeskySolver supernodal(FactorKind::Supernodal);
  ASSERT_EQ(supernodal.compute(gridLaplacianPlusShift(40, 0.5)), SolverStatus::Ok);
  EXPECT_FALSE(supernodal.usesShortRowIndices());
}

TEST(SparseSolver, LargeSystemsUseAReproducibleOrdering) {
  // 22,500 unknowns: above the size where nested dissection (METIS bisection)
  // is tried beside AMD. Two independent solvers must agree bit for bit.
  const SparseMatrix A = gridLaplacianPlusShift(150, 0.5);
  const Vector b = randomVector<double>(150 * 150, 16);
  Vector first;
  long firstNonZeros = 0;
  for (int run = 0; run < 2; ++run) {
    RealCholeskySolver solver;
    ASSERT_EQ(solver.compute(A), SolverStatus::Ok);
    Vector x;
    ASSERT_EQ(solver.solve(b, x), SolverStatus::Ok);
    EXPECT_LT(relativeResidual(A, x, b), 1e-12);
    if (run == 0) {
      first = x;
      firstNonZeros = solver.factorNonZeros();
    } else {
      EXPECT_EQ(x, first);
      EXPECT_EQ(solver.factorNonZeros(), firstNonZeros);
    }
  }
}

TEST(SparseSolver, StatusNamesAreDistinct) {
  const SolverStatus all[] = {SolverStatus::Ok,
                              SolverStatus::NotAnalyzed,
                              SolverStatus::PatternMismatch,
                              SolverStatus::NotPositiveDefinite,
                              SolverStatus::NotFactorized,
                              SolverStatus::SizeMismatch,
                              SolverStatus::NonFinite,
                              SolverStatus::CholmodError};
  std::set<std::string> names;
  for (SolverStatus status : all) names.insert(toString(status));
  EXPECT_EQ(names.size(), 8u);
  EXPECT_EQ(std::string(toString(SolverStatus::NotPositiveDefinite)), "NotPositiveDefinite");
}

}  // namespace
}  // namespace blot::stain
