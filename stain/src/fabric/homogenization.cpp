// Periodic homogenization of a weave tile (paper sec. 2, eqs. 1-2).
//
// Design note.
//  - Equations: for i = x, y find the periodic corrector f_i with
//    ∇·S(∇f_i + e_i) = 0 on the torus Ω (the tile with opposite sides glued),
//    then S_eff e_i = (1/|Ω|) ∫ S(e_i + ∇f_i) (eq. 1: the mean flux of the
//    cell problem whose mean gradient is e_i).
//  - Discretization: P1 elements on a torus mesh of the tile with unit cells,
//    each cell K x K squares, each square split into two triangles along
//    alternating diagonals (the gridMesh "union jack"): with an even number of
//    squares per side the mesh maps to itself under 90° rotations and axis
//    reflections, so a symmetric pattern gets an exactly symmetric discrete
//    S_eff, and a 90°-rotated tile an exactly swapped one. Cell interfaces lie
//    on mesh lines, so a laminate (whose exact corrector is piecewise linear
//    across the layers) is reproduced exactly at any K.
//    Per triangle everything is written with the shared element kernel
//    triangleStiffness (K_T = A ∇φᵀ S ∇φ): the load of problem i is
//    −K_T x_i (x_i the corner coordinates, since ∇x_i = e_i) and the mean flux
//    is Σ_T x_jᵀ K_T (x_i + f_i), so no gradient code is duplicated here.
//  - Constraint: the periodic stiffness is singular with the constants as its
//    null space (the torus is connected) and each load sums to zero, so the
//    system is consistent. We pin one vertex (identity row and column, zero
//    load): the pinned system is SPD for CHOLMOD, keeps the sparsity, and its
//    solution solves the singular system exactly (the dropped equation is the
//    negated sum of the others). The corrector is then shifted to zero mean;
//    S_eff depends only on ∇f_i, so the shift is cosmetic.
//    Rejected: a dense rank-one term 11ᵀ (destroys sparsity); a Lagrange
//    multiplier (saddle point, not SPD, so no Cholesky); regularising with εM
//    (changes the answer by O(ε)).
//  - The discrete S_eff is an energy minimum over a subspace of the periodic
//    H¹ functions, so it satisfies the same bounds as the exact one:
//    Reuss ≤ S_eff ≤ S_eff,h ≤ Voigt in the Loewner order, and converges from
//    above as K grows (O(h^{2s}), s ≤ 1 set by the corner singularities where
//    four cells meet).
#include <blot/stain/fabric/homogenization.h>

#include <blot/stain/geometry/operators.h>
#include <blot/stain/numerics/sparse_solver.h>

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::stain {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Element matrices of one cell: the square's two triangles for each diagonal.
/// Local corner order: triangle t of diagonal d uses square corners
/// kTriangleCorners[d][t] with corner c at (c & 1, c >> 1) / K.
struct CellElements {
  Matrix3 stiffness[2][2];  ///< [diagonal][triangle]
};

/// Square corners 0 = (0,0), 1 = (1,0), 2 = (0,1), 3 = (1,1); counter-clockwise
/// triangles. Diagonal 0 ("/") joins corners 0 and 3, diagonal 1 ("\") 1 and 2.
constexpr int kTriangleCorners[2][2][3] = {{{0, 1, 3}, {0, 3, 2}}, {{0, 1, 2}, {1, 3, 2}}};

Vector2 squareCorner(int corner, double h) {
  return Vector2((corner & 1) * h, (corner >> 1) * h);
}

}  // namespace

Matrix2 reussBound(const WeavePattern& pattern) {
  Matrix2 sum = Matrix2::Zero();
  for (const Matrix2& tensor : pattern.cellTensors()) sum += tensor.inverse();
  const Matrix2 inverse = (sum / static_cast<double>(pattern.cellTensors().size())).inverse();
  return 0.5 * (inverse + inverse.transpose());
}

Matrix2 voigtBound(const WeavePattern& pattern) {
  Matrix2 sum = Matrix2::Zero();
  for (const Matrix2& tensor : pattern.cellTensors()) sum += tensor;
  return sum / static_cast<double>(pattern.cellTensors().size());
}

Vector2 symmetricEigenvalues(const Matrix2& tensor) {
  const double mean = 0.5 * (tensor(0, 0) + tensor(1, 1));
  const double offDiagonal = 0.5 * (tensor(0, 1) + tensor(1, 0));
  const double radius = std::hypot(0.5 * (tensor(0, 0) - tensor(1, 1)), offDiagonal);
  return Vector2(mean - radius, mean + radius);
}

double principalAngle(const Matrix2& tensor) {
  const double scale = std::abs(tensor(0, 0)) + std::abs(tensor(1, 1));
  // Round-off in the off-diagonal (a symmetric pattern's S_eff has ~1e-15
  // relative) must not flip a 90° axis to −90°: treat it as zero.
  double offDiagonal = 0.5 * (tensor(0, 1) + tensor(1, 0));
  if (std::abs(offDiagonal) <= 1e-12 * scale) offDiagonal = 0.0;
  const double halfDifference = 0.5 * (tensor(0, 0) - tensor(1, 1));
  // Isotropic up to round-off: the eigenvectors are arbitrary, call it 0.
  if (std::hypot(halfDifference, offDiagonal) <= 1e-13 * scale) return 0.0;
  double angle = 0.5 * std::atan2(offDiagonal, halfDifference);  // in (−π/2, π/2]
  if (angle <= -0.5 * kPi) angle += kPi;
  return angle;
}

int defaultSubdivisions(const WeavePattern& pattern) {
  constexpr long kUnknownBudget = 16384;
  const long cells = static_cast<long>(pattern.rows()) * pattern.cols();
  int K = 4;
  while (K < 32 && cells * (K + 2) * (K + 2) <= kUnknownBudget) K += 2;
  return K;
}

HomogenizationResult homogenize(const WeavePattern& pattern, int subdivisions) {
  if (subdivisions == kAutoSubdivisions) subdivisions = defaultSubdivisions(pattern);
  if (subdivisions < 1)
    throw std::invalid_argument("homogenize: subdivisions must be >= 1, got " + std::to_string(subdivisions));
  const int rows = pattern.rows(), cols = pattern.cols(), K = subdivisions;
  const int nx = cols * K, ny = rows * K;  // squares (= vertices) per side of the torus
  const int vertexCount = nx * ny;
  const double h = 1.0 / K;
  auto vertex = [nx, ny](int i, int j) { return ((j + ny) % ny) * nx + (i + nx) % nx; };

  // Element matrices per cell (the squares of one cell are congruent).
  std::vector<CellElements> elements(static_cast<size_t>(rows * cols));
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      CellElements& cell = elements[static_cast<size_t>(r * cols + c)];
      for (int d = 0; d < 2; ++d)
        for (int t = 0; t < 2; ++t) {
          const int* corners = kTriangleCorners[d][t];
          cell.stiffness[d][t] = triangleStiffness(squareCorner(corners[0], h), squareCorner(corners[1], h),
                                                   squareCorner(corners[2], h), pattern.cellTensor(r, c));
        }
    }
  }
  // Visits every triangle: (cell elements, global vertex ids, local corner coordinates).
  auto forEachTriangle = [&](auto&& visit) {
    for (int j = 0; j < ny; ++j) {
      const int row = rows - 1 - j / K;  // file row 0 is the top of the tile
      for (int i = 0; i < nx; ++i) {
        const CellElements& cell = elements[static_cast<size_t>(row * cols + i / K)];
        const int diagonal = (i + j) % 2;
        const int squareVertices[4] = {vertex(i, j), vertex(i + 1, j), vertex(i, j + 1), vertex(i + 1, j + 1)};
        for (int t = 0; t < 2; ++t) {
          const int* corners = kTriangleCorners[diagonal][t];
          std::array<int, 3> ids;
          Eigen::Matrix<double, 3, 2> local;
          for (int k = 0; k < 3; ++k) {
            ids[static_cast<size_t>(k)] = squareVertices[corners[k]];
            local.row(k) = squareCorner(corners[k], h).transpose();
          }
          visit(cell.stiffness[diagonal][t], ids, local);
        }
      }
    }
  };

  // Periodic stiffness with vertex 0 pinned, and the two loads −K_T x_i.
  constexpr int pinned = 0;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(18) * static_cast<size_t>(vertexCount) + 1);
  Eigen::MatrixX2d loads = Eigen::MatrixX2d::Zero(vertexCount, 2);
  forEachTriangle([&](const Matrix3& Ke, const std::array<int, 3>& ids, const Eigen::Matrix<double, 3, 2>& local) {
    const Eigen::Matrix<double, 3, 2> load = -Ke * local;
    for (int k = 0; k < 3; ++k) {
      const int a = ids[static_cast<size_t>(k)];
      if (a == pinned) continue;
      loads.row(a) += load.row(k);
      for (int l = 0; l < 3; ++l) {
        const int b = ids[static_cast<size_t>(l)];
        if (b != pinned) triplets.emplace_back(a, b, Ke(k, l));
      }
    }
  });
  triplets.emplace_back(pinned, pinned, 1.0);
  SparseMatrix stiffness(vertexCount, vertexCount);
  stiffness.setFromTriplets(triplets.begin(), triplets.end());

  RealCholeskySolver solver;
  const SolverStatus status = solver.compute(stiffness);
  if (status != SolverStatus::Ok)
    throw std::runtime_error(pattern.sourceName() + ": homogenization: cell-problem factorization failed (" +
                             toString(status) + ")");
  Eigen::MatrixX2d correctors(vertexCount, 2);
  Vector rhs, solution;
  for (int i = 0; i < 2; ++i) {
    rhs = loads.col(i);
    const SolverStatus solved = solver.solve(rhs, solution);
    if (solved != SolverStatus::Ok)
      throw std::runtime_error(pattern.sourceName() + ": homogenization: cell-problem solve failed (" +
                               toString(solved) + ")");
    correctors.col(i) = solution.array() - solution.mean();  // zero-mean f_i
  }

  // Eq. (1): column i of S_eff is the mean flux (1/|Ω|) Σ_T ∫_T S(e_i + ∇f_i).
  Matrix2 fluxSum = Matrix2::Zero();
  forEachTriangle([&](const Matrix3& Ke, const std::array<int, 3>& ids, const Eigen::Matrix<double, 3, 2>& local) {
    Eigen::Matrix<double, 3, 2> potential = local;  // x_i + f_i at the corners
    for (int k = 0; k < 3; ++k) potential.row(k) += correctors.row(ids[static_cast<size_t>(k)]);
    fluxSum += local.transpose() * (Ke * potential);  // (j, i): x_jᵀ K_T (x_i + f_i)
  });
  const Matrix2 effective = fluxSum / static_cast<double>(rows * cols);

  HomogenizationResult result;
  result.effective = 0.5 * (effective + effective.transpose());
  result.voigtBound = voigtBound(pattern);
  result.average = result.voigtBound;
  result.reussBound = reussBound(pattern);
  result.eigenvalues = symmetricEigenvalues(result.effective);
  result.principalAngle = principalAngle(result.effective);
  result.subdivisions = K;
  result.patternHash = pattern.contentHash();
  result.vertexCount = vertexCount;
  return result;
}

const HomogenizationResult& Homogenizer::homogenize(const WeavePattern& pattern, int subdivisions) {
  if (subdivisions == kAutoSubdivisions) subdivisions = defaultSubdivisions(pattern);
  const auto key = std::make_pair(pattern.contentHash(), subdivisions);
  const auto [first, last] = cache_.equal_range(key);
  for (auto it = first; it != last; ++it) {
    if (it->second.cols == pattern.cols() && it->second.cellTensors == pattern.cellTensors()) {
      ++cacheHits_;
      return it->second.result;
    }
  }
  ++cacheMisses_;
  Entry entry{pattern.cellTensors(), pattern.cols(), blot::stain::homogenize(pattern, subdivisions)};
  return cache_.emplace(key, std::move(entry))->second.result;
}

void Homogenizer::clear() {
  cache_.clear();
  cacheHits_ = 0;
  cacheMisses_ = 0;
}

}  // namespace blot::stain
