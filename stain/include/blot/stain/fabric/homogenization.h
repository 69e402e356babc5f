#pragma once
/// Homogenization of a weave pattern into one effective (bulk) diffusion tensor
/// (paper sec. 2, eqs. 1-2) with two-sided bounds (primal and complementary
/// P1 cell problems) refined until they meet, plus the classical bounds.
///
/// All tensors are 2x2, symmetric, in the pattern's (x, y) = (weft, warp) basis
/// and the pattern's diffusion units (m²/s in the engine). S_eff does not depend
/// on the physical cell size, so the tile is meshed with unit cells.
#include <blot/stain/fabric/homogenization_mesh.h>
#include <blot/stain/types.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <cstdint>
#include <map>
#include <tuple>
#include <utility>
#include <vector>

namespace blot::stain {

/// Passed as `subdivisions`: refine graded meshes until the bounds meet (see
/// HomogenizationOptions).
inline constexpr int kAutoSubdivisions = 0;

/// Default relative gap between the bounds (HomogenizationOptions::tolerance).
inline constexpr double kDefaultGapTolerance = 0.01;
/// Most unknowns (mesh vertices) of one cell-problem solve: peak memory stays
/// under 0.5 GB and one solve (primal and dual) under about a minute
/// (measured in docs/patterns.md).
inline constexpr long kMaxCellProblemUnknowns = 500000;
/// Most cells in a tile (e.g. 100 x 100): the coarsest graded mesh, 28 unknowns
/// per cell, then fits kMaxCellProblemUnknowns.
inline constexpr int kMaxTileCells = 10000;

/// The uniform K of earlier releases, still used for studies: the largest even
/// K in [4, 32] with rows·cols·K² <= 16384 unknowns, and 4 for tiles larger than
/// 32x32 cells. Not used by kAutoSubdivisions any more.
int defaultSubdivisions(const WeavePattern& pattern);

/// Largest K accepted for `pattern` on the uniform mesh: rows·cols·K² <=
/// kMaxCellProblemUnknowns (0 if not even K = 1 fits).
int maxUniformSubdivisions(const WeavePattern& pattern);

/// How homogenize solves.
struct HomogenizationOptions {
  /// K >= 1: one solve on the uniform mesh, each cell K x K squares (a study;
  /// `converged` still reports whether the gap met the tolerance).
  /// kAutoSubdivisions: graded meshes (homogenization_mesh.h), refined in depth
  /// toward the lattice corners or in width until the gap <= tolerance or the
  /// next mesh would exceed maxUnknowns.
  int subdivisions = kAutoSubdivisions;
  double tolerance = kDefaultGapTolerance;    ///< Relative gap to reach, in (0, 1).
  long maxUnknowns = kMaxCellProblemUnknowns; ///< Per solve, in [1, kMaxCellProblemUnknowns].
};

/// Everything `blot homogenize` reports about one pattern.
struct HomogenizationResult {
  /// Best estimate of S_eff: (upper + lower) / 2, which is within gap/2·λ_max
  /// of the exact value in every entry (the exact value lies between the bounds).
  Matrix2 effective;
  Matrix2 upper;  ///< Primal (energy) P1 bound: upper − S_eff is PSD.
  Matrix2 lower;  ///< Complementary (flux) P1 bound: S_eff − lower is PSD.
  /// Relative gap max_ij |upper − lower|_ij / λ_max(upper).
  double gap = 0.0;
  bool converged = false;  ///< gap <= tolerance.
  double tolerance = kDefaultGapTolerance;
  Matrix2 average;      ///< Plain cell average ⟨S⟩ (the paper's "direct average"; equals the Voigt bound).
  Matrix2 reussBound;   ///< Harmonic bound ⟨S⁻¹⟩⁻¹: S_eff − reussBound is PSD.
  Matrix2 voigtBound;   ///< Arithmetic bound ⟨S⟩: voigtBound − S_eff is PSD.
  Vector2 eigenvalues;  ///< Of `effective`, ascending (min, max).
  /// Angle from the weft (x) axis to the eigenvector of the largest eigenvalue,
  /// counter-clockwise, in radians, in (−π/2, π/2]; 0 when isotropic.
  double principalAngle = 0.0;
  /// Uniform mesh: K. Graded mesh: intervals per cell side along the cell
  /// midlines (2·raysPerSide).
  int subdivisions = 0;
  int gradedLayers = 0;      ///< Graded mesh: rings per quarter cell; 0 for the uniform mesh.
  double innerRadius = 0.0;  ///< Graded mesh: radius of the innermost fan (cells); 0 for uniform.
  int levels = 0;            ///< Meshes solved (1 for the uniform mesh).
  std::uint64_t patternHash = 0; ///< WeavePattern::contentHash() of the input.
  int vertexCount = 0;           ///< Unknowns of the final mesh (its vertices).
};

/// The cell tensor of the complementary problem, T = JᵀS⁻¹J = S / det S (J the
/// 90° rotation; docs/patterns.md). The map is its own inverse, and the lower
/// bound is dualTensor(T_h) for the P1 homogenized T_h.
Matrix2 dualTensor(const Matrix2& tensor);

/// max_ij |upper − lower|_ij / λ_max(upper).
double relativeGap(const Matrix2& upper, const Matrix2& lower);

/// Both bounds on one mesh.
struct CellProblemBounds {
  Matrix2 upper;  ///< P1 homogenized S (symmetrised).
  Matrix2 lower;  ///< dualTensor of the P1 homogenized dual tensors.
  /// Graded meshes: estimated share of the energy (primal or dual, the larger)
  /// inside the innermost rings that the mesh cannot resolve, from the decay of
  /// the energy ring by ring around each lattice corner; 0 for uniform meshes.
  double tailFraction = 0.0;
  /// Energy ratio between consecutive rings at the corner with the largest
  /// tail (≈ σ^(2α) for a corner singularity r^α); 0 for uniform meshes.
  double tailRatio = 0.0;
};

/// Solves the primal and complementary cell problems of `pattern` on `mesh`
/// (one symbolic analysis, two factorizations). Throws std::runtime_error if
/// the solver fails (it cannot for a valid pattern).
CellProblemBounds cellProblemBounds(const WeavePattern& pattern, const CellMesh& mesh);

/// Harmonic (Reuss) bound ⟨S⁻¹⟩⁻¹ over the tile's cells (equal areas).
Matrix2 reussBound(const WeavePattern& pattern);
/// Arithmetic (Voigt) bound ⟨S⟩ over the tile's cells (equal areas).
Matrix2 voigtBound(const WeavePattern& pattern);

/// Eigenvalues (ascending) of a symmetric 2x2 tensor, closed form.
Vector2 symmetricEigenvalues(const Matrix2& tensor);
/// Angle (radians, in (−π/2, π/2]) from the x axis to the eigenvector of the
/// largest eigenvalue of a symmetric 2x2 tensor; 0 when the eigenvalues agree.
double principalAngle(const Matrix2& tensor);

/// Homogenizes `pattern` with two-sided bounds (docs/patterns.md): the primal
/// P1 solution bounds S_eff from above, the complementary one, the same solver
/// on the tensors dualTensor(S), from below. Throws std::invalid_argument,
/// naming the limit, for a tile above kMaxTileCells cells, a K whose mesh would
/// exceed options.maxUnknowns, or options out of range; the result of a
/// refinement that stopped at the budget has converged = false.
HomogenizationResult homogenize(const WeavePattern& pattern, const HomogenizationOptions& options);

/// homogenize(pattern, {subdivisions}) with the default tolerance and budget.
HomogenizationResult homogenize(const WeavePattern& pattern,
                                int subdivisions = kAutoSubdivisions);

/// Homogenizes with a cache keyed by pattern content and options, so a pattern used by
/// several patches or scenes is solved once. Owns its cache; not thread-safe.
class Homogenizer {
 public:
  /// The result for (pattern, options), computed on first request. The
  /// reference stays valid until clear() or the Homogenizer is destroyed.
  const HomogenizationResult& homogenize(const WeavePattern& pattern, const HomogenizationOptions& options);
  /// homogenize(pattern, {subdivisions}).
  const HomogenizationResult& homogenize(const WeavePattern& pattern,
                                         int subdivisions = kAutoSubdivisions);
  int cacheHits() const { return cacheHits_; }
  int cacheMisses() const { return cacheMisses_; }
  int cacheSize() const { return static_cast<int>(cache_.size()); }
  void clear();

 private:
  struct Entry {
    std::vector<Matrix2> cellTensors;  ///< Compared on a hit: a hash collision must not alias.
    int cols = 0;
    HomogenizationResult result;
  };
  /// (content hash, K, tolerance, unknown budget).
  std::multimap<std::tuple<std::uint64_t, int, double, long>, Entry> cache_;
  int cacheHits_ = 0;
  int cacheMisses_ = 0;
};

}  // namespace blot::stain
