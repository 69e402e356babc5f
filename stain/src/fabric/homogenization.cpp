// Periodic homogenization of a weave tile (paper sec. 2, eqs. 1-2).
//
// Design note: docs/design-notes.md, "stain/src/fabric/homogenization.cpp".
#include <blot/stain/fabric/homogenization.h>

#include <blot/stain/geometry/operators.h>
#include <blot/stain/numerics/sparse_solver.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::stain {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Innermost fan radius of the first graded mesh, and the deepest one refined to
/// (cells): below ~1e-60 the element areas (~r²) leave the normal doubles.
constexpr double kInitialInnerRadius = 0.05;
constexpr double kMinInnerRadius = 1e-60;

/// One cell-problem solve: the P1 homogenized tensor (symmetrised) and, on
/// graded meshes, the energy of the two correctors per (lattice corner, ring).
struct CellSolve {
  Matrix2 tensor;
  std::vector<double> ringEnergies;  ///< latticeCornerCount x ringCount, row-major; empty for uniform meshes.
};

/// Solves the cell problems for the per-cell tensors `cellTensors` on `mesh`.
/// `solver` keeps its symbolic analysis across calls on the same mesh (the
/// primal and the dual system share the sparsity pattern).
CellSolve solveCellProblem(const CellMesh& mesh, const std::vector<Matrix2>& cellTensors, int cellCount,
                           RealCholeskySolver& solver, const std::string& sourceName) {
  const int vertexCount = mesh.vertexCount;
  const size_t triangleCount = mesh.triangleVertices.size();
  auto elementStiffness = [&](size_t t) {
    const Eigen::Matrix<double, 3, 2>& p = mesh.triangleCorners[t];
    return triangleStiffness(p.row(0).transpose(), p.row(1).transpose(), p.row(2).transpose(),
                             cellTensors[static_cast<size_t>(mesh.triangleCells[t])]);
  };

  // Periodic stiffness with vertex 0 pinned, and the two loads −K_T x_i.
  constexpr int pinned = 0;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(9 * triangleCount + 1);
  Eigen::MatrixX2d loads = Eigen::MatrixX2d::Zero(vertexCount, 2);
  for (size_t t = 0; t < triangleCount; ++t) {
    const Matrix3 Ke = elementStiffness(t);
    const Eigen::Matrix<double, 3, 2> load = -Ke * mesh.triangleCorners[t];
    const std::array<int, 3>& ids = mesh.triangleVertices[t];
    for (int k = 0; k < 3; ++k) {
      const int a = ids[static_cast<size_t>(k)];
      if (a == pinned) continue;
      loads.row(a) += load.row(k);
      for (int l = 0; l < 3; ++l) {
        const int b = ids[static_cast<size_t>(l)];
        if (b != pinned) triplets.emplace_back(a, b, Ke(k, l));
      }
    }
  }
  triplets.emplace_back(pinned, pinned, 1.0);
  SparseMatrix stiffness(vertexCount, vertexCount);
  stiffness.setFromTriplets(triplets.begin(), triplets.end());
  std::vector<Eigen::Triplet<double>>().swap(triplets);  // free before the factorization

  SolverStatus status = solver.isAnalyzed() ? SolverStatus::Ok : solver.analyzePattern(stiffness);
  if (status == SolverStatus::Ok) status = solver.factorize(stiffness);
  if (status != SolverStatus::Ok)
    throw std::runtime_error(sourceName + ": homogenization: cell-problem factorization failed (" +
                             toString(status) + ")");
  Eigen::MatrixX2d correctors(vertexCount, 2);
  Vector rhs, solution;
  for (int i = 0; i < 2; ++i) {
    rhs = loads.col(i);
    const SolverStatus solved = solver.solve(rhs, solution);
    if (solved != SolverStatus::Ok)
      throw std::runtime_error(sourceName + ": homogenization: cell-problem solve failed (" + toString(solved) + ")");
    correctors.col(i) = solution.array() - solution.mean();  // zero-mean f_i
  }
  solver.releaseFactor();

  // Eq. (1): column i is the mean flux (1/|Ω|) Σ_T ∫_T S(e_i + ∇f_i); the
  // diagonal terms are the energies, summed per ring for the tail indicator.
  CellSolve result;
  const bool graded = !mesh.triangleRings.empty();
  if (graded) result.ringEnergies.assign(static_cast<size_t>(mesh.latticeCornerCount) * mesh.ringCount, 0.0);
  Matrix2 fluxSum = Matrix2::Zero();
  for (size_t t = 0; t < triangleCount; ++t) {
    const Matrix3 Ke = elementStiffness(t);
    const Eigen::Matrix<double, 3, 2>& local = mesh.triangleCorners[t];
    Eigen::Matrix<double, 3, 2> potential = local;  // x_i + f_i at the corners
    for (int k = 0; k < 3; ++k) potential.row(k) += correctors.row(mesh.triangleVertices[t][static_cast<size_t>(k)]);
    const Eigen::Matrix<double, 3, 2> flux = Ke * potential;
    fluxSum += local.transpose() * flux;  // (j, i): x_jᵀ K_T (x_i + f_i)
    if (graded) {
      const double energy = potential.col(0).dot(flux.col(0)) + potential.col(1).dot(flux.col(1));
      result.ringEnergies[static_cast<size_t>(mesh.triangleLatticeCorners[t]) * mesh.ringCount +
                          static_cast<size_t>(mesh.triangleRings[t])] += energy;
    }
  }
  const Matrix2 tensor = fluxSum / static_cast<double>(cellCount);
  result.tensor = 0.5 * (tensor + tensor.transpose());
  return result;
}

/// The tail indicator of one solve: (share of the energy below the resolved
/// rings, summed over the corners; per-ring energy ratio at the worst corner).
/// Around a corner singularity r^α the energy per ring decays like q^ℓ with
/// q = σ^(2α); it is read off two blocks of m rings (one e-fold of radius
/// each) clear of the fan, whose neighbourhood the mesh gets wrong, and the
/// geometric series below the inner block is the estimate.
std::pair<double, double> energyTail(const CellMesh& mesh, const CellSolve& solve) {
  const int rings = mesh.ringCount, m = mesh.raysPerSide;
  const int fan = rings - 1;
  if (solve.ringEnergies.empty() || fan < 3 * m) return {0.0, 0.0};
  double total = 0.0, tail = 0.0, worstTail = -1.0, worstRatio = 0.0;
  for (int c = 0; c < mesh.latticeCornerCount; ++c) {
    const double* e = solve.ringEnergies.data() + static_cast<size_t>(c) * rings;
    double outer = 0.0, inner = 0.0;  // rings [fan − 3m, fan − 2m) and [fan − 2m, fan − m)
    for (int l = 0; l < rings; ++l) {
      total += e[l];
      if (l >= fan - 3 * m && l < fan - 2 * m) outer += e[l];
      if (l >= fan - 2 * m && l < fan - m) inner += e[l];
    }
    if (!(outer > 0.0) || !(inner > 0.0)) continue;
    const double blockRatio = std::min(inner / outer, 0.999);
    const double cornerTail = inner * blockRatio / (1.0 - blockRatio);  // the last m rings, the fan and below
    tail += cornerTail;
    if (cornerTail > worstTail) worstTail = cornerTail, worstRatio = std::pow(blockRatio, 1.0 / m);
  }
  return {total > 0.0 ? tail / total : 0.0, worstRatio};
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
  const double larger = mean + radius, smaller = mean - radius;
  // Past 1e8 of anisotropy mean - radius cancels (diag(1e300, 1e-300) gave 0):
  // the product of the eigenvalues, the determinant, gives the small one.
  if (larger > 0 && smaller < 1e-8 * larger) {
    const double determinant = tensor(0, 0) * tensor(1, 1) - offDiagonal * offDiagonal;
    if (determinant > 0 && std::isfinite(determinant)) return Vector2(determinant / larger, larger);
  }
  return Vector2(smaller, larger);
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

int maxUniformSubdivisions(const WeavePattern& pattern) {
  const long cells = static_cast<long>(pattern.rows()) * pattern.cols();
  return static_cast<int>(std::floor(std::sqrt(static_cast<double>(kMaxCellProblemUnknowns) / cells) + 1e-12));
}

Matrix2 dualTensor(const Matrix2& tensor) {
  const Matrix2 dual = tensor / tensor.determinant();
  return 0.5 * (dual + dual.transpose());
}

double relativeGap(const Matrix2& upper, const Matrix2& lower) {
  return (upper - lower).cwiseAbs().maxCoeff() / symmetricEigenvalues(upper)(1);
}

CellProblemBounds cellProblemBounds(const WeavePattern& pattern, const CellMesh& mesh) {
  const int cellCount = pattern.rows() * pattern.cols();
  std::vector<Matrix2> dualTensors;
  dualTensors.reserve(pattern.cellTensors().size());
  for (const Matrix2& tensor : pattern.cellTensors()) dualTensors.push_back(dualTensor(tensor));
  RealCholeskySolver solver;  // one analysis: both systems have the mesh's pattern
  const CellSolve primal = solveCellProblem(mesh, pattern.cellTensors(), cellCount, solver, pattern.sourceName());
  const CellSolve dual = solveCellProblem(mesh, dualTensors, cellCount, solver, pattern.sourceName());
  CellProblemBounds bounds;
  bounds.upper = primal.tensor;
  bounds.lower = dualTensor(dual.tensor);
  const auto [primalTail, primalRatio] = energyTail(mesh, primal);
  const auto [dualTail, dualRatio] = energyTail(mesh, dual);
  bounds.tailFraction = std::max(primalTail, dualTail);
  bounds.tailRatio = primalTail >= dualTail ? primalRatio : dualRatio;
  return bounds;
}

namespace {

/// A count held in a double: its digits up to 1e15, then as 1.23e+20.
std::string formatCount(double count) {
  if (count < 1e15) return std::to_string(static_cast<long long>(count));
  std::ostringstream out;
  out << std::setprecision(3) << count;
  return out.str();
}

void checkOptions(const WeavePattern& pattern, const HomogenizationOptions& options) {
  const std::string name = pattern.sourceName() + ": homogenize: ";
  const long cells = static_cast<long>(pattern.rows()) * pattern.cols();
  if (cells > kMaxTileCells)
    throw std::invalid_argument(name + "the tile has " + std::to_string(pattern.rows()) + "x" +
                                std::to_string(pattern.cols()) + " = " + std::to_string(cells) +
                                " cells, more than the maximum of " + std::to_string(kMaxTileCells) +
                                " (docs/patterns.md)");
  if (!(options.tolerance > 0.0 && options.tolerance < 1.0))
    throw std::invalid_argument(name + "tolerance must be in (0, 1), got " + std::to_string(options.tolerance));
  if (options.maxUnknowns < 1 || options.maxUnknowns > kMaxCellProblemUnknowns)
    throw std::invalid_argument(name + "the unknown budget must be in [1, " + std::to_string(kMaxCellProblemUnknowns) +
                                "], got " + std::to_string(options.maxUnknowns));
  if (options.subdivisions < 0)
    throw std::invalid_argument(name + "subdivisions must be >= 1 (or 0 for refinement), got " +
                                std::to_string(options.subdivisions));
  const long K = options.subdivisions;
  // cells K² in double: as a long it wraps past 2^63 (K ≥ 759250125 on a
  // 4x4 tile) and the check passed; a double is exact up to 2^53, far past the limit.
  const double unknowns = static_cast<double>(cells) * static_cast<double>(K) * static_cast<double>(K);
  if (K > 0 && unknowns > static_cast<double>(options.maxUnknowns))
    throw std::invalid_argument(name + "subdivisions " + std::to_string(K) + " on a " + std::to_string(pattern.rows()) +
                                "x" + std::to_string(pattern.cols()) + "-cell tile needs " +
                                formatCount(unknowns) + " unknowns, more than the limit of " +
                                std::to_string(options.maxUnknowns) + " (largest K for this tile: " +
                                std::to_string(static_cast<long>(std::sqrt(static_cast<double>(options.maxUnknowns) / cells))) + ")");
}

HomogenizationResult finishResult(const WeavePattern& pattern, const CellProblemBounds& bounds, double tolerance) {
  HomogenizationResult result;
  result.upper = bounds.upper;
  result.lower = bounds.lower;
  result.effective = 0.5 * (bounds.upper + bounds.lower);
  result.gap = relativeGap(bounds.upper, bounds.lower);
  result.tolerance = tolerance;
  result.converged = result.gap <= tolerance;
  result.voigtBound = voigtBound(pattern);
  result.average = result.voigtBound;
  result.reussBound = reussBound(pattern);
  result.eigenvalues = symmetricEigenvalues(result.effective);
  result.principalAngle = principalAngle(result.effective);
  result.patternHash = pattern.contentHash();
  return result;
}

/// kAutoSubdivisions: graded meshes from one ray per side and radius 0.05,
/// deepened while the unresolved energy is over a quarter of the gap (to a tail
/// of a twentieth of the tolerance, by the observed ring ratio), widened (more
/// rays, same depth) otherwise.
HomogenizationResult refineUntilBoundsMeet(const WeavePattern& pattern, const HomogenizationOptions& options) {
  const int rows = pattern.rows(), cols = pattern.cols();
  GradedMeshLevel level{1, gradedLayersFor(1, kInitialInnerRadius)};
  if (gradedVertexCount(rows, cols, level) > options.maxUnknowns)
    throw std::invalid_argument(pattern.sourceName() + ": homogenize: the coarsest graded mesh of a " +
                                std::to_string(rows) + "x" + std::to_string(cols) + "-cell tile needs " +
                                std::to_string(gradedVertexCount(rows, cols, level)) +
                                " unknowns, more than the limit of " + std::to_string(options.maxUnknowns));
  HomogenizationResult result;
  for (int levels = 1;; ++levels) {
    const CellMesh mesh = gradedCellMesh(rows, cols, level);
    const CellProblemBounds bounds = cellProblemBounds(pattern, mesh);
    result = finishResult(pattern, bounds, options.tolerance);
    result.subdivisions = 2 * level.raysPerSide;
    result.gradedLayers = level.layers;
    result.innerRadius = gradedInnerRadius(level);
    result.levels = levels;
    result.vertexCount = mesh.vertexCount;
    if (result.converged) break;

    GradedMeshLevel next = level;
    const long perLayer = 8L * rows * cols * level.raysPerSide;  // vertices added by one more layer
    const long layerBudget = (options.maxUnknowns - gradedVertexCount(rows, cols, level)) / perLayer;
    const double q = bounds.tailRatio;
    const bool deepen = bounds.tailFraction > 0.25 * result.gap && q > 0.0 &&
                        result.innerRadius > kMinInnerRadius && layerBudget > 0;
    if (deepen) {
      const double target = 0.05 * options.tolerance;
      int extra = static_cast<int>(std::ceil(std::log(target / bounds.tailFraction) / std::log(q)));
      extra = std::max(extra, level.raysPerSide);  // at least one e-fold deeper
      const int deepest = gradedLayersFor(level.raysPerSide, kMinInnerRadius);
      extra = static_cast<int>(std::min<long>({static_cast<long>(extra), layerBudget,
                                               static_cast<long>(deepest - level.layers)}));
      next.layers += std::max(extra, 1);
    } else {
      // Resolved corners leave the smooth rate, gap ~ m⁻²: aim at 0.7·tolerance,
      // at least one ray more and at most three times as many.
      const int m = level.raysPerSide;
      const double predicted = m * std::sqrt(result.gap / (0.7 * options.tolerance));
      next.raysPerSide = std::clamp(static_cast<int>(std::ceil(predicted)), m + 1, 3 * m);
      next.layers = gradedLayersFor(next.raysPerSide, result.innerRadius);
      // Near the budget, the widest mesh that still fits.
      while (next.raysPerSide > m + 1 && gradedVertexCount(rows, cols, next) > options.maxUnknowns) {
        --next.raysPerSide;
        next.layers = gradedLayersFor(next.raysPerSide, result.innerRadius);
      }
    }
    if (gradedVertexCount(rows, cols, next) > options.maxUnknowns) break;  // budget spent: not converged
    level = next;
  }
  return result;
}

}  // namespace

HomogenizationResult homogenize(const WeavePattern& pattern, const HomogenizationOptions& options) {
  checkOptions(pattern, options);
  const std::vector<Matrix2>& cells = pattern.cellTensors();
  // A uniform tile is its own effective tensor (the corrector is zero): exact,
  // and free of the solve's conditioning (diag(1e300, 1e-300) is valid input
  // whose cell-problem matrix cannot be factorized in doubles).
  if (std::all_of(cells.begin(), cells.end(), [&](const Matrix2& t) { return t == cells.front(); })) {
    const CellProblemBounds exact{cells.front(), cells.front(), 0.0, 0.0};
    HomogenizationResult result = finishResult(pattern, exact, options.tolerance);
    result.subdivisions = options.subdivisions == kAutoSubdivisions ? 0 : options.subdivisions;
    result.levels = 0;  // no cell problem solved
    return result;
  }
  // Tensors far from 1 are scaled by a power of 4 (exact in binary, also
  // through square roots) so that the solve neither overflows nor underflows;
  // S_eff and both bounds scale linearly with the tensors.
  double largest = 0;
  for (const Matrix2& t : cells) largest = std::max(largest, t.cwiseAbs().maxCoeff());
  if (largest > 1e100 || largest < 1e-100) {
    const int exponent = static_cast<int>(std::round(std::log2(largest) / 2));
    const double factor = std::ldexp(1.0, 2 * exponent);
    HomogenizationResult result = homogenize(pattern.scaled(1.0 / factor), options);
    for (Matrix2* m : {&result.upper, &result.lower, &result.effective, &result.voigtBound, &result.average,
                       &result.reussBound})
      *m *= factor;
    result.eigenvalues *= factor;
    result.patternHash = pattern.contentHash();
    return result;
  }
  if (options.subdivisions == kAutoSubdivisions) return refineUntilBoundsMeet(pattern, options);
  const CellMesh mesh = uniformCellMesh(pattern.rows(), pattern.cols(), options.subdivisions);
  HomogenizationResult result = finishResult(pattern, cellProblemBounds(pattern, mesh), options.tolerance);
  result.subdivisions = options.subdivisions;
  result.levels = 1;
  result.vertexCount = mesh.vertexCount;
  return result;
}

HomogenizationResult homogenize(const WeavePattern& pattern, int subdivisions) {
  HomogenizationOptions options;
  options.subdivisions = subdivisions;
  return homogenize(pattern, options);
}

const HomogenizationResult& Homogenizer::homogenize(const WeavePattern& pattern,
                                                    const HomogenizationOptions& options) {
  const auto key = std::make_tuple(pattern.contentHash(), options.subdivisions, options.tolerance, options.maxUnknowns);
  const auto [first, last] = cache_.equal_range(key);
  for (auto it = first; it != last; ++it) {
    if (it->second.cols == pattern.cols() && it->second.cellTensors == pattern.cellTensors()) {
      ++cacheHits_;
      return it->second.result;
    }
  }
  ++cacheMisses_;
  Entry entry{pattern.cellTensors(), pattern.cols(), blot::stain::homogenize(pattern, options)};
  return cache_.emplace(key, std::move(entry))->second.result;
}

const HomogenizationResult& Homogenizer::homogenize(const WeavePattern& pattern, int subdivisions) {
  HomogenizationOptions options;
  options.subdivisions = subdivisions;
  return homogenize(pattern, options);
}

void Homogenizer::clear() {
  cache_.clear();
  cacheHits_ = 0;
  cacheMisses_ = 0;
}

}  // namespace blot::stain
